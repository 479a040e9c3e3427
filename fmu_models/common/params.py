"""Frozen parameter dataclasses and their file schema.

Each physical parameter is a dataclass field made by :func:`param` (default, unit, allowed range, meaning).
From that metadata :func:`params_schema` builds a strict pydantic schema on :class:`fmu_models.config.Schema`
(numbers only - no booleans or strings -, finite, inside the range; unknown keys rejected), so the range
written once beside the parameter is the one the FMU variable, the parameter file and the docs use.
:func:`validate_params` raises :class:`ParameterError` (a ``ConfigError``) listing every problem, one line
each, naming the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import numpy as np
from pydantic import Field, create_model, model_validator
from pydantic import ValidationError as PydanticValidationError

from fmu_models.common.errors import ParameterError
from fmu_models.common.model import Variable
from fmu_models.config import ConfigError, Schema, read_config_file

T = TypeVar("T")

#: extra (non-numeric or not-a-model-parameter) keys of a parameter file: name -> (annotation, default)
ExtraFields = Mapping[str, tuple[Any, Any]]

_NUMBER_ERRORS = ("float_type", "float_parsing", "int_type", "int_parsing", "int_from_float")
_RANGE_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")
_SCHEMAS: dict[tuple[type, tuple[str, ...]], type[Schema]] = {}


def param(default: float, unit: str, lo: float | None, hi: float | None, description: str) -> Any:
    """A dataclass field of a physical parameter, with its unit, allowed range and meaning."""
    return dataclasses.field(
        default=default, metadata={"unit": unit, "min": lo, "max": hi, "description": description}
    )


def numeric_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of a parameter dataclass that carry unit metadata (the scalar physical parameters)."""
    return [f for f in dataclasses.fields(cls) if "unit" in f.metadata]


def to_variables(params: Any) -> tuple[Variable, ...]:
    """FMU/model variables of the scalar parameters, with the instance's values as start values."""
    return tuple(
        Variable(
            f.name,
            f.metadata["unit"],
            f.metadata["description"],
            float(getattr(params, f.name)),
            f.metadata["min"],
            f.metadata["max"],
        )
        for f in numeric_fields(type(params))
    )


def params_schema(cls: type, extra: ExtraFields | None = None) -> type[Schema]:
    """The strict schema of a parameter file of dataclass ``cls`` (built once per class and extra keys)."""
    extra = dict(extra or {})
    key = (cls, tuple(sorted(extra)))
    if key not in _SCHEMAS:
        fields: dict[str, Any] = {
            f.name: (
                Annotated[float, Field(ge=f.metadata["min"], le=f.metadata["max"], allow_inf_nan=False,
                                       description=f"{f.metadata['description']} [{f.metadata['unit']}]")],
                f.default,
            )
            for f in numeric_fields(cls)
        }
        fields.update(extra)
        _SCHEMAS[key] = create_model(f"{cls.__name__}File", __base__=Schema, **fields)
    return _SCHEMAS[key]


def _shown(value: Any) -> str:
    if isinstance(value, float | int) and not isinstance(value, bool):
        return repr(float(value)) if math.isfinite(float(value)) else str(float(value))
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _problem_line(err: Mapping[str, Any], cls: type, known: list[str], retired: Mapping[str, str]) -> str:
    """One line for one schema error: field, value, and the allowed range or choices."""
    loc = [str(p) for p in err.get("loc", ())]
    name = ".".join(loc) or "(top level)"
    kind = str(err.get("type", ""))
    value = err.get("input")
    meta = {f.name: f.metadata for f in numeric_fields(cls)}.get(loc[0] if len(loc) == 1 else "")
    rng = f"[{meta['min']}, {meta['max']}] {meta['unit']}" if meta else ""
    if kind == "extra_forbidden" and name in retired:
        return f"{name} is no longer a parameter: {retired[name]}"
    if kind == "extra_forbidden":
        close = difflib.get_close_matches(name, known, n=1)
        return f"{name} is not a parameter" + (f" (did you mean {close[0]}?)" if close else "")
    if kind == "missing":
        return f"{name} is missing (required)"
    if meta and kind in _RANGE_ERRORS:
        return f"{name} = {_shown(value)} is outside the allowed range {rng}"
    if kind == "finite_number":
        return f"{name} = {_shown(value)} is not finite (allowed: a finite number{' in ' + rng if rng else ''})"
    if kind in _NUMBER_ERRORS:
        what = "an integer" if kind.startswith("int") else "a number"
        return f"{name} = {_shown(value)} is not {what} (allowed: {what}{' in ' + rng if rng else ''})"
    return f"{name} = {_shown(value)}: {err.get('msg', 'invalid')}"


def _flatten(values: Mapping[str, Any], sections: tuple[str, ...], source: str) -> dict[str, Any]:
    """Merge the keys of sub-tables (e.g. ``propulsion``) into the top level; ``_``-keys are comments."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(key, str) and key.startswith("_"):
            continue
        if key not in sections:
            flat[key] = value
        elif not isinstance(value, Mapping):
            raise ParameterError(source, [f"{key} = {_shown(value)} is not a table of parameters"])
        else:
            flat.update({k: v for k, v in value.items() if not (isinstance(k, str) and k.startswith("_"))})
    return flat


def validate_params(
    cls: type, values: Any, source: str, extra: ExtraFields | None = None, sections: tuple[str, ...] = (),
    retired: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """Check a mapping of parameters of ``cls``; return the given ones (validated, numbers as floats).

    Raises :class:`ParameterError` listing every problem (type, finiteness, range, unknown key) at once;
    ``retired`` maps a removed or renamed key to what to do instead (its message replaces "not a parameter").
    """
    if not isinstance(values, Mapping):
        raise ParameterError(source, [f"expected a table of parameters, found {type(values).__name__}"])
    data = _flatten(values, sections, source)
    schema = params_schema(cls, extra)
    try:
        model = schema.model_validate(data)
    except PydanticValidationError as err:
        known = sorted(schema.model_fields)
        lines = [_problem_line(e, cls, known, retired or {}) for e in err.errors(include_url=False)]
        raise ParameterError(source, lines) from None
    return {k: getattr(model, k) for k in model.model_fields_set}


def file_keys(cls: type, extra: ExtraFields | None = None, sections: tuple[str, ...] = (),
              retired: Mapping[str, str] | None = None) -> frozenset[str]:
    """Every key a flat parameter file of dataclass ``cls`` may hold (retired keys included: they belong to it and
    get their own message): the scalar parameters, the ``extra`` keys and the sub-table names ``sections``."""
    return frozenset({f.name for f in numeric_fields(cls)} | set(extra or {}) | set(sections) | set(retired or {}))


#: top-level keys of a parameter file that belong to no vehicle's parameters (read by ``validate --mc``: the
#: identified parameters' covariance and the model's discrepancy)
FILE_LEVEL_KEYS = ("uncertainty", "discrepancy")
#: the vehicles (one model and one FMU each) and the section key of each in a parameter file
VEHICLES = ("quadrotor", "fixed_wing")


def _listed(keys: Any, limit: int = 8) -> str:
    keys = sorted(map(str, keys))
    return ", ".join(keys[:limit]) + (f" and {len(keys) - limit} more" if len(keys) > limit else "")


def vehicle_sections(data: Any, known: Mapping[str, frozenset[str]], source: str) -> dict[str, dict[str, Any]]:
    """The parameters of each vehicle in parameter-file contents ``data``: vehicle name -> its table.

    ``known`` maps each vehicle name to the keys its flat file may hold (:func:`file_keys`). A file holds either
    one table per vehicle under its name (``{"quadrotor": {...}}``), or one vehicle's keys at the top level
    (a flat file), whose vehicle the keys tell: the one whose keys hold them all, else the only one with keys
    no other vehicle has (its own check then names the rest). ``_``-keys are comments and
    :data:`FILE_LEVEL_KEYS` belong to the file. :class:`ParameterError` naming ``source`` and the keys when a
    sectioned file has other keys beside its sections, a flat file holds no parameters, keys that fit every
    vehicle (ambiguous: the file must name its vehicle) or keys of several vehicles, or keys of none.
    """
    if not isinstance(data, Mapping):
        raise ParameterError(source, [f"expected a table of parameters, found {type(data).__name__}"])
    own = {k: v for k, v in data.items() if not (isinstance(k, str) and k.startswith("_")) and k not in FILE_LEVEL_KEYS}
    names = " or ".join(f'"{v}"' for v in known)
    wrap = f'put them under the vehicle\'s key ({names}: {{"{next(iter(known))}": {{...}}}})'
    found = [v for v in known if v in own]
    if found:
        stray = [k for k in own if k not in known]
        if stray:
            raise ParameterError(source, [f"keys {_listed(stray)} sit beside the vehicle sections {', '.join(found)} "
                                          "and would be ignored: move each into its vehicle's section"])
        return {v: own[v] for v in found}
    if not own:
        raise ParameterError(source, [f"no parameters (keys: {_listed(data) or 'none'}); a parameter file holds a "
                                      f"vehicle's section ({names}) or one vehicle's parameters at the top level"])
    keys = set(map(str, own))
    fits = [v for v, ks in known.items() if keys <= ks]
    if len(fits) == 1:
        return {fits[0]: dict(own)}
    if len(fits) > 1:
        raise ParameterError(source, [f"keys {_listed(keys)} are parameters of {' and '.join(fits)} alike, so the "
                                      f"file does not tell which vehicle they are for: {wrap}"])
    specific = {v: {k for k in keys if k in ks and not any(k in o for w, o in known.items() if w != v)}
                for v, ks in known.items()}
    voters = [v for v, ks in specific.items() if ks]
    if len(voters) == 1:
        return {voters[0]: dict(own)}
    if len(voters) > 1:
        raise ParameterError(source, ["keys of several vehicles in one flat file: " + "; ".join(
            f"{_listed(specific[v])} only of {v}" for v in voters) + f"; {wrap}, one section per vehicle"])
    every = set().union(*known.values())
    lines = []
    for k in sorted(keys - every):
        close = difflib.get_close_matches(k, sorted(every), n=1)
        lines.append(f"{k} is a parameter of no vehicle ({', '.join(known)})"
                     + (f" (did you mean {close[0]}?)" if close else ""))
    shared = keys & every
    if shared:
        lines.append(f"the other keys ({_listed(shared)}) fit {' and '.join(known)} alike, so the file does not tell "
                     f"which vehicle it is for: {wrap}")
    raise ParameterError(source, lines)


def vehicle_table(data: Any, vehicle: str, source: str) -> dict[str, Any]:
    """The table of ``vehicle`` in parameter-file contents ``data``: its section, or the file itself when it has no
    vehicle section (a flat file; the vehicle's own schema then checks every key). ``_``-comments stay (the schema
    skips them); :data:`FILE_LEVEL_KEYS` are dropped. :class:`ParameterError` naming ``source`` when the file holds
    other vehicles' sections only, or keys beside its sections that would be ignored."""
    if not isinstance(data, Mapping):
        raise ParameterError(source, [f"expected a table of parameters, found {type(data).__name__}"])
    sections = [v for v in VEHICLES if v in data]
    if vehicle in data:
        stray = [k for k in data if k not in VEHICLES and k not in FILE_LEVEL_KEYS
                 and not (isinstance(k, str) and k.startswith("_"))]
        if stray:
            raise ParameterError(source, [f"keys {_listed(stray)} sit beside the vehicle sections "
                                          f"{', '.join(sections)} and would be ignored: move each into its vehicle's "
                                          "section"])
        table = data[vehicle]
        if not isinstance(table, Mapping):
            raise ParameterError(source, [f"{vehicle}: expected a table of parameters, found {type(table).__name__}"])
        return dict(table)
    if sections:
        raise ParameterError(source, [f"holds the {', '.join(sections)} section only and no {vehicle} section: give a "
                                      f"{vehicle} parameter file (a {vehicle!r} section or its keys at the top level)"])
    return {k: v for k, v in data.items() if k not in FILE_LEVEL_KEYS}


def read_json(path: str | Path) -> dict[str, Any]:
    """Read a parameter file (JSON, or TOML by suffix); :class:`ParameterError` names the file on failure."""
    try:
        return read_config_file(path)
    except ConfigError as err:
        raise ParameterError(err.source, err.problems) from None


#: most parameters an ``uncertainty`` block may carry (its covariance is this squared)
MAX_UNCERTAIN_PARAMS = 200


class Uncertainty(Schema):
    """The optional top-level ``"uncertainty"`` key of a parameter file: the identified parameters' estimate
    and covariance, carried from ``identify`` to ``validate --mc``.

    ``names`` are FMU parameter names; ``mean`` their estimate in the FMU's units; ``covariance`` the
    symmetric positive semi-definite matrix of their estimation errors (units: products of theirs).
    """

    names: list[str] = Field(min_length=1, max_length=MAX_UNCERTAIN_PARAMS)
    mean: list[Annotated[float, Field(allow_inf_nan=False)]] = Field(min_length=1, max_length=MAX_UNCERTAIN_PARAMS)
    covariance: list[list[Annotated[float, Field(allow_inf_nan=False)]]] = Field(
        min_length=1, max_length=MAX_UNCERTAIN_PARAMS)
    note: str = Field("", max_length=2000)  #: what the numbers are (``identify thrust`` writes one); not read

    @model_validator(mode="after")
    def _consistent(self) -> Uncertainty:
        n = len(self.names)
        if len(set(self.names)) != n:
            dup = sorted({x for x in self.names if self.names.count(x) > 1})
            raise ValueError(f"names repeat {', '.join(dup)} (allowed: each parameter once)")
        if len(self.mean) != n:
            raise ValueError(f"mean has {len(self.mean)} values for {n} names (allowed: one per name)")
        rows = [len(r) for r in self.covariance]
        if len(rows) != n or any(k != n for k in rows):
            raise ValueError(f"covariance is {len(rows)} rows of {sorted(set(rows))} values (allowed: {n} x {n}, "
                             "one row and column per name)")
        c = np.asarray(self.covariance, dtype=float)
        scale = max(float(np.max(np.abs(c))), 1e-300)
        if not np.allclose(c, c.T, rtol=1e-6, atol=1e-9 * scale):
            raise ValueError("covariance is not symmetric (allowed: C[i][j] == C[j][i])")
        low = float(np.linalg.eigvalsh(c).min())
        if low < -1e-8 * scale:
            raise ValueError(f"covariance has a negative eigenvalue {low:.3g} (allowed: positive semi-definite)")
        return self

    @property
    def std(self) -> dict[str, float]:
        """Standard deviation of each parameter (square root of the covariance diagonal)."""
        return {n: float(np.sqrt(max(self.covariance[i][i], 0.0))) for i, n in enumerate(self.names)}


#: the ``uncertainty`` key as an extra field of :func:`params_schema` (parameter files that carry it)
UNCERTAINTY_FIELD: ExtraFields = {"uncertainty": (Uncertainty | None, None)}


#: most signals, horizon bins and quantile levels a ``discrepancy`` block may carry
MAX_DISCREPANCY_SIGNALS, MAX_HORIZON_BINS, MAX_QUANTILE_LEVELS = 64, 100, 101
Level = Annotated[float, Field(gt=0.0, lt=1.0, allow_inf_nan=False)]
FiniteValue = Annotated[float, Field(allow_inf_nan=False)]


class SignalDiscrepancy(Schema):
    """One signal's model discrepancy: quantiles of (logged - FMU) per horizon bin (time since the replay window
    restarted from the logged state), in the FMU output's unit."""

    horizon_edges_s: list[Annotated[float, Field(ge=0.0, le=86400.0, allow_inf_nan=False)]] = Field(
        min_length=2, max_length=MAX_HORIZON_BINS + 1)
    quantiles: list[list[FiniteValue]] = Field(min_length=1, max_length=MAX_HORIZON_BINS)
    samples: list[Annotated[int, Field(ge=0)]] = Field(min_length=1, max_length=MAX_HORIZON_BINS)
    #: the quantiles are of (logged - FMU) / (basis + scale_floor), the basis given by ``scale_by`` (None: of
    #: logged - FMU itself)
    scale_floor: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    #: the scale's basis: ``departure`` |FMU - FMU at the window's first sample| (the error grows with how far the
    #: model itself moved since the restart), ``magnitude`` |FMU| (with the output's size) or ``slope`` |dFMU/dt|
    #: [unit/s] (with how fast the output changes: a small lag or phase error of the model)
    scale_by: Literal["departure", "magnitude", "slope"] = "departure"
    #: the scale (basis + ``scale_floor``) is held at this, a high quantile of the learning residuals' scales: the
    #: quantiles say nothing of scales no learning replay reached, and carried linearly past them a replay that
    #: moves faster than any learning one gets a band many times its error. None: not held
    scale_max: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    #: an angle compared modulo 2 pi (residual and departure taken the short way round)
    wrap: bool = False
    #: the quantiles are of the residuals with both signs (a band centred on the FMU); False: of the residuals as
    #: they are, kept where their sign carries from one learning replay to another (informative, not read)
    symmetric: bool = True
    #: the centre of a symmetric band, in the quantiles' unit: the residuals' median at the window's restart from the
    #: logged state (the first horizon bin), where the model's dynamics have not yet erred, so a bias the FMU does
    #: not have (an airspeed sensor's calibration). Kept where it carries from one learning replay to another; the
    #: quantiles already include it (informative, not read). None: centred on the FMU
    offset: float | None = Field(None, allow_inf_nan=False)
    #: ``validate --mc``: the band (the parameter draws convolved with this discrepancy) is stretched by this
    #: about its per-sample median, chosen on the learning replays so that it covers its nominal level there (the
    #: parameter spread is otherwise counted twice: the residuals learned already carry the parameters' error).
    #: None: 1 (learned without parameter draws)
    band_factor: float | None = Field(None, gt=0.0, le=100.0, allow_inf_nan=False)
    #: ``validate --mc``: the weight of the parameter draws' deviations in the band: 1, the draws' spread
    #: convolved with this discrepancy; 0, this discrepancy alone (the residuals learned already carry the
    #: parameters' error, and where the draws' spread does not follow it, it only widens the band). Chosen on
    #: the learning replays, each left out in turn. None: 1
    parameter_weight: float | None = Field(None, ge=0.0, le=1.0, allow_inf_nan=False)

    @model_validator(mode="after")
    def _consistent(self) -> SignalDiscrepancy:
        e = self.horizon_edges_s
        if any(b <= a for a, b in itertools.pairwise(e)):
            raise ValueError(f"horizon_edges_s = {e}: allowed strictly increasing values")
        n = len(e) - 1
        if len(self.quantiles) != n or len(self.samples) != n:
            raise ValueError(f"{len(self.quantiles)} quantile rows and {len(self.samples)} sample counts for {n} "
                             "horizon bins (allowed: one of each per bin)")
        if any(any(b < a for a, b in itertools.pairwise(row)) for row in self.quantiles):
            raise ValueError("a quantile row decreases (allowed: non-decreasing along the levels)")
        if self.scale_max is not None and (self.scale_floor is None or self.scale_max < self.scale_floor):
            raise ValueError(f"scale_max = {self.scale_max}: allowed only with a scale_floor, at least "
                             f"scale_floor ({self.scale_floor})")
        return self


class Discrepancy(Schema):
    """The optional top-level ``"discrepancy"`` key of a parameter file, beside ``uncertainty``: the model's
    error learned where the truth is known (replays of flights through the FMU), per signal and horizon, as
    empirical quantiles at ``levels``; ``validate --mc`` adds draws from it to the parameter draws
    (``identification.validation.discrepancy``)."""

    levels: list[Level] = Field(min_length=2, max_length=MAX_QUANTILE_LEVELS)
    signals: dict[str, SignalDiscrepancy] = Field(min_length=1, max_length=MAX_DISCREPANCY_SIGNALS)
    window_s: float = Field(ge=0.0, le=86400.0, allow_inf_nan=False)
    rate_hz: float = Field(gt=0.0, le=2000.0, allow_inf_nan=False)
    #: the learning replays' fixed-wing window start velocity (``validate --start-velocity``; None: not recorded)
    start_velocity: Literal["force", "logged"] | None = None
    logs: list[Annotated[str, Field(max_length=1000)]] = Field(default_factory=list, max_length=1000)
    note: str = Field("", max_length=2000)  #: how the numbers were made; not read

    @model_validator(mode="after")
    def _levels(self) -> Discrepancy:
        if any(b <= a for a, b in itertools.pairwise(self.levels)):
            raise ValueError(f"levels = {self.levels}: allowed strictly increasing values in (0, 1)")
        bad = [k for k, s in self.signals.items() if any(len(r) != len(self.levels) for r in s.quantiles)]
        if bad:
            raise ValueError(f"signals {', '.join(bad)}: a quantile row's length differs from levels' "
                             f"({len(self.levels)}; allowed: one value per level)")
        return self


def discrepancy_bins(s: SignalDiscrepancy, h_s: np.ndarray) -> np.ndarray:
    """Index of the horizon bin of each horizon ``h_s`` [s] (time since the replay window restarted from the logged
    state); a horizon beyond the learned ones takes the last bin, not an extrapolation."""
    edges = np.asarray(s.horizon_edges_s)
    return np.clip(np.searchsorted(edges, np.asarray(h_s, float), side="right") - 1, 0, len(s.quantiles) - 1)


def discrepancy_scale(s: SignalDiscrepancy, model: np.ndarray, first: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """What the stored quantiles of ``s`` multiply, per sample: 1 when they are of logged - FMU itself, else the
    basis (``scale_by``) + ``scale_floor``. ``model``: the FMU output; ``first``: the FMU output at the first sample
    of each sample's replay window; ``slope``: |dFMU/dt| [unit/s] (same shapes). The one definition for learning,
    ``validate --mc`` and the HIL record's band. Held at ``scale_max`` where given."""
    model = np.asarray(model, float)
    if s.scale_floor is None:
        return np.ones_like(model)
    if s.scale_by == "magnitude":
        basis = np.abs(model)
    elif s.scale_by == "slope":
        basis = np.abs(np.asarray(slope, float))
    else:
        d = model - np.asarray(first, float)
        if s.wrap:
            d = (d + math.pi) % (2.0 * math.pi) - math.pi
        basis = np.abs(d)
    scale = basis + s.scale_floor
    return scale if s.scale_max is None else np.minimum(scale, s.scale_max)  # NaN stays NaN


def discrepancy_quantile(disc: Discrepancy, name: str, level: float, h_s: np.ndarray, model: np.ndarray,
                         first: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """Quantile at ``level`` (inside the stored levels, linear between them) of signal ``name``'s logged - FMU at
    horizons ``h_s`` [s], in the FMU output's unit, given the FMU output ``model``, its value ``first`` at each
    sample's window start and its slope (:func:`discrepancy_scale`)."""
    s = disc.signals[name]
    levels = np.asarray(disc.levels)
    if not levels[0] <= level <= levels[-1]:
        raise ValueError(f"level {level}: allowed {levels[0]:g}..{levels[-1]:g} (the stored quantile levels)")
    at = np.array([float(np.interp(level, levels, row)) for row in s.quantiles])
    return at[discrepancy_bins(s, h_s)] * discrepancy_scale(s, model, first, slope)


def discrepancy_of(data: dict[str, Any], path: str) -> Discrepancy | None:
    """The ``discrepancy`` block of parameter-file contents ``data`` read from ``path`` (None when there is none;
    :class:`ParameterError` naming the file and each problem when it is malformed)."""
    from fmu_models.config import validate_config

    if not isinstance(data, dict) or "discrepancy" not in data:
        return None
    try:
        return validate_config(data["discrepancy"], Discrepancy, str(path))
    except ConfigError as err:
        lines = [re.sub(r"^field \(top level\) = .*: Value error, ", "", p) for p in err.problems]
        raise ParameterError(err.source, [f"discrepancy: {p}" for p in lines]) from None


def read_uncertainty(path: str | Path) -> Uncertainty:
    """The ``uncertainty`` block of a parameter file (JSON, or TOML by suffix); :class:`ParameterError` naming
    the file and each problem when it is missing or malformed."""
    return uncertainty_of(read_json(path), str(path))


def uncertainty_of(data: dict[str, Any], path: str) -> Uncertainty:
    """The ``uncertainty`` block of parameter-file contents ``data`` read from ``path`` (named in errors)."""
    from fmu_models.config import validate_config

    if "uncertainty" not in data:
        raise ParameterError(str(path), ['no "uncertainty" key: identify with a covariance, or add '
                                         '{"uncertainty": {"names": [...], "mean": [...], "covariance": [[...]]}}'])
    try:
        return validate_config(data["uncertainty"], Uncertainty, str(path))
    except ConfigError as err:
        lines = [re.sub(r"^field \(top level\) = .*: Value error, ", "", p) for p in err.problems]
        raise ParameterError(err.source, [f"uncertainty: {p}" for p in lines]) from None

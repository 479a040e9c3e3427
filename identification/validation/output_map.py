"""Which FMU output is compared with which logged signal, with unit, frame, angle handling and pass rules.

Config (TOML, checked by the typed schema :class:`OutputMapFile` of ``fmu_models.config``)::

    [thresholds]
    max_theil = 0.3                  # Theil's U below this (default for every signal)
    min_skill_persistence = 0.0      # skill against persistence above this (default for every signal)

    [signals.yaw_rad]                # FMU output
    log = "yaw_rad"                  # canonical log signal or raw "MSG.Field"
    log_unit = "rad"                 # unit of the log values; converted to the FMU output's unit
    scale = 1.0                      # after unit conversion; -1 flips an axis (FLU -> FRD, up -> down)
    scale_by_param = ""              # multiply by an FMU parameter too (e.g. mass_kg: specific force -> force)
    offset = 0.0
    wrap = true                      # angle: every metric and plot on the wrapped difference (-180..180 deg)
    max_theil = 0.5                  # per-signal Theil threshold
    max_rmse = 0.02                  # tolerance [signal unit]: also accurate enough below it; a window where
                                     # the signal moves less than this is "n/a" (nothing to score)
    min_skill_persistence = 0.0      # must beat holding the window's first logged value (always required)
    min_skill_mean = 0.0             # optional: must beat the window mean of the log too
    gate = true                      # false: scored and reported, but its verdict does not set the exit status

A ``[signals]`` table replaces the vehicle's default map; ``[signals_extra]`` adds to it.

Verdict of a signal over samples (one window, or all scored windows pooled), in this order: ``n/a`` when the
signal and the model both stay within ``max_rmse`` of persistence (nothing to score); ``FAIL`` "loses to
persistence" when ``1 - RMSE/RMSE_persistence <= min_skill_persistence``; ``FAIL`` when Theil's U is not below
``max_theil`` (and the RMSE not below ``max_rmse``); ``FAIL`` when ``min_skill_mean`` is set and not met;
``tie`` when the pooled skill's block-bootstrap interval (over the replay windows,
:func:`identification.common.metrics.skill_interval`) reaches down to ``min_skill_persistence``: the model beats
persistence by a margin that noise makes; else ``pass``. ``max_rmse`` can never pass a signal that loses to
persistence. A single window has no interval: its verdict is the point rule alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from fmu_models.common.units import LOG_UNITS
from fmu_models.config import ConfigError, FiniteFloat, PositiveFiniteFloat, Schema, read_config_file, validate_config
from identification.common.metrics import FitMetrics, SkillInterval, skill

DEFAULT_MAX_THEIL = 0.3
DEFAULT_MIN_SKILL = 0.0
#: log unit -> (SI unit, factor): one table for the readers and the output maps
UNIT_CONVERSIONS = LOG_UNITS
SI_UNITS = ("m", "rad", "m/s", "m/s2", "rad/s", "N", "1", "s")


class OutputMapError(ConfigError):
    """A bad output-map config or a unit that does not fit the FMU output; names file, signal and value."""


Skill = Annotated[float, Field(ge=-100.0, lt=1.0, allow_inf_nan=False)]


class SignalEntry(Schema):
    """One ``[signals.<fmu output>]`` table."""

    log: str | None = None  # canonical log signal or raw "MSG.Field" (default: the FMU output's name)
    log_unit: str | None = None  # unit of the log values, converted to the FMU output's unit (deg, cm, g, ...)
    scale: FiniteFloat = 1.0  # after unit conversion; -1 flips an axis (FLU -> FRD, up -> down)
    scale_by_param: str | None = None  # multiply by this FMU parameter too (mass_kg: specific force -> force)
    offset: FiniteFloat = 0.0  # added after scaling [FMU unit]
    wrap: bool = False  # an angle: every metric and plot on the wrapped difference (-180..180 deg)
    max_theil: PositiveFiniteFloat | None = None  # Theil's U must be below this (default: thresholds.max_theil)
    max_rmse: PositiveFiniteFloat | None = None  # tolerance [FMU unit]: accurate below it; moving less is n/a
    min_skill_persistence: Skill | None = None  # skill against persistence must exceed this over its interval
    min_skill_mean: Skill | None = None  # optional: must beat the window mean of the log by this too
    gate: bool = True  # false: scored and reported, but its verdict does not set the run's status


class Thresholds(Schema):
    """Defaults for every signal of the map."""

    max_theil: PositiveFiniteFloat = DEFAULT_MAX_THEIL  # Theil's U below this (0 perfect, 1 useless)
    min_skill_persistence: Skill = DEFAULT_MIN_SKILL  # skill against persistence above this, with confidence


class OutputMapFile(Schema):
    """An output-map file."""

    thresholds: Thresholds = Thresholds()  # defaults for every signal
    signals: dict[str, SignalEntry] | None = None  # by FMU output name: replaces the vehicle's default map
    signals_extra: dict[str, SignalEntry] = Field(default_factory=dict)  # by FMU output name: added to it


@dataclass(frozen=True)
class SignalMap:
    fmu: str
    log: str
    log_unit: str | None = None
    scale: float = 1.0
    scale_by_param: str | None = None
    offset: float = 0.0
    wrap: bool = False
    max_theil: float = DEFAULT_MAX_THEIL
    max_rmse: float | None = None
    min_skill_persistence: float = DEFAULT_MIN_SKILL
    min_skill_mean: float | None = None
    gate: bool = True

    def judge(self, fit: FitMetrics, rmse_persistence: float, rmse_mean: float,
              interval: SkillInterval | None = None) -> tuple[str, str]:
        """``(verdict, reason)`` of a fit beside its baselines and, for pooled scores, the interval of its skill
        against persistence; see the module docstring for the rules."""
        tol = self.max_rmse
        sp, sm = skill(fit.rmse, rmse_persistence), skill(fit.rmse, rmse_mean)
        if fit.rmse <= (tol or 0.0) and rmse_persistence <= (tol or 0.0):
            return "n/a", (f"moved less than its tolerance {tol:g} (persistence RMSE {rmse_persistence:.3g}): "
                           "nothing to score" if tol else "constant and matched exactly: nothing to score")
        if not sp > self.min_skill_persistence:  # NaN (persistence exact, model not) fails too
            return "FAIL", (f"loses to persistence: skill {sp:+.2f} (RMSE {fit.rmse:.3g} against "
                            f"{rmse_persistence:.3g} for holding the window's first logged value; needs > "
                            f"{self.min_skill_persistence:g})")
        if not (fit.theil_u < self.max_theil or (tol is not None and fit.rmse < tol)):
            extra = f" and RMSE {fit.rmse:.3g} >= {tol:g}" if tol is not None else ""
            return "FAIL", f"inaccurate: Theil U {fit.theil_u:.3f} >= {self.max_theil:g}{extra}"
        if self.min_skill_mean is not None and not sm > self.min_skill_mean:
            return "FAIL", f"loses to the window mean: skill {sm:+.2f} (needs > {self.min_skill_mean:g})"
        if interval is not None and not interval.lo > self.min_skill_persistence:
            return "tie", (f"no better than persistence with confidence: skill {sp:+.3f}, "
                           f"{100 * interval.level:.0f} % interval {_signed(interval.lo)}..{_signed(interval.hi)} "
                           f"over {interval.n_blocks} windows reaches {self.min_skill_persistence:g}")
        margin = "" if interval is None else \
            f" {100 * interval.level:.0f} % interval {_signed(interval.lo)}..{_signed(interval.hi)},"
        return "pass", (f"beats persistence (skill {sp:+.2f},{margin} Theil U {fit.theil_u:.3f} < "
                        f"{self.max_theil:g})")

    def convert(self, values: np.ndarray, fmu_unit: str | None, params: Mapping[str, float]) -> np.ndarray:
        """Log values in the FMU output's unit and frame."""
        factor = self.scale
        if self.log_unit:
            si, f = UNIT_CONVERSIONS.get(self.log_unit, (self.log_unit, 1.0))
            if fmu_unit and si != fmu_unit:
                raise OutputMapError("output map", [f"signals.{self.fmu}: log unit {self.log_unit!r} converts to "
                                                    f"{si!r}, but the FMU output is in {fmu_unit!r}"])
            factor *= f
        if self.scale_by_param:
            if self.scale_by_param not in params:
                raise OutputMapError("output map", [f"signals.{self.fmu}.scale_by_param: {self.scale_by_param!r} "
                                                    "is not an FMU parameter"])
            factor *= params[self.scale_by_param]
        return np.asarray(values, dtype=float) * factor + self.offset

    def align(self, model: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """Model values brought within pi of the measurement for angles (``wrap``), else unchanged: the
        difference of the two is then the wrapped error (-pi..pi) for every metric and plot."""
        if not self.wrap:
            return model
        return measured + (model - measured + math.pi) % (2 * math.pi) - math.pi


#: tolerances of the default maps: ~1 deg of attitude, ~2 deg/s of body rate (a few sensor sigmas)
ANGLE_TOL_RAD, RATE_TOL_RAD_S = 0.02, 0.035


def _gyro(axis: str) -> SignalMap:
    return SignalMap(f"rate_body_{axis}_rad_s", f"gyro_body_{axis}_rad_s", max_rmse=RATE_TOL_RAD_S)


def _angle(name: str, wrap: bool = False) -> SignalMap:
    return SignalMap(name, name, wrap=wrap, max_rmse=ANGLE_TOL_RAD)


QUADROTOR = (
    SignalMap("altitude_m", "altitude_m"), _angle("roll_rad"), _angle("pitch_rad"), _angle("yaw_rad", wrap=True),
    _gyro("x"), _gyro("y"), _gyro("z"),
    # paper 000 Fig. 5: the thrust map's force against the measured F_z = -m a_z (specific force, FRD)
    SignalMap("thrust_total_N", "accel_body_z_m_s2", scale=-1.0, scale_by_param="mass_kg"),
)
FIXED_WING = (
    _angle("roll_rad"), _angle("pitch_rad"), _angle("yaw_rad", wrap=True), _gyro("x"), _gyro("y"), _gyro("z"),
    SignalMap("airspeed_m_s", "airspeed_m_s"),
    SignalMap("accel_body_x_m_s2", "accel_body_x_m_s2"), SignalMap("accel_body_y_m_s2", "accel_body_y_m_s2"),
    SignalMap("accel_body_z_m_s2", "accel_body_z_m_s2"), SignalMap("altitude_m", "altitude_m"),
)
DEFAULTS = {"quadrotor": QUADROTOR, "fixed_wing": FIXED_WING}


def load(path: str | Path | None, vehicle: str) -> tuple[SignalMap, ...]:
    """The vehicle's default map, or the map of a TOML/JSON file (every problem reported at once)."""
    if vehicle not in DEFAULTS:
        raise OutputMapError("output map", [f"no default output map for vehicle {vehicle!r} "
                                            f"(known: {', '.join(DEFAULTS)})"])
    if path is None:
        return DEFAULTS[vehicle]
    try:
        data = read_config_file(path)
    except ConfigError as err:
        raise OutputMapError(err.source, err.problems) from None
    return from_dict(data, vehicle, str(path))


def _unit_problems(table: str, fmu: str, entry: SignalEntry) -> list[str]:
    problems = []
    unit = entry.log_unit
    if unit and unit not in UNIT_CONVERSIONS and "/" not in unit and unit not in SI_UNITS:
        problems.append(f"{table}.{fmu}.log_unit = {unit!r}; known: {', '.join(UNIT_CONVERSIONS)} or an SI unit")
    return problems


def from_dict(data: Mapping[str, Any], vehicle: str, source: str = "output map") -> tuple[SignalMap, ...]:
    """Maps of a decoded config; :class:`OutputMapError` lists every problem with field, value and range."""
    problems = [f"{table}.{fmu}: 'log' (the logged signal) is required"
                for table in ("signals", "signals_extra") if isinstance(data.get(table), Mapping)
                for fmu, raw in data[table].items() if isinstance(raw, Mapping) and "log" not in raw]
    try:
        cfg = validate_config(data, OutputMapFile, source)
    except ConfigError as err:
        raise OutputMapError(source, err.problems + problems) from None
    th = cfg.thresholds
    defaults = {"max_theil": th.max_theil, "min_skill_persistence": th.min_skill_persistence}
    base = {} if cfg.signals is not None else {m.fmu: replace(m, **defaults) for m in DEFAULTS[vehicle]}
    for table, entries in (("signals", cfg.signals or {}), ("signals_extra", cfg.signals_extra)):
        for fmu, entry in entries.items():
            found = _unit_problems(table, fmu, entry)
            problems += found
            if found or entry.log is None:
                continue
            given = {k: v for k, v in entry.model_dump().items() if v is not None}
            base[fmu] = SignalMap(fmu=fmu, **{**defaults, **given})
    if problems:
        raise OutputMapError(source, problems)
    if not base:
        raise OutputMapError(source, ["no signals to compare"])
    return tuple(base.values())


def _signed(x: float) -> str:
    return f"{x:+.3f}" if math.isfinite(x) else "n/a"

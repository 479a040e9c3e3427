"""ANFIS (Jang 1993; paper 000 section 2.1) as data plus one forward pass for numpy and CasADi.

Layer 1 passes the inputs, layer 2 applies membership functions (Gaussian ``exp(-(x-m)^2/sigma^2)``
exactly as paper 000 eq. 2, or generalised bell ``1/(1+|(x-m)/sigma|^(2b))``), layer 3 forms rule firing
strengths by product AND over a grid partition (every combination of one MF per input, the last input
varying fastest), layer 4 weights Takagi-Sugeno consequents (zero order: ``f = r``; first order:
``f = sum_i p_i x_i + r``), layer 5 is the normalised weighted average (eq. 4).

All numbers are in raw input units (summed PWM in us for the thrust map); a trainer that scales inputs
internally must convert back before writing the JSON. The JSON schema (``to_dict``/``from_dict``) is the one
``identification`` writes and the quadrotor FMU reads.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmu_models.common.errors import ParameterError, ProblemList
from fmu_models.common.mathns import NP
from fmu_models.common.params import read_json
from fmu_models.config import ConfigError, FiniteFloat, Schema, validate_config

MF_TYPES = ("gaussian", "gbell")
#: consequent features of one input x (a per-motor command, 0 at idle) and the battery ratio r = V/V_nom
FEATURES = ("x2", "x", "x2_r")


def feature_values(names: tuple[str, ...], x: Any, r: Any = 1.0) -> list[Any]:
    """Values of the named :data:`FEATURES` at ``x`` (and ``r``), numpy or CasADi."""
    table = {"x2": lambda: x * x, "x": lambda: x, "x2_r": lambda: x * x * r}
    return [table[n]() for n in names]


class AnfisMapFile(Schema):
    """Types of a thrust-map table (strict: no bool/str for numbers, finite); :meth:`AnfisMap.from_dict`
    checks the shapes and values after it."""

    type: str = "anfis"
    inputs: list[str] | None = None
    mf_type: str = "gaussian"
    mf_mean: list[list[FiniteFloat]] | None = None
    mf_sigma: list[list[FiniteFloat]] | None = None
    mf_slope: list[list[FiniteFloat]] | None = None
    order: int = 0
    consequents: list[list[FiniteFloat]] | None = None
    input_range: list[list[FiniteFloat]] | None = None
    features: list[str] | None = None
    output: str = "thrust_N"
    source: str = ""


@dataclass(frozen=True)
class AnfisMap:
    """A trained ANFIS: membership functions per input, one consequent row per rule.

    ``mf_mean[i][j]``, ``mf_sigma[i][j]``: centre and width of MF j of input i (input units).
    ``mf_slope[i][j]``: bell exponent b (gbell only).
    ``consequents[r]``: ``[r0]`` (order 0) or ``[p_1, ..., p_n, r0]`` (order 1) for rule r.
    ``input_range[i]``: ``(lo, hi)`` band input i was trained on; the map is trusted only inside it.
    ``features``: first-order consequents over named features of the one input ``x`` instead of the inputs
    (:data:`FEATURES`: ``x2`` = x^2, ``x`` = x, ``x2_r`` = x^2 r with r = V/V_nom); each row then holds one
    coefficient per feature and no constant, so every rule, and the map, is zero at x = 0 (idle).
    """

    inputs: tuple[str, ...]
    mf_type: str
    mf_mean: tuple[tuple[float, ...], ...]
    mf_sigma: tuple[tuple[float, ...], ...]
    mf_slope: tuple[tuple[float, ...], ...] | None
    order: int
    consequents: tuple[tuple[float, ...], ...]
    input_range: tuple[tuple[float, float], ...]
    output: str = "thrust_N"
    source: str = ""
    features: tuple[str, ...] | None = None

    # ----------------------------------------------------------------- structure
    @property
    def n_inputs(self) -> int:
        return len(self.inputs)

    @property
    def n_mfs(self) -> tuple[int, ...]:
        return tuple(len(m) for m in self.mf_mean)

    @property
    def n_rules(self) -> int:
        return math.prod(self.n_mfs)

    def rule_indices(self) -> list[tuple[int, ...]]:
        """MF index per input for each rule, in consequent order (grid partition)."""
        return list(itertools.product(*(range(n) for n in self.n_mfs)))

    # ----------------------------------------------------------------- forward pass
    def memberships(self, x: list[Any], xp: Any = NP) -> list[list[Any]]:
        """Layer 2: ``mu[i][j]`` for input values ``x[i]`` (arrays of samples or CasADi scalars)."""
        mu = []
        for i, xi in enumerate(x):
            row = []
            for j, (m, s) in enumerate(zip(self.mf_mean[i], self.mf_sigma[i], strict=True)):
                z = (xi - m) / s
                if self.mf_type == "gaussian":
                    row.append(xp.exp(-(z * z)))
                else:
                    b = self.mf_slope[i][j]  # type: ignore[index]
                    row.append(1.0 / (1.0 + xp.fabs(z) ** (2.0 * b)))
            mu.append(row)
        return mu

    def firing(self, x: list[Any], xp: Any = NP) -> list[Any]:
        """Layer 3: product-AND firing strength of every rule."""
        mu = self.memberships(x, xp)
        out = []
        for idx in self.rule_indices():
            w = mu[0][idx[0]]
            for i in range(1, self.n_inputs):
                w = w * mu[i][idx[i]]
            out.append(w)
        return out

    def rule_outputs(self, x: list[Any], r: Any = 1.0) -> list[Any]:
        """Layer 4 consequents ``f_r`` (before weighting); ``r`` = V/V_nom for the ``x2_r`` feature."""
        if self.features is not None:
            phi = feature_values(self.features, x[0], r)
            out = []
            for row in self.consequents:
                f = row[0] * phi[0]
                for c, p in zip(row[1:], phi[1:], strict=True):
                    f = f + c * p
                out.append(f)
            return out
        out = []
        for row in self.consequents:
            f = row[-1]
            if self.order == 1:
                for i in range(self.n_inputs):
                    f = f + row[i] * x[i]
            out.append(f)
        return out

    def evaluate(self, x: list[Any], xp: Any = NP, r: Any = 1.0) -> Any:
        """Layer 5 (paper 000 eq. 4): ``sum(w_r f_r) / sum(w_r)``, with no band handling."""
        w = self.firing(x, xp)
        f = self.rule_outputs(x, r)
        num = w[0] * f[0]
        den = w[0]
        for wr, fr in zip(w[1:], f[1:], strict=True):
            num = num + wr * fr
            den = den + wr
        return num / den

    # ----------------------------------------------------------------- data
    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "type": "anfis",
            "inputs": list(self.inputs),
            "mf_type": self.mf_type,
            "mf_mean": [list(r) for r in self.mf_mean],
            "mf_sigma": [list(r) for r in self.mf_sigma],
            "order": self.order,
            "consequents": [list(r) for r in self.consequents],
            "input_range": [list(r) for r in self.input_range],
            "output": self.output,
            "source": self.source,
        }
        if self.mf_slope is not None:
            d["mf_slope"] = [list(r) for r in self.mf_slope]
        if self.features is not None:
            d["features"] = list(self.features)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "thrust_map") -> AnfisMap:
        """Build and check a map; every problem is reported at once (``ParameterError``)."""
        try:
            d = validate_config(d, AnfisMapFile, source).model_dump(exclude_unset=True)
        except ConfigError as err:
            raise ParameterError(source, err.problems) from None
        probs = ProblemList(source)
        if d.get("type", "anfis") != "anfis":
            probs.add(f"type = {d.get('type')!r}; only 'anfis' is supported")
        inputs = tuple(d.get("inputs") or ())
        if not inputs:
            probs.add("inputs is missing or empty (list of input names, e.g. ['pwm_sum_us'])")
        mf_type = d.get("mf_type", "gaussian")
        if mf_type not in MF_TYPES:
            probs.add(f"mf_type = {mf_type!r}; allowed: {', '.join(MF_TYPES)}")
        order = d.get("order", 0)
        if order not in (0, 1):
            probs.add(f"order = {order!r}; allowed: 0 (zero-order) or 1 (first-order Takagi-Sugeno)")
        mean, sigma = _table(d, "mf_mean", probs), _table(d, "mf_sigma", probs)
        slope = _table(d, "mf_slope", probs) if mf_type == "gbell" else None
        cons = _table(d, "consequents", probs)
        rng_raw = _table(d, "input_range", probs)
        features = d.get("features")
        width = None
        if features is not None:
            features = tuple(features)
            width = len(features)
            _check_features(probs, features, len(inputs), order)
        _check_tables(probs, len(inputs), order, mean, sigma, slope, cons, rng_raw, width)
        probs.raise_if_any()
        return cls(
            inputs=inputs,
            mf_type=mf_type,
            mf_mean=mean,
            mf_sigma=sigma,
            mf_slope=slope,
            order=int(order),
            consequents=cons,
            input_range=tuple((r[0], r[1]) for r in rng_raw if len(r) == 2),
            output=str(d.get("output", "thrust_N")),
            source=str(d.get("source", "")),
            features=features,
        )

    @classmethod
    def load(cls, path: str | Path) -> AnfisMap:
        data = read_json(path)
        return cls.from_dict(data.get("thrust_map", data), source=str(path))

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")


_Table = tuple[tuple[float, ...], ...]


def _table(d: dict[str, Any], key: str, probs: ProblemList) -> _Table:
    """``d[key]`` as a tuple of float rows; a problem (and ``()``) when it is missing or not numbers."""
    raw = d.get(key)
    if raw is None:
        probs.add(f"{key} is missing")
        return ()
    try:
        return tuple(tuple(float(v) for v in row) for row in raw)
    except (TypeError, ValueError):
        probs.add(f"{key} must be a list of lists of numbers, got {raw!r}")
        return ()


def _check_features(probs: ProblemList, features: tuple[str, ...], n_inputs: int, order: int) -> None:
    """Problems of a feature-consequent map: known, distinct features, one input, first order."""
    bad = [f for f in features if f not in FEATURES]
    if bad or not features or len(set(features)) != len(features):
        probs.add(f"features = {list(features)}; allowed: distinct names from {', '.join(FEATURES)}")
    if n_inputs != 1 or order != 1:
        probs.add(f"features need one input and order 1, got {n_inputs} input(s) and order {order}")


def _check_tables(
    probs: ProblemList, n: int, order: int, mean: _Table, sigma: _Table, slope: _Table | None, cons: _Table,
    rng: _Table, width: int | None = None,
) -> None:
    """Add a problem for every table whose shape or values do not fit ``n`` inputs and ``order``."""
    for key, tab in (("mf_mean", mean), ("mf_sigma", sigma), ("input_range", rng)):
        if tab and len(tab) != n:
            probs.add(f"{key} has {len(tab)} rows, expected one per input ({n})")
    if mean and sigma and [len(r) for r in mean] != [len(r) for r in sigma]:
        probs.add("mf_mean and mf_sigma must have the same number of MFs per input")
    if slope is not None and [len(r) for r in slope] != [len(r) for r in mean]:
        probs.add("mf_slope must have the same shape as mf_mean")
    for i, row in enumerate(sigma):
        for j, s in enumerate(row):
            if not (s > 0.0 and math.isfinite(s)):
                probs.add(f"mf_sigma[{i}][{j}] = {s}; must be > 0")
    for i, r in enumerate(rng):
        if len(r) != 2 or not (math.isfinite(r[0]) and math.isfinite(r[1]) and r[0] < r[1]):
            probs.add(f"input_range[{i}] = {list(r)}; must be [lo, hi] with lo < hi")
    n_rules = math.prod(len(r) for r in mean) if mean else 0
    width = width if width is not None else 1 + (n if order == 1 else 0)
    if cons and len(cons) != n_rules:
        probs.add(f"consequents has {len(cons)} rows, expected one per rule ({n_rules})")
    for r, row in enumerate(cons):
        if len(row) != width:
            probs.add(f"consequents[{r}] has {len(row)} values, expected {width} for order {order}")
        if not all(math.isfinite(v) for v in row):
            probs.add(f"consequents[{r}] = {list(row)} has a non-finite value")


#: Paper 000 Tables 2 and 3: six Gaussian MFs on the summed PWM of four motors, zero-order consequents.
PUBLISHED_MEAN_US = (5924.4, 6010.3, 5800.0, 5961.9, 6045.2, 6217.3)
PUBLISHED_SIGMA_US = (40.2, 100.0, 100.0, 42.8, 38.5, 78.5)
PUBLISHED_FZ_N = (10.0, 10.5, 10.6, 11.4, 11.6, 11.9)


def published_map() -> AnfisMap:
    """The thrust map of paper 000 (Tables 2-3).

    The paper gives no trained band; its flight data sit where the MF centres are, so the band is
    taken as [min mean, max mean] = [5800, 6217.3] us summed. Outside it the published map folds back
    (at 4000 us it returns 10.6 N, more than the 10.37 N it gives at 5900 us).
    """
    return AnfisMap(
        inputs=("pwm_sum_us",),
        mf_type="gaussian",
        mf_mean=(PUBLISHED_MEAN_US,),
        mf_sigma=(PUBLISHED_SIGMA_US,),
        mf_slope=None,
        order=0,
        consequents=tuple((c,) for c in PUBLISHED_FZ_N),
        input_range=((min(PUBLISHED_MEAN_US), max(PUBLISHED_MEAN_US)),),
        output="thrust_N",
        source="Sant'Ana et al., COBEM 2019, Tables 2-3",
    )

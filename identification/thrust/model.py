"""The thrust model of ``uavfmu identify thrust``: candidates, fit, prediction as the FMU evaluates it, baselines.

Per motor ``T_i = r^e G(x_i, r)`` (:func:`fmu_models.quadrotor.thrust.motor_thrust`), ``G`` a one-input ANFIS
with first-order Sugeno consequents over physical features of the per-motor command
``u = (pwm - idle)/(full - idle)``: ``u^2, u`` without voltage; with voltage (``r = V/V_nom``) either
``u^2, u, u^2 r`` (input ``u``) or ``(u r)^2, u r`` (input ``u_eff``: motor speed ~ duty x voltage). A one-rule
map is exactly the least-squares polynomial of its features, so the model family contains its polynomial
rivals; the feature set, the number of rules and the battery-state time constant are chosen by cross-validation
on the training flights only (:func:`select_spec`), never on the held-out flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from fmu_models.common.atmosphere import G0_M_S2 as G0
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import command, constants_of, motor_thrust
from identification.thrust.anfis_train import feature_design, feature_map_monotone, firing_of, train_feature_anfis
from identification.thrust.battery import HOVER_TAUS_S, equivalent_voltage_V, hover_thrust_scale
from identification.thrust.dataset import ThrustDataError, interleaved_blocks

#: (map input, consequent features) tried with a voltage log; without one only the first feature set applies
VOLTAGE_CANDIDATES = (("u", ("x2", "x", "x2_r")), ("u_eff", ("x2", "x")))
NO_VOLTAGE_CANDIDATE = ("u", ("x2", "x"))
SIMPLER_MARGIN = 1e-3  #: a more complex candidate is kept only when its CV RMSE is lower by this fraction


@dataclass(frozen=True)
class ModelSpec:
    """Structure of the thrust model: command range, voltage use, map input/features, rules, battery state."""

    idle_us: float
    full_us: float
    nominal_V: float
    voltage: bool  #: the logged battery voltage feeds the map (``x2_r`` or ``u_eff``)
    input_name: str = "u"
    features: tuple[str, ...] = ("x2", "x")
    n_rules: int = 1
    tau_s: float | None = None  #: hover-condition battery state time constant (None: no state)

    @property
    def exponent(self) -> float:
        """``thrust_voltage_exponent``: 1 carries a no-voltage battery state as an equivalent voltage."""
        return 0.0 if self.voltage else 1.0

    def describe(self) -> str:
        v = f"voltage via {'x^2 r' if 'x2_r' in self.features else 'u_eff = u V/V_nom'}" if self.voltage else ""
        state = f"hover battery state tau {self.tau_s:.0f} s" if self.tau_s else ("" if self.voltage else
                                                                                "no battery state")
        return ", ".join(s for s in (f"{self.n_rules} rule(s)", f"input {self.input_name}",
                                     "features " + "/".join(self.features), v, state) if s)


@dataclass
class FlightData:
    """What the model needs of one flight: per-motor PWM (N, 4) [us], voltage [V] or None, hover mask,
    time [s], measured thrust [N], weight [N], and ``cos(roll) cos(pitch)`` (None: attitude not logged)."""

    name: str
    pwm_us: np.ndarray
    volt_V: np.ndarray | None
    hover: np.ndarray
    time_s: np.ndarray
    thrust_N: np.ndarray
    weight_N: float
    period_s: float
    tilt_cos: np.ndarray | None = None

    def take(self, idx: np.ndarray, name: str) -> FlightData:
        v = None if self.volt_V is None else self.volt_V[idx]
        c = None if self.tilt_cos is None else self.tilt_cos[idx]
        return FlightData(name, self.pwm_us[idx], v, self.hover[idx], self.time_s[idx], self.thrust_N[idx],
                          self.weight_N, self.period_s, c)

    def vertical(self, thrust_N: np.ndarray) -> np.ndarray:
        """The vertical part [N] of a body-z thrust: ``T cos(roll) cos(pitch)`` (T when attitude is not logged)."""
        return thrust_N if self.tilt_cos is None else thrust_N * self.tilt_cos


# --------------------------------------------------------------------------- model evaluation
def _ratio(f: FlightData, spec: ModelSpec) -> np.ndarray:
    return f.volt_V / spec.nominal_V if (spec.voltage and f.volt_V is not None) else np.ones(len(f.thrust_N))


def map_input(f: FlightData, spec: ModelSpec) -> tuple[np.ndarray, np.ndarray]:
    """Per-motor map input x (N, 4) and ratio r (N,) of a flight, as the FMU forms them."""
    u = command(f.pwm_us, spec.idle_us, spec.full_us)
    r = _ratio(f, spec)
    return (u * r[:, None] if spec.input_name == "u_eff" else u), r


def fmu_total_thrust(p: QuadrotorParams, pwm_us: np.ndarray, volt_V: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Total thrust [N] the quadrotor FMU gives for per-motor PWM (N, 4) and its battery input (N,)."""
    c = constants_of(p)
    c = c._replace(scale=c.scale * scale)
    t = motor_thrust(p.thrust_map, np.asarray(pwm_us, float), np.asarray(volt_V, float)[:, None], c, N_MOTORS)
    return np.asarray(t).sum(axis=1)


def battery_input_V(p: QuadrotorParams, spec: ModelSpec, f: FlightData, state: bool = True) -> np.ndarray:
    """The FMU's ``battery_voltage_V`` input for a flight: the logged voltage, or the hover battery state as an
    equivalent voltage (``state``), or the nominal voltage."""
    if spec.voltage and f.volt_V is not None:
        return f.volt_V
    nominal = np.full(len(f.thrust_N), spec.nominal_V)
    if not (state and spec.tau_s):
        return nominal
    base = f.vertical(fmu_total_thrust(p, f.pwm_us, nominal))
    return equivalent_voltage_V(hover_thrust_scale(f.time_s, base, f.hover, f.weight_N, spec.tau_s), spec.nominal_V)


def predict(p: QuadrotorParams, spec: ModelSpec, f: FlightData, state: bool = True) -> np.ndarray:
    """Total thrust [N] of the FMU on flight ``f`` (with its battery state unless ``state`` is False)."""
    return fmu_total_thrust(p, f.pwm_us, battery_input_V(p, spec, f, state))


def hover_scale(pred_N: np.ndarray, f: FlightData) -> float:
    """Per-flight calibration: the scale making the mean predicted vertical thrust over the hover samples m g
    (the same for the model and the baselines)."""
    m = float(np.mean(f.vertical(pred_N)[f.hover]))
    return f.weight_N / m if m > 0.0 else 1.0


# --------------------------------------------------------------------------- fit
@dataclass(frozen=True)
class Fit:
    """A fitted model: its parameters and the least-squares design/residuals of the consequents (for the
    covariance)."""

    params: QuadrotorParams
    design: np.ndarray
    residual_N: np.ndarray


def fit(train: list[FlightData], spec: ModelSpec, epochs: int, check_block_s: float, source: str,
        mass_kg: float | None = None) -> Fit:
    """Train the map of ``spec`` on ``train`` (every 5th block of ``check_block_s`` checks, more than one rule)."""
    xr = [map_input(f, spec) for f in train]
    x = np.concatenate([a for a, _ in xr])
    r = np.concatenate([b for _, b in xr])
    y = np.concatenate([f.thrust_N for f in train])
    check = None
    if spec.n_rules > 1:
        period = float(np.median([f.period_s for f in train]))
        chk = interleaved_blocks(len(y), max(1, round(check_block_s / period)), 5)
        check = (x[chk], r[chk], y[chk])
        x, r, y = x[~chk], r[~chk], y[~chk]
    res = train_feature_anfis(x, r, y, spec.features, spec.n_rules, epochs, check, spec.input_name, source)
    params = QuadrotorParams.from_dict({
        "mass_kg": float(mass_kg if mass_kg is not None else np.mean([f.weight_N for f in train]) / G0),
        "pwm_idle_us": spec.idle_us, "pwm_full_us": spec.full_us, "battery_nominal_V": spec.nominal_V,
        "thrust_voltage_exponent": spec.exponent, "thrust_map": res.amap.to_dict(),
    }, source=source)
    wbar = firing_of(res.amap, x) if spec.n_rules > 1 else None
    design = feature_design(x, r, wbar, spec.features)
    theta = np.concatenate([np.asarray(row) for row in res.amap.consequents])
    return Fit(params, design, y - design @ theta)


def fit_physical(train: list[FlightData], spec: ModelSpec, epochs: int, check_block_s: float, source: str,
                 mass_kg: float | None = None) -> tuple[Fit, ModelSpec]:
    """:func:`fit`, falling back to simpler structures while the map falls with the command somewhere on its
    band: one rule fewer at a time, then the square law ``x^2`` alone (thrust ~ speed^2, monotone when its
    coefficient is positive). ThrustDataError when even that falls: the data do not show thrust rising."""
    tried = [replace(spec, n_rules=n) for n in range(spec.n_rules, 0, -1)]
    tried.append(replace(spec, n_rules=1, features=("x2",)))
    for s in dict.fromkeys(tried):  # distinct, in order
        fitted = fit(train, s, epochs, check_block_s, source, mass_kg)
        if is_physical(fitted.params, train, s):
            return fitted, s
    raise ThrustDataError(f"{source}: even the square law T = a u^2 falls with the command on the band; the data "
                          "do not show thrust rising with PWM")


def is_physical(p: QuadrotorParams, train: list[FlightData], spec: ModelSpec) -> bool:
    """The map rises with the command over its band at the lowest, mean and highest battery ratio flown."""
    r = np.concatenate([_ratio(f, spec) for f in train])
    r_values = (float(r.min()), float(r.mean()), float(r.max())) if "x2_r" in spec.features else (1.0,)
    return feature_map_monotone(p.thrust_map, r_values)


# --------------------------------------------------------------------------- baselines
def poly_features(f: FlightData, spec: ModelSpec, with_voltage: bool) -> np.ndarray:
    """Regressors of the polynomial baselines: sum u^2, sum u (and sum u^2 V/V_nom), u as the model's."""
    u = command(f.pwm_us, spec.idle_us, spec.full_us)
    cols = [(u * u).sum(axis=1), u.sum(axis=1)]
    if with_voltage:
        cols.append((u * u).sum(axis=1) * f.volt_V / spec.nominal_V)  # type: ignore[operator]
    return np.stack(cols, axis=1)


def baseline_predictions(train: list[FlightData], test: FlightData, spec: ModelSpec) -> dict[str, np.ndarray]:
    """Held-out predictions [N] of the constant m g and the least-squares polynomials fitted on ``train``."""
    out = {"constant m g": np.full(len(test.thrust_N), test.weight_N)}
    variants = [("poly sum u^2, sum u", False)]
    if spec.voltage:
        variants.append(("poly sum u^2, sum u, sum u^2 V", True))
    y = np.concatenate([f.thrust_N for f in train])
    for name, with_v in variants:
        a = np.concatenate([poly_features(f, spec, with_v) for f in train])
        out[name] = poly_features(test, spec, with_v) @ np.linalg.lstsq(a, y, rcond=None)[0]
    return out


# --------------------------------------------------------------------------- selection by inner CV
def inner_folds(flights: list[FlightData], n_blocks: int) -> list[tuple[str, list[FlightData], FlightData]]:
    """(name, training flights, held-out set): leave-one-flight-out, or time blocks of a single flight."""
    if len(flights) >= 2:
        return [(f.name, [g for g in flights if g is not f], f) for f in flights]
    f = flights[0]
    n = len(f.thrust_N)
    block = np.minimum(np.arange(n) * n_blocks // n, n_blocks - 1)
    return [(f"{f.name} block {b + 1}/{n_blocks}", [f.take(block != b, f.name)], f.take(block == b, f.name))
            for b in range(n_blocks)]


def candidates(base: ModelSpec, max_rules: int, states: bool) -> list[list[ModelSpec]]:
    """Candidate structures, grouped by map (same fit), simplest first; each group lists its battery states.

    With ``states`` (no voltage log) every candidate carries a hover battery state: a new flight's battery is
    unknown, and a cross-validation inside one training flight (two-flight LOFO) cannot show what the state
    gains between flights; only its time constant is chosen."""
    sets = VOLTAGE_CANDIDATES if base.voltage else (NO_VOLTAGE_CANDIDATE,)
    taus: tuple[float | None, ...] = tuple(sorted(HOVER_TAUS_S, reverse=True)) if states else (None,)
    return [[replace(base, input_name=i, features=feats, n_rules=n, tau_s=t) for t in taus]
            for n in range(1, max_rules + 1) for i, feats in sets]


def select_spec(train: list[FlightData], base: ModelSpec, max_rules: int, epochs: int, check_block_s: float,
                n_blocks: int, calibrate: bool, states: bool = True) -> tuple[ModelSpec, dict[str, float]]:
    """The candidate with the lowest pooled inner-CV RMSE on ``train`` alone (raw, plus calibrated when
    ``calibrate``); a more complex one must be better by ``SIMPLER_MARGIN``. Also returns every score."""
    folds = inner_folds(train, n_blocks)
    scores: dict[str, float] = {}
    best: tuple[float, ModelSpec] = (math.inf, base)
    for group in candidates(base, max_rules, states=states and not base.voltage):
        sse = np.zeros(len(group))
        count = 0
        for _, tr, te in folds:
            p = fit(tr, group[0], epochs, check_block_s, "inner CV").params
            if not is_physical(p, tr, group[0]):  # candidates that fall with the command are not kept
                sse[:] = math.inf
                break
            for k, spec in enumerate(group):
                pred = predict(p, spec, te)
                sse[k] += _sse(pred, te.thrust_N) + (_sse(pred * hover_scale(pred, te), te.thrust_N) if calibrate
                                                     else 0.0)
            count += len(te.thrust_N)
        for k, spec in enumerate(group):
            score = math.sqrt(sse[k] / max(count, 1) / (2.0 if calibrate else 1.0))
            scores[spec.describe()] = score
            if score < best[0] * (1.0 - SIMPLER_MARGIN):
                best = (score, spec)
    return best[1], scores


def _sse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sum((a - b) ** 2))


def covariance(fitted: Fit) -> np.ndarray:
    """Covariance of the consequent coefficients at the fitted premises: the least-squares sandwich
    ``(AᵀA)⁻¹ [Σ_t Σ_s a_t γ(s - t) a_sᵀ] (AᵀA)⁻¹ n/(n - k)`` with the residual autocovariance ``γ`` of an
    autoregressive model of the residuals (Burg, order by AIC; the output-error bounds' treatment,
    :func:`identification.estimation.oem.coloured_covariance_ar`). Serially correlated samples carry less
    information than their count; a lag-1 inflation ``(1 + ρ)/(1 - ρ)``, used before 2026-11-28, sees only the
    first lag and covered 0.65 of the 95 % intervals of white + AR(1) residuals (``bench/thrust_coverage.py``)."""
    from identification.estimation.oem import ar_polynomials, coloured_covariance_ar

    a, e = fitted.design, fitted.residual_N
    n, k = a.shape
    if n <= k:
        raise ThrustDataError(f"{n} samples for {k} coefficients: no covariance")
    inv = np.linalg.pinv(a.T @ a)
    middle = coloured_covariance_ar(a[:, None, :], e[:, None], ar_polynomials([e[:, None]]))
    cov = inv @ middle @ inv * n / (n - k)
    return 0.5 * (cov + cov.T)

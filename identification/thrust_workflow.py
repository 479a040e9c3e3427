"""Thrust identification from many flights of one vehicle, scored as the FMU evaluates it (issue 13).

``identify_thrust(config) -> ThrustResult``. Each flight (log + mass) gives airborne samples of per-motor
PWM, battery voltage (when logged) and measured thrust ``-m a_z``. The model is the quadrotor FMU's: per
motor ``T_i = s F(n pwm_eff_i) / n`` with the voltage-compensated command
``pwm_eff = idle + (pwm - idle) V / V_nom`` (:func:`fmu_models.quadrotor.thrust.motor_thrust`), ``F`` a
one-input ANFIS trained by hybrid learning on the motor sum, kept monotone, zero at idle and extended
physically outside its band. Every figure is computed with that same function (clamps, extrapolation,
voltage, idle, calibration scale ``s``), never from the raw map.

Held-out scoring: leave-one-flight-out with two or more flights, time-blocked folds with one. Beside the
model, on the same held-out samples: the constant ``m g`` and least-squares polynomials in
``u = (pwm - idle)/(pwm_max - idle)`` per motor (``sum u^2, sum u``; with voltage also ``sum u^2 V``).
Logs without voltage can take a per-flight calibration: one scale per flight so that the model's mean
thrust over that flight's hover samples equals ``m g`` (mass and PWM only, no accelerometer); polynomial
baselines get the same calibration so the comparison stays fair.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.atmosphere import G0_M_S2 as G0
from fmu_models.config import bounded, range_problems
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import effective_pwm, motor_thrust
from identification.anfis_train import AnfisTrainConfig, is_monotone, r_squared, rmse, train_anfis_motors
from identification.flightlog import check_quality
from identification.jsonio import write_json
from identification.thrust_dataset import (
    MOTOR_SIGNAL,
    ThrustDataError,
    ThrustDataset,
    ThrustDatasetConfig,
    build_thrust_dataset,
    interleaved_blocks,
    interval_means,
)

HOVER_CLIMB_M_S = 0.3  #: |climb rate| below this is hover (calibration, summaries)
CALIBRATIONS = ("auto", "on", "off")


@dataclass(frozen=True)
class FlightSpec:
    """One log and the vehicle's mass on that flight [kg]."""

    path: Path
    mass_kg: float

    @property
    def name(self) -> str:
        return Path(self.path).name


@dataclass(frozen=True)
class ThrustConfig:
    """Options of :func:`identify_thrust` (checked by :func:`check_config`).

    ``calibrate``: ``auto`` (per-flight calibration when the flights log no voltage), ``on`` or ``off``.
    ``use_voltage``: use the logged battery voltage when every flight has it. ``n_mfs``: most MFs tried (the
count is chosen by an inner CV on the training flights). ``n_folds_single``: time
    blocks when only one flight is given. ``out``/``metrics``: files to write (None: write nothing).
    """

    flights: tuple[FlightSpec, ...]
    out: Path | None = None
    metrics: Path | None = None
    pwm_idle_us: float = bounded(1000.0, 800.0, 1500.0, "us")
    pwm_max_us: float = bounded(2000.0, 1000.0, 2500.0, "us")
    use_voltage: bool = True
    calibrate: str = "auto"
    n_mfs: int = bounded(2, 1, 8)
    epochs: int = bounded(30, 1, 2000)
    n_folds_single: int = bounded(3, 2, 20)
    motor_min_pwm_us: float = bounded(1150.0, 800.0, 2200.0, "us")
    max_lag_s: float = bounded(0.3, 0.0, 5.0, "s")
    lowpass_hz: float | None = bounded(None, 1e-3, 1000.0, "Hz (None: no filter)", optional=True)
    check_block_s: float = bounded(5.0, 0.1, 600.0, "s")
    channel_map: Path | None = None
    force: bool = False


@dataclass
class Flight:
    """Airborne samples of one flight: per-motor PWM (N, 4) [us], voltage [V] or None, thrust [N]."""

    spec: FlightSpec
    data: ThrustDataset
    pwm_us: np.ndarray
    volt_V: np.ndarray | None
    hover: np.ndarray
    yaw_rate: np.ndarray | None = None
    reader_warnings: tuple[str, ...] = ()
    quality: dict[str, Any] | None = None  #: the log's data-quality summary (``DataQuality.to_dict``)

    @property
    def weight_N(self) -> float:
        return self.spec.mass_kg * G0

    def take(self, idx: np.ndarray) -> Flight:
        v = None if self.volt_V is None else self.volt_V[idx]
        r = None if self.yaw_rate is None else self.yaw_rate[idx]
        return Flight(self.spec, self.data.subset(idx), self.pwm_us[idx], v, self.hover[idx], r)


@dataclass(frozen=True)
class Score:
    """RMSE [N] and R^2 of one predictor on one held-out set."""

    rmse_N: float
    r2: float


@dataclass(frozen=True)
class FoldResult:
    """Scores on one held-out flight (or time block): the model and every baseline by name."""

    held_out: str
    n_samples: int
    model: Score
    baselines: dict[str, Score]
    calibration_scale: float
    n_mfs: int = 0

    @property
    def best_baseline(self) -> str:
        return min(self.baselines, key=lambda k: self.baselines[k].rmse_N)


@dataclass(frozen=True)
class ThrustResult:
    """Outcome of :func:`identify_thrust`: parameters, held-out table, verdict, per-flight summaries."""

    params: QuadrotorParams
    folds: tuple[FoldResult, ...]
    pooled_model_rmse_N: float
    pooled_baseline_rmse_N: dict[str, float]
    model_beats_baselines: bool
    flights: tuple[dict[str, Any], ...]
    calibration: dict[str, float]
    metrics: dict[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def params_for(self, flight: str) -> QuadrotorParams:
        """The parameters to replay ``flight`` with: its calibration scale as ``thrust_scale`` (else 1)."""
        return dataclasses.replace(self.params, thrust_scale=self.calibration.get(flight, 1.0))

    @property
    def exit_code(self) -> int:
        """0 when the model beats every baseline on held-out data (or ``force``), else 3."""
        return 0 if self.model_beats_baselines or self.metrics.get("forced") else 3


# --------------------------------------------------------------------------- input
def check_config(cfg: ThrustConfig) -> None:
    """Every problem of ``cfg`` in one :class:`ThrustDataError` (flight, field, value, allowed range)."""
    probs = []
    if not cfg.flights:
        probs.append("no flight given (LOG[=MASS_KG] ...)")
    for f in cfg.flights:
        m = f.mass_kg
        if not (isinstance(m, int | float) and math.isfinite(m) and 0.05 <= m <= 50.0):
            probs.append(f"flight {f.name}: field mass_kg = {m!r}; allowed a finite number in [0.05, 50] kg")
    probs += range_problems(cfg)
    if not probs and not cfg.pwm_idle_us < cfg.pwm_max_us:
        probs.append(f"pwm_idle_us = {cfg.pwm_idle_us}, pwm_max_us = {cfg.pwm_max_us}; need idle < max")
    if cfg.calibrate not in CALIBRATIONS:
        probs.append(f"calibrate = {cfg.calibrate!r}; allowed: {', '.join(CALIBRATIONS)}")
    if probs:
        raise ThrustDataError("identify thrust: " + "; ".join(probs))


def load_flight(spec: FlightSpec, cfg: ThrustConfig) -> Flight:
    """Read one log and cut its airborne samples (errors name the flight and the field)."""
    from identification.readers import read_log

    log = read_log(spec.path, channel_map=cfg.channel_map)
    check_quality(log, cfg.force)  # a log damaged beyond DEFAULT_MAX_DAMAGE is refused unless forced
    ds_cfg = ThrustDatasetConfig(
        mass_kg=spec.mass_kg,
        motor_min_pwm_us=cfg.motor_min_pwm_us,
        max_lag_s=cfg.max_lag_s,
        lowpass_hz=cfg.lowpass_hz,
        pwm_idle_us=min(max(cfg.pwm_idle_us, 800.0), 1500.0),
        airborne_on_mean_pwm=True,
    )
    data = build_thrust_dataset(log, ds_cfg, source=f"flight {spec.name}")
    pwm = np.stack([data.inputs[MOTOR_SIGNAL.format(k=k)] for k in range(1, N_MOTORS + 1)], axis=1)
    volt = data.inputs.get("battery_voltage_V")
    climb = data.inputs.get("climb_rate_m_s")
    hover = np.abs(climb) < HOVER_CLIMB_M_S if climb is not None else np.ones(data.n_samples, bool)
    if not hover.any():
        hover = np.ones(data.n_samples, bool)
    quality = log.quality.to_dict() if getattr(log, "quality", None) is not None else None
    return Flight(spec, data, pwm, volt, hover, _yaw_rate(log, data), tuple(getattr(log, "warnings", ()) or ()),
                  quality)


def _yaw_rate(log: Any, data: ThrustDataset) -> np.ndarray | None:
    """Mean body-z gyro [rad/s] over each PWM sample interval, or None when not logged."""
    try:
        g = log.signal("gyro_body_z_rad_s")
    except KeyError:
        return None
    t, v = (g if isinstance(g, tuple) else (g.t_s, g.values))
    t, v = np.asarray(t, float), np.asarray(v, float)
    edges = np.empty(2 * data.n_samples)
    edges[0::2] = data.time_s
    edges[1::2] = data.time_s + data.sample_period_s
    mean, _ = interval_means(t, v, edges)
    r = mean[0::2]
    return r if np.isfinite(r).mean() > 0.9 else None


def flight_summary(f: Flight) -> dict[str, Any]:
    """Samples kept, PWM band, voltage range, hover PWM of one flight (printed and in the metrics)."""
    s = f.pwm_us.sum(axis=1)
    out: dict[str, Any] = {
        "flight": f.spec.name,
        "path": str(f.spec.path),
        "mass_kg": f.spec.mass_kg,
        "samples": f.data.n_samples,
        "pwm_sum_band_us": [float(s.min()), float(s.max())],
        "hover_pwm_mean_us": float(f.pwm_us[f.hover].mean()),
        "hover_samples": int(f.hover.sum()),
        "mean_thrust_N": float(f.data.fz_N.mean()),
        "weight_N": f.weight_N,
        "lag_s": f.data.lag_s,
        "voltage_range_V": None if f.volt_V is None else [float(f.volt_V.min()), float(f.volt_V.max())],
        "notes": list(f.data.notes),
        "reader_warnings": list(f.reader_warnings),
        "quality": f.quality,
    }
    return out


# --------------------------------------------------------------------------- model
@dataclass(frozen=True)
class ModelSpec:
    """How the commands are compensated: nominal voltage and exponent (0 without voltage)."""

    idle_us: float
    nominal_V: float
    exponent: float


def _volt(f: Flight, spec: ModelSpec) -> np.ndarray:
    return f.volt_V if (f.volt_V is not None and spec.exponent > 0.0) else np.full(len(f.pwm_us), spec.nominal_V)


def fit_model(train: list[Flight], spec: ModelSpec, cfg: ThrustConfig, source: str,
              n_mfs: int | None = None) -> QuadrotorParams:
    """Train the per-motor ANFIS on ``train`` (checking blocks for early stopping) with ``n_mfs`` MFs
    (default ``cfg.n_mfs``); if the map is not monotone on its band, fewer MFs."""
    x = np.concatenate([effective_pwm(f.pwm_us, _volt(f, spec)[:, None], spec.idle_us, spec.nominal_V,
                                      spec.exponent) for f in train])
    y = np.concatenate([f.data.fz_N for f in train])
    period = float(np.median([f.data.sample_period_s for f in train]))
    chk = interleaved_blocks(len(y), max(1, round(cfg.check_block_s / period)), 5)
    amap = None
    for n in range(n_mfs or cfg.n_mfs, 0, -1):
        tc = AnfisTrainConfig(n_mfs=n, order=1, epochs=cfg.epochs)
        res = train_anfis_motors(x[~chk], y[~chk], tc, (x[chk], y[chk]), source=source)
        amap = res.amap
        if is_monotone(amap) and amap.input_range[0][0] > N_MOTORS * spec.idle_us:
            break
    assert amap is not None
    if not is_monotone(amap):
        raise ThrustDataError(f"{source}: even a one-rule map falls with PWM; the data do not show thrust rising")
    return QuadrotorParams.from_dict(
        {
            "mass_kg": float(np.mean([f.spec.mass_kg for f in train])),
            "pwm_idle_us": spec.idle_us,
            "battery_nominal_V": spec.nominal_V,
            "thrust_voltage_exponent": spec.exponent,
            "thrust_map": amap.to_dict(),
        },
        source=source,
    )


def fmu_total_thrust(p: QuadrotorParams, pwm_us: np.ndarray, volt_V: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Total thrust [N] the quadrotor FMU gives for per-motor PWM (N, 4) and voltage (N,): same function."""
    lo, hi = p.thrust_map.input_range[0]
    t = motor_thrust(p.thrust_map, np.asarray(pwm_us, float), np.asarray(volt_V, float)[:, None],
                     p.pwm_idle_us, lo, hi, p.battery_nominal_V, p.thrust_voltage_exponent,
                     scale * p.thrust_scale, N_MOTORS)
    return np.asarray(t).sum(axis=1)


def hover_scale(pred_N: np.ndarray, f: Flight) -> float:
    """Calibration: the scale making the mean predicted thrust over the flight's hover samples m g."""
    m = float(np.mean(pred_N[f.hover]))
    return f.weight_N / m if m > 0.0 else 1.0


# --------------------------------------------------------------------------- baselines
def _features(f: Flight, cfg: ThrustConfig, with_voltage: bool) -> np.ndarray:
    """Polynomial regressors per sample: sum u^2, sum u (and sum u^2 V) with u = (pwm - idle)/range."""
    u = (f.pwm_us - cfg.pwm_idle_us) / (cfg.pwm_max_us - cfg.pwm_idle_us)
    cols = [(u * u).sum(axis=1), u.sum(axis=1)]
    if with_voltage:
        cols.append((u * u).sum(axis=1) * f.volt_V)
    return np.stack(cols, axis=1)


def baseline_predictions(train: list[Flight], test: Flight, cfg: ThrustConfig, voltage: bool) -> dict[str, np.ndarray]:
    """Held-out predictions [N] of the constant m g and the least-squares polynomials fitted on ``train``."""
    out = {"constant m g": np.full(test.data.n_samples, test.weight_N)}
    variants = [("poly sum u^2, sum u", False)]
    if voltage:
        variants.append(("poly sum u^2, sum u, sum u^2 V", True))
    y = np.concatenate([f.data.fz_N for f in train])
    for name, with_v in variants:
        a = np.concatenate([_features(f, cfg, with_v) for f in train])
        coef = np.linalg.lstsq(a, y, rcond=None)[0]
        out[name] = _features(test, cfg, with_v) @ coef
    return out


# --------------------------------------------------------------------------- cross-validation
def folds(flights: list[Flight], n_blocks: int) -> list[tuple[str, list[Flight], Flight]]:
    """(name, training flights, held-out set): leave-one-flight-out, or time blocks of a single flight."""
    if len(flights) >= 2:
        return [(f.spec.name, [g for g in flights if g is not f], f) for f in flights]
    f = flights[0]
    block = np.minimum(np.arange(f.data.n_samples) * n_blocks // f.data.n_samples, n_blocks - 1)
    return [(f"{f.spec.name} block {b + 1}/{n_blocks}", [f.take(block != b)], f.take(block == b))
            for b in range(n_blocks)]


def score_fold(name: str, train: list[Flight], test: Flight, spec: ModelSpec, cfg: ThrustConfig,
               calibrate: bool) -> FoldResult:
    """Train on ``train`` (MF count chosen by inner CV on ``train`` only), score the FMU's thrust and the
    baselines on ``test`` (calibrated if asked)."""
    n_mfs = select_mfs(train, spec, cfg, calibrate)
    p = fit_model(train, spec, cfg, source=f"fold without {name}", n_mfs=n_mfs)
    pred = fmu_total_thrust(p, test.pwm_us, _volt(test, spec))
    scale = hover_scale(pred, test) if calibrate else 1.0
    y = test.data.fz_N
    base = baseline_predictions(train, test, cfg, spec.exponent > 0.0)
    scores = {}
    for bname, b in base.items():
        scores[bname] = Score(rmse(b, y), r_squared(b, y))
        if calibrate and bname != "constant m g":
            bc = b * hover_scale(b, test)
            scores[bname + " (calibrated)"] = Score(rmse(bc, y), r_squared(bc, y))
    model = Score(rmse(pred * scale, y), r_squared(pred * scale, y))
    return FoldResult(name, int(y.size), model, scores, scale, p.thrust_map.n_mfs[0])


def select_mfs(train: list[Flight], spec: ModelSpec, cfg: ThrustConfig, calibrate: bool) -> int:
    """MF count in 1..``cfg.n_mfs`` with the lowest pooled RMSE of an inner CV on ``train`` alone
    (leave-one-flight-out, or time blocks of a single flight); ties go to fewer MFs."""
    if cfg.n_mfs == 1:
        return 1
    inner = folds(train, cfg.n_folds_single)
    best = (math.inf, 1)
    for n in range(1, cfg.n_mfs + 1):
        sse, count = 0.0, 0
        for _, tr, te in inner:
            pred = fmu_total_thrust(fit_model(tr, spec, cfg, "inner CV", n_mfs=n), te.pwm_us, _volt(te, spec))
            if calibrate:
                pred = pred * hover_scale(pred, te)
            sse += float(np.sum((pred - te.data.fz_N) ** 2))
            count += te.data.n_samples
        score = math.sqrt(sse / count)
        if score < best[0] * (1.0 - 1e-3):
            best = (score, n)
    return best[1]


def _pooled(results: list[FoldResult], get: Any) -> float:
    n = sum(r.n_samples for r in results)
    return math.sqrt(sum(get(r) ** 2 * r.n_samples for r in results) / n)


# --------------------------------------------------------------------------- the workflow
def model_spec(flights: list[Flight], cfg: ThrustConfig) -> tuple[ModelSpec, list[str]]:
    """Voltage compensation when every flight logs the voltage (and it is wanted); notes why not."""
    notes = []
    have = [f.volt_V is not None for f in flights]
    use = cfg.use_voltage and all(have)
    if cfg.use_voltage and any(have) and not all(have):
        missing = ", ".join(f.spec.name for f in flights if f.volt_V is None)
        notes.append(f"battery voltage missing in {missing}: the model ignores voltage for every flight")
    if not use:
        return ModelSpec(cfg.pwm_idle_us, QuadrotorParams().battery_nominal_V, 0.0), notes
    v_nom = float(np.median(np.concatenate([f.volt_V for f in flights])))  # type: ignore[misc]
    return ModelSpec(cfg.pwm_idle_us, round(v_nom, 3), 1.0), notes


def identify_thrust(cfg: ThrustConfig) -> ThrustResult:
    """Read, align, cross-validate against baselines, fit on all flights, write params and metrics."""
    check_config(cfg)
    flights = [load_flight(s, cfg) for s in cfg.flights]
    spec, notes = model_spec(flights, cfg)
    calibrate = cfg.calibrate == "on" or (cfg.calibrate == "auto" and spec.exponent == 0.0)
    results = [score_fold(n, tr, te, spec, cfg, calibrate) for n, tr, te in folds(flights, cfg.n_folds_single)]
    names = list(results[0].baselines)
    pooled_b = {b: _pooled(results, lambda r, b=b: r.baselines[b].rmse_N) for b in names}
    pooled_m = _pooled(results, lambda r: r.model.rmse_N)
    wins = pooled_m < min(pooled_b.values())
    final = fit_model(flights, spec, cfg, source=f"identify thrust ({len(flights)} flights)",
                      n_mfs=select_mfs(flights, spec, cfg, calibrate))
    final = dataclasses.replace(final, mass_kg=flights[0].spec.mass_kg)
    cal = {}
    if calibrate:
        cal = {f.spec.name: hover_scale(fmu_total_thrust(final, f.pwm_us, _volt(f, spec)), f) for f in flights}
    yaw, yaw_note = _yaw(flights, final, spec, cal)
    if yaw is not None:
        final = dataclasses.replace(final, b_drag_N_m_s2=yaw.b_drag_N_m_s2)
    summaries = tuple(flight_summary(f) for f in flights)
    warnings = list(notes) + ([yaw_note] if yaw_note else [])
    if not wins:
        best = min(pooled_b, key=pooled_b.get)  # type: ignore[arg-type]
        warnings.append(
            f"the identified model LOSES on held-out data: RMSE {pooled_m:.3f} N vs {pooled_b[best]:.3f} N of "
            f"the baseline '{best}'"
        )
    result = ThrustResult(final, tuple(results), pooled_m, pooled_b, wins, summaries, cal,
                          warnings=tuple(warnings))
    result.metrics.update(_metrics(result, cfg, spec, calibrate))
    result.metrics["yaw"] = yaw.as_dict() if yaw is not None else {"skipped": yaw_note}
    _write(result, cfg)
    return result


def _yaw(flights: list[Flight], p: QuadrotorParams, spec: ModelSpec, cal: dict[str, float]) -> tuple[Any, str]:
    """Yaw torque per thrust from the flights' yaw response (None and a note when it cannot be done)."""
    from identification.yaw_torque import identify_yaw_torque, spin_thrust, windows

    if any(f.yaw_rate is None for f in flights):
        return None, "yaw torque not identified: a flight has no gyro_body_z_rad_s"
    ms = []
    for f in flights:
        per_motor = np.stack([fmu_total_thrust(p, f.pwm_us[:, [i] * N_MOTORS], _volt(f, spec)) / N_MOTORS
                              for i in range(N_MOTORS)], axis=1) * cal.get(f.spec.name, 1.0)
        ok = np.isfinite(f.yaw_rate)  # type: ignore[arg-type]
        seg = np.where(ok, f.data.segment, -1)
        ms += windows(f.data.time_s, seg, spin_thrust(per_motor), np.nan_to_num(f.yaw_rate),  # type: ignore[arg-type]
                      f.data.sample_period_s)
    ms = [m for m in ms if np.all(np.isfinite(m.y))]
    try:
        return identify_yaw_torque(ms, p), ""
    except ValueError as err:
        return None, f"yaw torque not identified: {err}"


def _metrics(r: ThrustResult, cfg: ThrustConfig, spec: ModelSpec, calibrate: bool) -> dict[str, Any]:
    return {
        "flights": list(r.flights),
        "cross_validation": "leave-one-flight-out" if len(cfg.flights) >= 2 else f"{cfg.n_folds_single} time blocks",
        "voltage_compensation": spec.exponent > 0.0,
        "battery_nominal_V": spec.nominal_V,
        "per_flight_calibration": calibrate,
        "calibration_scale": r.calibration,
        "folds": [
            {"held_out": f.held_out, "samples": f.n_samples, "calibration_scale": f.calibration_scale,
             "n_mfs": f.n_mfs,
             "model": dataclasses.asdict(f.model),
             "baselines": {k: dataclasses.asdict(v) for k, v in f.baselines.items()},
             "best_baseline": f.best_baseline,
             "model_beats_best_baseline": f.model.rmse_N < f.baselines[f.best_baseline].rmse_N}
            for f in r.folds
        ],
        "pooled_model_rmse_N": r.pooled_model_rmse_N,
        "pooled_baseline_rmse_N": r.pooled_baseline_rmse_N,
        "model_beats_baselines": r.model_beats_baselines,
        "verdict": "model beats every baseline on held-out data" if r.model_beats_baselines
        else "MODEL LOSES to a baseline on held-out data",
        "forced": bool(cfg.force and not r.model_beats_baselines),
        "warnings": list(r.warnings),
        "thrust_map_mfs": r.params.thrust_map.n_mfs[0],
        "band_us": list(r.params.thrust_map.input_range[0]),
        "scored_with": "fmu_models.quadrotor.thrust.motor_thrust (the FMU's function)",
    }


def _write(r: ThrustResult, cfg: ThrustConfig) -> None:
    metrics_path = cfg.metrics or (cfg.out.with_suffix(".metrics.json") if cfg.out else None)
    if cfg.out is not None:
        section = r.params.to_dict()
        section["k_thrust_source"] = "default (not identified from thrust data)"
        QuadrotorParams.from_dict(section, source=f"{cfg.out} (about to be written)")
        cfg.out.parent.mkdir(parents=True, exist_ok=True)
        write_json(cfg.out, {"quadrotor": section, "_identification": {
            "metrics": str(metrics_path), "flight_calibration_thrust_scale": r.calibration}})
    if metrics_path is not None:
        metrics_path.parent.mkdir(parents=True, exist_ok=True)
        write_json(metrics_path, r.metrics)

"""Thrust identification from many flights of one vehicle, scored as the FMU evaluates it.

``identify_thrust(config) -> ThrustResult``. Each flight (log + mass) gives airborne samples of per-motor
PWM, battery voltage (when logged) and measured thrust ``-m a_z``. The model (:mod:`identification.thrust.model`)
is a per-motor ANFIS with first-order Sugeno consequents over physical features of the command, so that one
rule is exactly the least-squares polynomial; with no voltage log a battery state estimated from the flight's
own hover condition (:mod:`identification.thrust.battery`) reaches the FMU as an equivalent battery voltage.
Every figure is computed with the FMU's function (:func:`fmu_models.quadrotor.thrust.motor_thrust`).

Held-out scoring: leave-one-flight-out with two or more flights, time-blocked folds with one; the map's
feature set, rule count and battery-state time constant are chosen by an inner cross-validation on the
training flights of each fold (nested CV). Beside the model, on the same held-out samples: the constant
``m g`` and least-squares polynomials in ``u`` per motor, raw and with a per-flight hover calibration (one
scale per flight making the mean over its hover samples ``m g``; mass and PWM only). The verdict compares
the model with every baseline by :func:`identification.common.metrics.skill_interval` (block bootstrap; the rule of
:class:`identification.common.metrics.SkillInterval`): ``lose`` when the baseline's RMSE is lower by more than 0.1 %
pooled or on any held-out set, whatever the interval; ``win`` when every pooled interval lies above zero; else
``tie``.

Longer than 700 lines because the folds, the baselines at each level of side information and the verdict share
one data layout; the map itself, the battery state and the data set live in their own modules.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.atmosphere import G0_M_S2 as G0
from fmu_models.config import bounded, range_problems
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import consequent_parameters
from identification.common.jsonio import write_json
from identification.common.metrics import SkillInterval, block_starts, overall_outcome, skill_interval
from identification.thrust.anfis_train import r_squared, rmse
from identification.thrust.battery import HOVER_CLIMB_M_S, hover_thrust_scale
from identification.thrust.dataset import (
    MOTOR_MIN_PWM_US,
    MOTOR_SIGNAL,
    ThrustDataError,
    ThrustDataset,
    ThrustDatasetConfig,
    build_thrust_dataset,
    damage_gate,
    interval_means,
)
from identification.thrust.model import (
    FlightData,
    ModelSpec,
    baseline_predictions,
    battery_input_V,
    covariance,
    fit_physical,
    fmu_total_thrust,
    hover_scale,
    inner_folds,
    predict,
    select_spec,
)

CALIBRATIONS = ("auto", "on", "off")
CONSTANT = "constant m g"
OUTCOMES = ("win", "tie", "lose")
#: side-information levels of the comparisons: every predictor at a level has the same information
RAW, STATE, CALIBRATED = "raw", "battery state", "calibrated"
INFORMATION = {
    RAW: "no information from the held-out flight beyond PWM, mass and a logged voltage where a predictor "
         "takes it",
    STATE: "each predictor times its own hover battery state on the held-out flight (causal, the model's "
           "time constant; from mass, PWM, climb rate and attitude)",
    CALIBRATED: "each predictor times its own per-flight hover calibration (one scale per held-out flight: "
                "mean vertical thrust over its hover samples = m g)",
}


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

    ``calibrate``: also score with a per-flight hover calibration (``auto``: when no voltage is logged).
    ``use_voltage``: use the logged battery voltage when every flight has it. ``battery_state``: without a
    voltage log, carry the hover-condition battery state (its time constant chosen by inner CV). ``n_mfs``:
    most rules tried (the count is chosen by inner CV). ``fmu_mass_kg``: the FMU's ``mass_kg`` (required
    when the flights' masses differ). ``accept_damaged_log``: use logs whose damaged share exceeds the limit.
    ``write_losing_model``: write the parameter file even when a baseline beats the model (the verdict and
    exit status still say it loses). ``out``/``metrics``: files to write (None: write nothing).
    """

    flights: tuple[FlightSpec, ...]
    out: Path | None = None
    metrics: Path | None = None
    pwm_idle_us: float = bounded(1000.0, 800.0, 1500.0, "us")
    pwm_max_us: float = bounded(2000.0, 1000.0, 2500.0, "us")
    use_voltage: bool = True
    battery_state: bool = True
    calibrate: str = "auto"
    n_mfs: int = bounded(3, 1, 6)
    epochs: int = bounded(30, 1, 2000)
    n_folds_single: int = bounded(3, 2, 20)
    motor_min_pwm_us: float = bounded(MOTOR_MIN_PWM_US, 800.0, 2200.0, "us")
    max_lag_s: float = bounded(0.3, 0.0, 5.0, "s")
    lowpass_hz: float | None = bounded(None, 1e-3, 1000.0, "Hz (None: no filter)", optional=True)
    check_block_s: float = bounded(5.0, 0.1, 600.0, "s")
    channel_map: Path | None = None
    fmu_mass_kg: float | None = bounded(None, 0.05, 50.0, "kg (None: the flights' common mass)", optional=True)
    accept_damaged_log: bool = False
    write_losing_model: bool = False
    #: known vertical drag coefficient [N s/m] (``kd_z_N_s_m`` of ``identify quadrotor``): the measured thrust is
    #: then ``-m a_z - kd_z w``, without the drag that follows the climb rate (None: ``-m a_z``)
    vertical_drag_N_s_m: float | None = bounded(None, 0.0, 100.0, "N s/m (None: no drag correction)", optional=True)
    #: where the cross-validation folds run (``identification.common.parallel``): None in this process unless a
    #: scheduler is
    #: given (``scheduler`` or ``UAVFMU_SCHEDULER``), 0 in this process, N local worker processes
    workers: int | None = bounded(None, 0, 64, "worker processes (0: in this process)", optional=True)
    scheduler: str | None = None


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
    overrides: tuple[str, ...] = ()  #: what an option overrode for this flight (printed and in the metrics)
    tilt_cos: np.ndarray | None = None  #: cos(roll) cos(pitch) per sample (None: attitude not logged)

    @property
    def weight_N(self) -> float:
        return self.spec.mass_kg * G0

    def model_data(self, use_voltage: bool) -> FlightData:
        """The arrays the thrust model needs."""
        return FlightData(self.spec.name, self.pwm_us, self.volt_V if use_voltage else None, self.hover,
                          self.data.time_s, self.data.fz_N, self.weight_N, self.data.sample_period_s, self.tilt_cos)


@dataclass(frozen=True)
class Score:
    """RMSE [N] and R^2 of one predictor on one held-out set."""

    rmse_N: float
    r2: float


@dataclass(frozen=True)
class FoldResult:
    """Scores on one held-out flight (or time block): the model (with and without its battery state, raw and
    calibrated) and every baseline by name; ``series`` holds the held-out predictions for the intervals."""

    held_out: str
    n_samples: int
    model: Score
    baselines: dict[str, Score]
    calibration_scale: float
    spec: ModelSpec
    period_s: float = 0.1
    series: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def best_baseline(self) -> str:
        return min(self.baselines, key=lambda k: self.baselines[k].rmse_N)


@dataclass(frozen=True)
class ThrustResult:
    """Outcome of :func:`identify_thrust`: parameters, held-out table, verdict, per-flight summaries."""

    params: QuadrotorParams
    spec: ModelSpec
    folds: tuple[FoldResult, ...]
    pooled: dict[str, float]
    comparisons: dict[str, dict[str, Any]]
    verdict: str
    flights: tuple[dict[str, Any], ...]
    calibration: dict[str, float]
    uncertainty: dict[str, Any]
    metrics: dict[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    overrides: tuple[str, ...] = ()
    written: Path | None = None

    @property
    def model_beats_baselines(self) -> bool:
        return self.verdict == "win"

    @property
    def pooled_model_rmse_N(self) -> float:
        return self.pooled["model"]

    def params_for(self, flight: str) -> QuadrotorParams:
        """The parameters to replay ``flight`` with when the replay cannot drive the battery state: its
        calibration scale as ``thrust_scale`` (else 1). A replay that drives ``battery_voltage_V`` with
        :func:`identification.thrust.model.battery_input_V` needs no scale."""
        return dataclasses.replace(self.params, thrust_scale=self.calibration.get(flight, 1.0))

    @property
    def exit_code(self) -> int:
        """0 when no baseline beats the model on held-out data (``win`` or ``tie``), 3 when one does."""
        return 3 if self.verdict == "lose" else 0


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
    masses = sorted({f.mass_kg for f in cfg.flights})
    if not probs and len(masses) > 1 and cfg.fmu_mass_kg is None:
        listing = ", ".join(f"{f.name} {f.mass_kg} kg" for f in cfg.flights)
        probs.append(f"the flights have different masses ({listing}): name the FMU's mass_kg with --fmu-mass-kg "
                     "(ThrustConfig.fmu_mass_kg)")
    if probs:
        raise ThrustDataError("identify thrust: " + "; ".join(probs))


def fmu_mass(cfg: ThrustConfig) -> float:
    """The FMU's mass [kg]: the one the user named, else the flights' common mass."""
    return float(cfg.fmu_mass_kg if cfg.fmu_mass_kg is not None else cfg.flights[0].mass_kg)


def load_flight(spec: FlightSpec, cfg: ThrustConfig) -> Flight:
    """Read one log and cut its airborne samples (errors name the flight and the field)."""
    from identification.logs.readers import read_log

    log = read_log(spec.path, channel_map=cfg.channel_map)
    overrides = damage_gate(log, cfg.accept_damaged_log)
    ds_cfg = ThrustDatasetConfig(
        mass_kg=spec.mass_kg,
        motor_min_pwm_us=cfg.motor_min_pwm_us,
        max_lag_s=cfg.max_lag_s,
        lowpass_hz=cfg.lowpass_hz,
        pwm_idle_us=min(max(cfg.pwm_idle_us, 800.0), 1500.0),
        airborne_on_mean_pwm=True,
        vertical_drag_N_s_m=cfg.vertical_drag_N_s_m,
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
                  quality, overrides, _tilt_cos(log, data))


def _tilt_cos(log: Any, data: ThrustDataset) -> np.ndarray | None:
    """``cos(roll) cos(pitch)`` at the middle of each PWM sample interval, or None when not logged."""
    from identification.thrust.dataset import _series

    angles = [_series(log, name) for name in ("roll_rad", "pitch_rad")]
    if any(a is None or a[0].size < 2 for a in angles):
        return None
    mid = data.time_s + data.sample_period_s / 2.0
    roll, pitch = (np.interp(mid, *a) for a in angles)  # type: ignore[misc]
    return np.cos(roll) * np.cos(pitch)


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
    return {
        "flight": f.spec.name,
        "path": str(f.spec.path),
        "mass_kg": f.spec.mass_kg,
        "samples": f.data.n_samples,
        "pwm_sum_band_us": [float(s.min()), float(s.max())],
        "hover_pwm_mean_us": float(f.pwm_us[f.hover].mean()),
        "hover_samples": int(f.hover.sum()),
        "mean_thrust_N": float(f.data.fz_N.mean()),
        "attitude_logged": f.tilt_cos is not None,
        "weight_N": f.weight_N,
        "lag_s": f.data.lag_s,
        "voltage_range_V": None if f.volt_V is None else [float(f.volt_V.min()), float(f.volt_V.max())],
        "notes": list(f.data.notes),
        "reader_warnings": list(f.reader_warnings),
        "quality": f.quality,
        "overrides": list(f.overrides),
    }


# --------------------------------------------------------------------------- folds and scores
def base_spec(flights: list[Flight], cfg: ThrustConfig) -> tuple[ModelSpec, list[str]]:
    """Voltage use (every flight logs it and it is wanted), nominal voltage; notes why not."""
    notes = []
    have = [f.volt_V is not None for f in flights]
    use = cfg.use_voltage and all(have)
    if cfg.use_voltage and any(have) and not all(have):
        missing = ", ".join(f.spec.name for f in flights if f.volt_V is None)
        notes.append(f"battery voltage missing in {missing}: the model ignores voltage for every flight")
    v_nom = QuadrotorParams().battery_nominal_V
    if use:
        v_nom = round(float(np.median(np.concatenate([f.volt_V for f in flights]))), 3)  # type: ignore[misc]
    return ModelSpec(cfg.pwm_idle_us, cfg.pwm_max_us, v_nom, use), notes


def _select(train: list[FlightData], base: ModelSpec, cfg: ThrustConfig, calibrate: bool) -> ModelSpec:
    spec, _ = select_spec(train, base, cfg.n_mfs, cfg.epochs, cfg.check_block_s, cfg.n_folds_single, calibrate,
                          states=cfg.battery_state)
    return spec


def score_fold(name: str, train: list[FlightData], test: FlightData, base: ModelSpec, cfg: ThrustConfig,
               calibrate: bool) -> FoldResult:
    """Select the structure on ``train`` (inner CV), fit on ``train``, score it and the baselines on ``test``.

    Every predictor (the map, the constant m g, the polynomials) is also given each piece of side information
    the model may take from the held-out flight, by the same function: its own hover battery state
    (:func:`with_battery_state`, when the model has one) and a per-flight hover calibration
    (:func:`identification.thrust.model.hover_scale`, when ``calibrate``); see :data:`INFORMATION`."""
    fitted, spec = fit_physical(train, _select(train, base, cfg, calibrate), cfg.epochs, cfg.check_block_s,
                                source=f"fold without {name}")
    p = fitted.params
    y = test.thrust_N
    raw_model = predict(p, spec, test, state=False)
    pred = predict(p, spec, test)
    series = {"measured": y, "model": pred}
    raw = {_model_key(spec, RAW): raw_model, **baseline_predictions(train, test, spec)}
    series.update(raw)
    if spec.tau_s is not None:
        for key, v in raw.items():
            if key != _model_key(spec, RAW):
                series[f"{key} ({STATE})"] = with_battery_state(v, test, spec.tau_s)
    if calibrate:
        for key, v in raw.items():
            series[f"{key} ({CALIBRATED})"] = v * hover_scale(v, test)
    scale = hover_scale(pred, test)
    scores = {k: Score(rmse(v, y), r_squared(v, y)) for k, v in series.items() if k not in ("measured", "model")}
    return FoldResult(name, int(y.size), Score(rmse(pred, y), r_squared(pred, y)), scores, scale, spec,
                      test.period_s, series)


def with_battery_state(pred_N: np.ndarray, f: FlightData, tau_s: float) -> np.ndarray:
    """``pred_N`` times its own hover battery state on flight ``f`` (time constant ``tau_s``): what the model's
    state does to the map (:func:`identification.thrust.model.battery_input_V`), applied to any predictor."""
    return pred_N * hover_thrust_scale(f.time_s, f.vertical(pred_N), f.hover, f.weight_N, tau_s)


def outer_folds(flights: list[FlightData], n_blocks: int) -> list[tuple[str, list[FlightData], FlightData]]:
    """Leave-one-flight-out, or time blocks of a single flight."""
    return inner_folds(flights, n_blocks)


def fold_results(data: list[FlightData], base: ModelSpec, cfg: ThrustConfig, calibrate: bool) -> list[FoldResult]:
    """:func:`score_fold` of every outer fold as tasks of ``identification.common.parallel`` (in this process by
    default: a
    few folds do not repay a cluster start-up); in fold order whatever the order they finish in. The fit has no
    randomness (``identification.thrust.anfis_train``), so no task seed is needed and every worker gives the same
    bits."""
    from identification.common.parallel import SCHEDULER_ENV, map_tasks

    opts = {k: getattr(cfg, k) for k in _FOLD_OPTIONS}
    tasks = [{"held_out": n, "train": [dataclasses.asdict(d) for d in tr], "test": dataclasses.asdict(te),
              "base": dataclasses.asdict(base), "options": opts, "calibrate": calibrate}
             for n, tr, te in outer_folds(data, cfg.n_folds_single)]
    workers = cfg.workers
    if workers is None:
        workers = None if cfg.scheduler or os.environ.get(SCHEDULER_ENV) else 0
    run = map_tasks(fold_task, tasks, scheduler=cfg.scheduler, workers=workers, progress=False, desc="thrust folds")
    if run.failures:
        raise ThrustDataError("cross-validation: " + "; ".join(f"fold without {tasks[i]['held_out']}: {err}"
                                                               for i, err in sorted(run.failures.items())))
    return [_fold_of(got) for _, got in run.results() if got is not None]


#: the options of :class:`ThrustConfig` that a fold reads
_FOLD_OPTIONS = ("n_mfs", "epochs", "check_block_s", "n_folds_single", "battery_state")


def fold_task(task: dict[str, Any]) -> dict[str, Any]:
    """One outer fold on a worker (``identification.common.parallel``): plain data in, plain data out."""
    cfg = ThrustConfig(flights=(), **task["options"])
    base = task["base"]
    spec = ModelSpec(**{**base, "features": tuple(base["features"])})
    f = score_fold(task["held_out"], [FlightData(**d) for d in task["train"]], FlightData(**task["test"]), spec,
                   cfg, task["calibrate"])
    out: dict[str, Any] = {"held_out": f.held_out, "n_samples": f.n_samples, "model": dataclasses.asdict(f.model),
                           "baselines": {k: dataclasses.asdict(v) for k, v in f.baselines.items()},
                           "calibration_scale": f.calibration_scale, "spec": dataclasses.asdict(f.spec),
                           "period_s": f.period_s, "series_names": list(f.series)}
    out.update({f"series_{i}": np.asarray(v) for i, v in enumerate(f.series.values())})
    return out


def _fold_of(got: dict[str, Any]) -> FoldResult:
    spec = got["spec"]
    return FoldResult(got["held_out"], got["n_samples"], Score(**got["model"]),
                      {k: Score(**v) for k, v in got["baselines"].items()}, got["calibration_scale"],
                      ModelSpec(**{**spec, "features": tuple(spec["features"])}), got["period_s"],
                      {k: got[f"series_{i}"] for i, k in enumerate(got["series_names"])})


def _model_key(spec: ModelSpec, level: str) -> str:
    """The series name of the model with the side information ``level`` (``model`` is the written one)."""
    if level == STATE or (level == RAW and spec.tau_s is None):
        return "model"
    bare = "model" if spec.tau_s is None else "model without battery state"
    return bare if level == RAW else f"{bare} ({level})"


def _is_baseline(key: str) -> bool:
    """A raw baseline's series name (the constant or a polynomial, no side information)."""
    return key == CONSTANT or (key.startswith("poly") and not key.endswith(")"))


def _baseline_key(base: str, level: str) -> str:
    return base if level == RAW else f"{base} ({level})"


def levels_of(spec: ModelSpec, calibrate: bool) -> list[str]:
    """The side-information levels scored: none, the hover battery state (a model with one), the calibration."""
    return [RAW, *([STATE] if spec.tau_s is not None else []), *([CALIBRATED] if calibrate else [])]


def used_levels(spec: ModelSpec, calibrate: bool) -> list[str]:
    """The levels the written model is used at, which decide the verdict: the information the FMU is given
    in a replay (its battery state, or none) and, when scored, the per-flight calibration of
    :meth:`ThrustResult.params_for`."""
    return [STATE if spec.tau_s is not None else RAW, *([CALIBRATED] if calibrate else [])]


def comparisons(folds: list[FoldResult], calibrate: bool, block_s: float) -> dict[str, dict[str, Any]]:
    """Model vs each baseline with the same side information (:data:`INFORMATION`), pooled over the held-out
    sets and per held-out set, as skill intervals.

    At each level every predictor has the same information from the held-out flight: none (``raw``), its own
    hover battery state (``battery state``: the model's time constant, applied to the constant and the
    polynomials as to the map), or its own per-flight hover calibration (``calibrated``). ``in_verdict``: the
    level is one the written model is used at (:func:`used_levels`)."""
    # each fold selects its own structure, so one may carry a battery state and another not: the series of a
    # fold are looked up by that fold's own structure (:func:`_fold_key`), its model and baselines alike
    ref = next((f.spec for f in folds if f.spec.tau_s is not None), folds[0].spec)
    raw_bases = [b for b in folds[0].series if _is_baseline(b)]
    used = used_levels(ref, calibrate)
    out = {}
    for level in levels_of(ref, calibrate):
        model = _model_key(ref, level)
        for b in raw_bases:
            base = _baseline_key(b, level)
            if any(_fold_key(f, level, b) not in f.series for f in folds):
                continue
            pooled = _interval(folds, level, b, block_s)
            per = {f.held_out: _interval([f], level, b, block_s).as_dict() for f in folds}
            out[f"{model} vs {base}"] = {"model": model, "baseline": base, "information": level,
                                         "information_text": INFORMATION[level], "in_verdict": level in used,
                                         "pooled": pooled.as_dict(), "per_held_out": per,
                                         "rmse_ratio": _ratio(folds, level, b)}
    return out


def headline(comp: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The like-for-like headline: at the information the written model is used with in a replay (the first
    level of :func:`used_levels`), the model against the best baseline given the same information."""
    level = next(c["information"] for c in comp.values() if c["in_verdict"])
    same = [c for c in comp.values() if c["information"] == level]
    best = max(same, key=lambda c: c["rmse_ratio"])  # the baseline with the lowest RMSE
    return {"information": level, "information_text": INFORMATION[level], "model": best["model"],
            "baseline": best["baseline"], "rmse_ratio": best["rmse_ratio"], "outcome": best["pooled"]["outcome"]}


def _fold_key(f: FoldResult, level: str, base: str | None = None) -> str:
    """Fold ``f``'s series of the model (``base`` None) or of raw baseline ``base`` at side information ``level``,
    by the fold's own structure: where it has no battery state, neither the model nor the baseline gets one."""
    if base is None:
        return _model_key(f.spec, level)
    return base if level == STATE and f.spec.tau_s is None else _baseline_key(base, level)


def _interval(folds: list[FoldResult], level: str, base: str, block_s: float) -> SkillInterval:
    ys, ms, bs, starts, offset = [], [], [], [], 0
    for f in folds:
        n = f.n_samples
        block = max(1, round(block_s / f.period_s))
        starts.append(block_starts(n, block) + offset)
        ys.append(f.series["measured"])
        ms.append(f.series[_fold_key(f, level)])
        bs.append(f.series[_fold_key(f, level, base)])
        offset += n
    return skill_interval(np.concatenate(ys), np.concatenate(ms), np.concatenate(bs), np.concatenate(starts))


def _ratio(folds: list[FoldResult], level: str, base: str) -> float:
    return _pooled_rmse(folds, level) / _pooled_rmse(folds, level, base)


def _pooled_rmse(folds: list[FoldResult], level: str, base: str | None = None) -> float:
    sse = sum(float(np.sum((f.series[_fold_key(f, level, base)] - f.series["measured"]) ** 2)) for f in folds)
    return math.sqrt(sse / sum(f.n_samples for f in folds))


def verdict_of(comp: dict[str, dict[str, Any]]) -> str:
    """Over the comparisons ``in_verdict``: ``lose`` if a baseline beats the model pooled or on any held-out set;
    ``win`` if the model beats every baseline pooled (intervals above zero); else ``tie``."""
    judged = [c for c in comp.values() if c.get("in_verdict", True)]
    pooled = [c["pooled"]["outcome"] for c in judged]
    per = [o["outcome"] for c in judged for o in c["per_held_out"].values()]
    return "lose" if "lose" in per else overall_outcome(pooled)


# --------------------------------------------------------------------------- the workflow
def identify_thrust(cfg: ThrustConfig) -> ThrustResult:
    """Read, nested-cross-validate against baselines, fit on all flights, write params and metrics."""
    check_config(cfg)
    flights = [load_flight(s, cfg) for s in cfg.flights]
    base, notes = base_spec(flights, cfg)
    calibrate = cfg.calibrate == "on" or (cfg.calibrate == "auto" and not base.voltage)
    data = [f.model_data(base.voltage) for f in flights]
    results = fold_results(data, base, cfg, calibrate)
    comp = comparisons(results, calibrate, cfg.check_block_s)
    verdict = verdict_of(comp)
    chosen = _select(data, base, cfg, calibrate)
    fitted, spec = fit_physical(data, chosen, cfg.epochs, cfg.check_block_s,
                                source=f"identify thrust ({len(flights)} flights)", mass_kg=fmu_mass(cfg))
    final = fitted.params
    if spec != chosen:
        notes.append(f"the selected map ({chosen.describe()}) falls with the command on its band; written: "
                     f"{spec.describe()}")
    # thrust_scale for replays that cannot drive the battery state: the model without it, calibrated per flight
    cal = {d.name: hover_scale(predict(final, spec, d, state=False), d) for d in data} if calibrate else {}
    yaw, yaw_note, yaw_held = _yaw(flights, data, final, spec, cal)
    if yaw is not None:
        final = dataclasses.replace(final, b_drag_N_m_s2=yaw.b_drag_N_m_s2)
    pooled = {k: math.sqrt(sum(float(np.sum((f.series[k] - f.series["measured"]) ** 2)) for f in results)
                           / sum(f.n_samples for f in results))
              for k in results[0].series if k != "measured" and all(k in f.series for f in results)}
    warnings = list(notes) + ([yaw_note] if yaw_note else [])
    if verdict == "lose":
        warnings.append("the identified model LOSES to a baseline on held-out data: " + _losers(comp, True))
    unused = _losers(comp, False)
    if unused:
        warnings.append("without the side information it is used with, the model LOSES to a baseline given the "
                        f"same (not in the verdict): {unused}")
    overrides = [o for f in flights for o in f.overrides]
    result = ThrustResult(final, spec, tuple(results), pooled, comp, verdict,
                          tuple(flight_summary(f) for f in flights), cal, _uncertainty(fitted),
                          warnings=tuple(warnings), overrides=tuple(overrides))
    result.metrics.update(_metrics(result, cfg, calibrate))
    result.metrics["yaw"] = ({**yaw.as_dict(), "held_out_vs_holding_the_rate": yaw_held} if yaw is not None
                             else {"skipped": yaw_note})
    return _write(result, cfg)


def _losers(comp: dict[str, dict[str, Any]], in_verdict: bool) -> str:
    items = []
    for key, c in comp.items():
        if c["in_verdict"] != in_verdict:
            continue
        where = [h for h, o in c["per_held_out"].items() if o["outcome"] == "lose"]
        if c["pooled"]["outcome"] == "lose" or where:
            items.append(f"{key} (RMSE ratio {c['rmse_ratio']:.3f}{'; loses on ' + ', '.join(where) if where else ''})")
    return "; ".join(items)


def _uncertainty(fitted: Any) -> dict[str, Any]:
    """The ``uncertainty`` key of the parameter file: FMU names of the consequents, mean and covariance."""
    names = [n for n, _, _ in consequent_parameters(fitted.params.thrust_map)]
    mean = [float(v) for row in fitted.params.thrust_map.consequents for v in row]
    cov = covariance(fitted)
    return {"names": names, "mean": mean, "covariance": [[float(v) for v in row] for row in cov],
            "note": "consequent coefficients of the thrust map at the fitted membership functions; least-squares "
                    "sandwich covariance with an autoregressive model of the residuals' autocorrelation"}


def _yaw(flights: list[Flight], data: list[FlightData], p: QuadrotorParams, spec: ModelSpec,
         cal: dict[str, float]) -> tuple[Any, str, dict[str, dict[str, Any]]]:
    """Yaw torque per thrust from the flights' yaw response (None and a note when it cannot be done), and with
    two or more flights its leave-one-flight-out skill against holding the logged yaw rate per held-out flight
    (the note says when the fit loses on one)."""
    from identification.thrust.yaw_torque import identify_yaw_torque

    if any(f.yaw_rate is None for f in flights):
        return None, "yaw torque not identified: a flight has no gyro_body_z_rad_s", {}
    per_flight = [yaw_windows(f, d, p, spec, 1.0 if spec.tau_s is not None else cal.get(f.spec.name, 1.0))
                  for f, d in zip(flights, data, strict=True)]
    try:
        fitted = identify_yaw_torque([m for ms in per_flight for m in ms], p)
    except ValueError as err:
        return None, f"yaw torque not identified: {err}", {}
    held = _yaw_held_out(flights, per_flight, p) if len(flights) >= 2 else {}
    losses = [f"{name} (skill {h['skill']:+.2f} [{h['lo']:+.2f}, {h['hi']:+.2f}])" for name, h in held.items()
              if h["outcome"] == "lose"]
    note = (f"yaw torque LOSES to holding the logged yaw rate on held-out flight(s) {', '.join(losses)}: "
            "b_drag_N_m_s2 is written from all flights, but the yaw axis is not validated" if losses else "")
    return fitted, note, held


def yaw_windows(f: Flight, d: FlightData, p: QuadrotorParams, spec: ModelSpec, scale: float = 1.0) -> list[Any]:
    """The yaw-replay windows of one flight (``identification.thrust.yaw_torque.windows``): the FMU's per-motor thrust
    with the model's battery input (the hover state when it has one), times ``scale``, as ``sum_i s_i T_i``;
    samples without a logged yaw rate cut the windows."""
    from identification.thrust.yaw_torque import spin_thrust, windows

    volt = battery_input_V(p, spec, d)
    per_motor = np.stack([fmu_total_thrust(p, f.pwm_us[:, [i] * N_MOTORS], volt) / N_MOTORS
                          for i in range(N_MOTORS)], axis=1) * scale
    ok = np.isfinite(f.yaw_rate)  # type: ignore[arg-type]
    seg = np.where(ok, f.data.segment, -1)
    ms = windows(f.data.time_s, seg, spin_thrust(per_motor), np.nan_to_num(f.yaw_rate),  # type: ignore[arg-type]
                 f.data.sample_period_s)
    return [m for m in ms if np.all(np.isfinite(m.y))]


def _yaw_held_out(flights: list[Flight], per_flight: list[list[Any]], p: QuadrotorParams
                  ) -> dict[str, dict[str, Any]]:
    """Per flight: the yaw torque fitted on the other flights, replayed on its windows, against holding the
    logged yaw rate (skill interval over windows)."""
    from identification.thrust.yaw_torque import identify_yaw_torque, replay

    out: dict[str, dict[str, Any]] = {}
    for i, f in enumerate(flights):
        train = [m for j, ms in enumerate(per_flight) if j != i for m in ms]
        if not train or len(per_flight[i]) < 2:
            continue
        c = identify_yaw_torque(train, p).b_drag_N_m_s2 / p.k_thrust_N_s2
        model, logged, starts = replay(per_flight[i], c, p.Jz_kg_m2)
        hold = replay(per_flight[i], 0.0, p.Jz_kg_m2)[0]
        si = skill_interval(logged, model, hold, starts)
        out[f.spec.name] = {"skill": si.skill, "lo": si.lo, "hi": si.hi, "outcome": si.outcome,
                            "windows": len(per_flight[i])}
    return out


VERDICT_TEXT = {"win": "model beats every baseline on held-out data",
                "tie": "TIE: no baseline beats the model, but it does not beat every one beyond noise",
                "lose": "MODEL LOSES to a baseline on held-out data"}


def _metrics(r: ThrustResult, cfg: ThrustConfig, calibrate: bool) -> dict[str, Any]:
    return {
        "flights": list(r.flights),
        "fmu_mass_kg": r.params.mass_kg,
        "cross_validation": "leave-one-flight-out" if len(cfg.flights) >= 2 else f"{cfg.n_folds_single} time blocks",
        "model_selection": "nested: feature set, rules and battery-state time constant by inner CV on the "
                           "training flights of each fold",
        "model": r.spec.describe(),
        "voltage_compensation": r.spec.voltage,
        "battery_state": _battery_state(r.spec),
        "battery_nominal_V": r.spec.nominal_V,
        "per_flight_calibration": calibrate,
        "calibration_scale": r.calibration,
        "folds": [
            {"held_out": f.held_out, "samples": f.n_samples, "calibration_scale": f.calibration_scale,
             "model_structure": f.spec.describe(), "n_rules": f.spec.n_rules,
             "model": dataclasses.asdict(f.model),
             "baselines": {k: dataclasses.asdict(v) for k, v in f.baselines.items()},
             "best_baseline": f.best_baseline}
            for f in r.folds
        ],
        "pooled_rmse_N": r.pooled,
        "comparisons": r.comparisons,
        "information_levels": INFORMATION,
        "verdict_levels": sorted({c["information"] for c in r.comparisons.values() if c["in_verdict"]}),
        "headline": headline(r.comparisons),
        "verdict": r.verdict,
        "verdict_text": VERDICT_TEXT[r.verdict],
        "overrides": list(r.overrides),
        "warnings": list(r.warnings),
        "thrust_map_rules": r.params.thrust_map.n_rules,
        "band": list(r.params.thrust_map.input_range[0]),
        "scored_with": "fmu_models.quadrotor.thrust.motor_thrust (the FMU's function)",
    }


def _battery_state(spec: ModelSpec) -> dict[str, Any]:
    if spec.voltage:
        return {"method": "logged battery voltage", "fmu_input": "battery_voltage_V"}
    if spec.tau_s is None:
        return {"method": "none (--no-battery-state)"}
    return {"method": "hover condition (identification.thrust.battery.hover_thrust_scale)", "tau_s": spec.tau_s,
            "hover_climb_m_s": HOVER_CLIMB_M_S, "fmu_input": "battery_voltage_V",
            "equivalent_voltage": "battery_nominal_V * s(t); thrust_voltage_exponent = 1"}


def _write(r: ThrustResult, cfg: ThrustConfig) -> ThrustResult:
    metrics_path = cfg.metrics or (cfg.out.with_suffix(".metrics.json") if cfg.out else None)
    written = None
    if cfg.out is not None and (r.verdict != "lose" or cfg.write_losing_model):
        section = r.params.to_dict()
        section["k_thrust_source"] = "default (not identified from thrust data)"
        QuadrotorParams.from_dict(section, source=f"{cfg.out} (about to be written)")
        cfg.out.parent.mkdir(parents=True, exist_ok=True)
        write_json(cfg.out, {"quadrotor": section, "uncertainty": r.uncertainty, "_identification": {
            "metrics": str(metrics_path), "verdict": r.verdict,
            "flights": [{"flight": f["flight"], "mass_kg": f["mass_kg"]} for f in r.flights],
            "fmu_mass_kg": r.params.mass_kg, "battery_state": _battery_state(r.spec),
            "flight_calibration_thrust_scale": r.calibration}})
        written = cfg.out
        if r.verdict == "lose":
            r = dataclasses.replace(r, overrides=(*r.overrides, f"--write-losing-model: wrote {cfg.out} although "
                                                  "a baseline beats the model on held-out data"))
    elif cfg.out is not None:
        r = dataclasses.replace(r, warnings=(*r.warnings, f"{cfg.out} not written: the model loses "
                                             "(--write-losing-model writes it anyway)"))
    r.metrics["overrides"] = list(r.overrides)
    r.metrics["parameters_written"] = str(written) if written else None
    if metrics_path is not None:
        metrics_path.parent.mkdir(parents=True, exist_ok=True)
        write_json(metrics_path, r.metrics)
    return dataclasses.replace(r, written=written)

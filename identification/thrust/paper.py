"""Paper 000's single-log thrust workflow (``uavfmu identify thrust --method paper``) as a library.

``identify_thrust_paper(cfg) -> PaperThrustResult`` cuts the airborne (PWM, F_z) data set from the log,
computes the Pearson correlation of each candidate input with F_z, refuses to train below the paper's 0.85
gate unless ``force`` (:class:`CorrelationGateError`, after writing the metrics file with ``refused``),
trains the ANFIS by hybrid learning, scores it on validation data (a second log, or the last part of the
log) against least-squares polynomials, derives k of eq. 6 from the curve's slope and writes a parameter
file ``build_fmus.py --params`` reads. :func:`load_paper_data` is its first step (data sets and
correlations), public so a caller can show the correlations before training. The default thrust workflow
(many flights, voltage-aware) is ``identification.thrust.workflow``.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.units import G0_M_S2
from fmu_models.quadrotor.anfis import AnfisMap
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.thrust import thrust_sum
from identification.common.jsonio import write_json
from identification.common.metrics import block_starts, overall_outcome, skill_interval
from identification.thrust.anfis_train import (
    AnfisTrainConfig,
    PolynomialFit,
    TrainResult,
    polynomial_baselines,
    r_squared,
    rmse,
    train_anfis,
)
from identification.thrust.dataset import (
    MOTOR_SIGNAL,
    PAPER_MIN_PEARSON,
    CorrelationGateError,
    MotorSpeedModel,
    ThrustConstant,
    ThrustDataError,
    ThrustDataset,
    ThrustDatasetConfig,
    build_thrust_dataset,
    check_gate,
    damage_gate,
    interleaved_blocks,
    k_thrust_from_curve,
    pearson,
)

CHECK_EVERY = 5  #: every 5th block of the training data is checking data (early stopping)
DEFAULT_BATTERY_V = 11.1  #: battery voltage [V] for k when none is given or logged (3S LiPo, nominal)
K_RATIO_BAND = (0.5, 2.0)  #: slope-based over level-based k outside this band: a warning


def _paper_anfis() -> AnfisTrainConfig:
    return AnfisTrainConfig(n_mfs=3, order=1, epochs=100)


@dataclass(frozen=True)
class PaperThrustConfig:
    """Options of :func:`identify_thrust_paper` (``train_fraction`` and ``min_pearson`` checked here)."""

    log: Path
    """flight log to identify from (.BIN DataFlash, .ulg ULog, ...)"""
    out: Path
    """parameter JSON to write"""
    dataset: ThrustDatasetConfig
    """how to cut the data set: mass [kg], airborne thresholds, lag, low-pass, extra inputs, idle PWM [us]"""
    validate: Path | None = None
    """second log for validation (``None``: the last ``1 - train_fraction`` of ``log``)"""
    plots: Path | None = None
    """folder for the PNG figures of paper 000 Figs. 3-6 (``None``: no figures)"""
    channel_map: Path | None = None
    """TOML/JSON ``[channels]`` overriding the log's motor mapping"""
    metrics: Path | None = None
    """metrics JSON (``None``: ``out`` with suffix ``.metrics.json``)"""
    anfis: AnfisTrainConfig = field(default_factory=_paper_anfis)
    """hybrid-learning hyper-parameters (3 Gaussian MFs, order 1, 100 epochs)"""
    train_fraction: float = 0.7
    """first fraction of the airborne samples to train on, without ``validate`` (0, 1)"""
    min_pearson: float = PAPER_MIN_PEARSON
    """Pearson gate on r(summed PWM, F_z) [-1, 1]"""
    skip_gate: bool = False
    """train even when the Pearson gate fails (``--skip-pearson-gate``; recorded as ``gate_forced``)"""
    accept_damaged_log: bool = False
    """use a log whose damaged share exceeds the limit (``--accept-damaged-log``; the damage is reported)"""
    write_losing_model: bool = False
    """write the parameter file even when a baseline beats the model (``--write-losing-model``)"""
    check_block_s: float = 5.0
    """checking data: every 5th block of this length [s] of the training data"""
    kv_rpm_per_V: float = 920.0
    """motor Kv [rpm/V] of the motor speed model behind k"""
    battery_V: float | None = None
    """battery voltage [V] for k (``None``: median logged voltage, else 11.1 V)"""
    pwm_max_us: float = 1900.0
    """per-motor PWM of full throttle [us]"""
    k_thrust_N_s2: float | None = None
    """use this k [N s^2] instead of deriving it"""

    def __post_init__(self) -> None:
        if not 0.0 < self.train_fraction < 1.0:
            raise ThrustDataError(f"--train-fraction = {self.train_fraction}; allowed (0, 1)")
        if not -1.0 <= self.min_pearson <= 1.0:
            raise ThrustDataError(f"--min-pearson = {self.min_pearson}; allowed [-1, 1]")

    @property
    def metrics_path(self) -> Path:
        """The metrics JSON written beside the parameters."""
        return self.metrics or self.out.with_suffix(".metrics.json")


@dataclass(frozen=True)
class PaperData:
    """The data sets of one run: ``full`` (all airborne samples of the log), training and validation parts.

    ``correlations``: Pearson r of every candidate input with F_z over ``full`` (what the gate looks at,
    as the paper's Fig. 3). ``val_name``: where the validation data come from, in words.
    """

    full: ThrustDataset
    train: ThrustDataset
    val: ThrustDataset
    val_name: str
    correlations: dict[str, float]
    overrides: tuple[str, ...] = ()


@dataclass(frozen=True)
class PaperThrustResult:
    """Outcome of :func:`identify_thrust_paper` (a refused gate raises instead; its metrics say ``refused``).

    ``metrics``: what the metrics JSON holds. ``warnings``: a forced gate, slope and level k disagreeing.
    ``notes``: the data set's notes (signals not logged, short segments dropped).
    """

    metrics: dict[str, Any]
    params_path: Path
    metrics_path: Path
    correlations: dict[str, float]
    k_thrust_N_s2: float
    gate_forced: bool
    model_beats_baselines: bool = True
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    outcome: str = "win"  #: win / tie / lose against the baselines (skill intervals)
    overrides: tuple[str, ...] = ()  #: what an option overrode (damaged log, gate, losing model written)
    written: bool = True  #: the parameter file was written

    @property
    def exit_code(self) -> int:
        """0 when no baseline beats the model on validation data, 3 when one does."""
        return 3 if self.outcome == "lose" else 0


def _read(path: Path, channel_map: Path | None = None) -> Any:
    """The ``FlightLog`` of ``path`` (``identification.logs.readers.read_log``)."""
    from identification.logs.readers import read_log

    return read_log(path, channel_map=channel_map)


def load_paper_data(cfg: PaperThrustConfig) -> PaperData:
    """Read the log(s) and cut the training and validation data sets (FileNotFoundError, ThrustDataError)."""
    for path in (cfg.log, cfg.validate):
        if path is not None and not path.is_file():
            raise FileNotFoundError(f"{path}: log file not found")
    log = _read(cfg.log, cfg.channel_map)
    overrides = list(damage_gate(log, cfg.accept_damaged_log))
    full = build_thrust_dataset(log, cfg.dataset, source=str(cfg.log))
    if cfg.validate is not None:
        train = full
        vcfg = dataclasses.replace(cfg.dataset, lag_s=full.lag_s)
        vlog = _read(cfg.validate, cfg.channel_map)
        overrides += damage_gate(vlog, cfg.accept_damaged_log)
        val = build_thrust_dataset(vlog, vcfg, source=str(cfg.validate))
        val_name = str(cfg.validate)
    else:
        train, val = full.split(cfg.train_fraction)
        val_name = f"last {1.0 - cfg.train_fraction:.0%} of {cfg.log.name}"
    return PaperData(full, train, val, val_name, full.correlations(), tuple(overrides))


def identify_thrust_paper(
    cfg: PaperThrustConfig, data: PaperData | None = None, on_warning: Callable[[str], None] | None = None
) -> PaperThrustResult:
    """Paper 000's workflow on ``cfg.log`` (see the module docstring); ``data`` from :func:`load_paper_data`.

    ``on_warning`` is called with each warning when it arises (they are in the result too). Raises
    CorrelationGateError (gate refused; metrics written), ThrustDataError, AnfisTrainingError,
    ParameterError, FileNotFoundError or LogError.
    """
    warn = on_warning or (lambda _message: None)
    data = data or load_paper_data(cfg)
    metrics = _data_metrics(cfg, data)
    if cfg.plots:
        from identification.common import plots

        plots.thrust_correlation(
            cfg.plots / "fig3_correlation.png", data.full.pwm_sum_us, data.full.fz_N, data.correlations,
            cfg.min_pearson,
        )
    gate_warnings = _gate(cfg, data, metrics)
    for w in gate_warnings:
        warn(w)
    train_result = _train(cfg, data.train)
    amap = train_result.amap
    polys = polynomial_baselines(data.train.pwm_sum_us, data.train.fz_N, data.val.pwm_sum_us, data.val.fz_N)
    k_value, k_source, kc, k_warnings = _k_thrust(cfg, amap, data.train)
    for w in k_warnings:
        warn(w)
    section = _params_section(cfg, amap, k_value, k_source)
    metrics.update(_fit_metrics(train_result, data, polys, fmu_thrust(section), cfg.dataset.mass_kg,
                                cfg.check_block_s))
    metrics.update(_k_metrics(k_value, kc))
    overrides = list(data.overrides) + [w for w in gate_warnings[:1]]
    written = metrics["outcome"] != "lose" or cfg.write_losing_model
    if written:
        write_json(cfg.out, {"quadrotor": section, "_identification": {"metrics": str(cfg.metrics_path)}})
        if metrics["outcome"] == "lose":
            overrides.append(f"--write-losing-model: wrote {cfg.out} although a baseline beats the model")
    metrics["overrides"] = overrides
    metrics["parameters_written"] = str(cfg.out) if written else None
    write_json(cfg.metrics_path, metrics)
    if cfg.plots:
        _fit_plots(cfg.plots, data, train_result, min(polys, key=lambda p: p.test_rmse), fmu_thrust(section),
                   cfg.dataset.pwm_idle_us)
    return PaperThrustResult(
        metrics=metrics,
        params_path=cfg.out,
        metrics_path=cfg.metrics_path,
        correlations=data.correlations,
        k_thrust_N_s2=k_value,
        gate_forced=bool(gate_warnings),
        model_beats_baselines=bool(metrics["model_beats_baselines"]),
        outcome=metrics["outcome"],
        overrides=tuple(overrides),
        written=written,
        warnings=tuple(gate_warnings + k_warnings),
        notes=tuple(data.full.notes),
    )


def _data_metrics(cfg: PaperThrustConfig, data: PaperData) -> dict[str, Any]:
    """The metrics known before training: data sets, lag, correlations."""
    return {
        "log": str(cfg.log),
        "validation": data.val_name,
        "mass_kg": cfg.dataset.mass_kg,
        "lag_s": data.full.lag_s,
        "lag_estimated": data.full.lag_estimated,
        "lowpass_hz": cfg.dataset.lowpass_hz,
        "pearson": data.correlations,
        "pearson_train_split": data.train.correlations(),
        "pearson_gate": cfg.min_pearson,
        "n_train": data.train.n_samples,
        "n_validation": data.val.n_samples,
        "notes": list(data.full.notes),
    }


def _gate(cfg: PaperThrustConfig, data: PaperData, metrics: dict[str, Any]) -> list[str]:
    """Apply the Pearson gate; on refusal write the metrics (``refused``) and re-raise. Returns warnings."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # returned as a warning instead
            gate_warnings = check_gate(
                data.correlations, ("pwm_sum_us",), cfg.min_pearson, cfg.skip_gate, source=str(cfg.log)
            )
    except CorrelationGateError:
        metrics["refused"] = True
        write_json(cfg.metrics_path, metrics)
        raise
    metrics["gate_forced"] = bool(gate_warnings)
    return [f"--skip-pearson-gate: training despite the gate: {w}" for w in gate_warnings[:1]]


def _train(cfg: PaperThrustConfig, train: ThrustDataset) -> TrainResult:
    """Hybrid ANFIS training on summed PWM; every 5th block of the training data is checking data."""
    block = max(1, round(cfg.check_block_s / train.sample_period_s))
    chk = interleaved_blocks(train.n_samples, block, CHECK_EVERY)
    a = cfg.anfis
    return train_anfis(
        train.pwm_sum_us[~chk],
        train.fz_N[~chk],
        a,
        train.pwm_sum_us[chk],
        train.fz_N[chk],
        input_names=("pwm_sum_us",),
        output="thrust_N",
        source=f"uavfmu identify thrust {cfg.log.name} (hybrid ANFIS, {a.n_mfs} {a.mf_type} MFs, order {a.order})",
    )


def _k_thrust(
    cfg: PaperThrustConfig, amap: AnfisMap, train: ThrustDataset
) -> tuple[float, str, ThrustConstant | None, list[str]]:
    """k [N s^2] of eq. 6, its source in words, the derivation (None if it failed for a given k), warnings."""
    battery_V = cfg.battery_V
    if battery_V is None:
        bv = train.inputs.get("battery_voltage_V")
        battery_V = float(np.median(bv)) if bv is not None else DEFAULT_BATTERY_V
    motor = MotorSpeedModel(cfg.kv_rpm_per_V, battery_V, cfg.dataset.pwm_idle_us, cfg.pwm_max_us)
    try:
        kc: ThrustConstant | None = k_thrust_from_curve(amap, train.pwm_sum_us, motor)
    except ThrustDataError:
        if cfg.k_thrust_N_s2 is None:
            raise
        kc = None  # k given explicitly: the derivation is only a diagnostic
    notes = []
    if kc is not None:
        ratio = kc.k_N_s2 / kc.k_from_level_N_s2 if kc.k_from_level_N_s2 > 0.0 else float("inf")
        if not K_RATIO_BAND[0] <= ratio <= K_RATIO_BAND[1]:
            notes.append(
                f"k from the curve's slope ({kc.k_N_s2:.3g}) and from its level "
                f"({kc.k_from_level_N_s2:.3g}) differ by {ratio:.2f}x: the motor speed model or the "
                "data's PWM-thrust slope is off (battery sag over a hover flight makes the slope shallow)"
            )
    if cfg.k_thrust_N_s2 is not None:
        return cfg.k_thrust_N_s2, "given on the command line (--k-thrust-N-s2)", kc, notes
    assert kc is not None  # derivation errors were raised above
    return kc.k_N_s2, kc.description, kc, notes


def _params_section(cfg: PaperThrustConfig, amap: AnfisMap, k_value: float, k_source: str) -> dict[str, Any]:
    """The ``quadrotor`` section of the parameter file, checked by ``QuadrotorParams`` before writing."""
    from fmu_models.quadrotor.params import QuadrotorParams

    section = {
        "mass_kg": cfg.dataset.mass_kg,
        "pwm_idle_us": cfg.dataset.pwm_idle_us,
        "k_thrust_N_s2": k_value,
        "k_thrust_source": k_source,
        "thrust_map": amap.to_dict(),
    }
    QuadrotorParams.from_dict(section, source=f"{cfg.out} (about to be written)")
    return section


def fmu_thrust(section: dict[str, Any]) -> Callable[[ThrustDataset], np.ndarray]:
    """Total thrust [N] of a data set's per-motor PWM as the FMU built from ``section`` evaluates it (band
    extension, idle, nominal voltage): every figure is scored with it, never with the raw map."""
    from fmu_models.quadrotor.params import QuadrotorParams
    from identification.thrust.model import fmu_total_thrust

    params = QuadrotorParams.from_dict(section)

    def total(ds: ThrustDataset) -> np.ndarray:
        pwm = np.stack([ds.inputs[MOTOR_SIGNAL.format(k=k)] for k in range(1, N_MOTORS + 1)], axis=1)
        return fmu_total_thrust(params, pwm, np.full(len(pwm), params.battery_nominal_V))

    return total


def _fit_metrics(res: TrainResult, data: PaperData, polys: list[PolynomialFit],
                 thrust: Callable[[ThrustDataset], np.ndarray], mass_kg: float, check_block_s: float) -> dict[str, Any]:
    """Training history and the scores on training and validation data (RMSE [N], R^2, Pearson r) of the
    thrust the FMU evaluates, beside the constant (m g) and the least-squares polynomials of summed PWM."""
    train, val = data.train, data.val
    y_val, y_train = thrust(val), thrust(train)
    constant = rmse(np.full(val.n_samples, mass_kg * G0_M_S2), val.fz_N)
    rivals = {"constant m g": np.full(val.n_samples, mass_kg * G0_M_S2),
              **{f"polynomial degree {p.degree}": p(val.pwm_sum_us) for p in polys}}
    starts = block_starts(val.n_samples, max(1, round(check_block_s / val.sample_period_s)))
    skill = {k: skill_interval(val.fz_N, y_val, b, starts).as_dict() for k, b in rivals.items()}
    verdict = overall_outcome([v["outcome"] for v in skill.values()])
    return {
        "scored_with": "fmu_models.quadrotor.thrust.motor_thrust per motor (the FMU's function)",
        "constant_validation_rmse_N": constant,
        "skill_vs_baselines": skill,
        "model_beats_baselines": verdict == "win",
        "outcome": verdict,
        "verdict": {"win": "model beats every baseline on validation data",
                    "tie": "TIE: no baseline beats the model on validation data, but not every one beyond noise",
                    "lose": "MODEL LOSES to a baseline on validation data"}[verdict],
        "epochs": res.epochs_run,
        "best_epoch": res.best_epoch + 1,
        "train_rmse_N": rmse(y_train, train.fz_N),
        "train_r2": r_squared(y_train, train.fz_N),
        "validation_rmse_N": rmse(y_val, val.fz_N),
        "validation_r2": r_squared(y_val, val.fz_N),
        "validation_pearson": pearson(y_val, val.fz_N),
        "polynomial_validation_rmse_N": {str(p.degree): p.test_rmse for p in polys},
        "best_polynomial_degree": min(polys, key=lambda p: p.test_rmse).degree,
        "train_rmse_per_epoch_N": list(res.train_rmse),
        "check_rmse_per_epoch_N": list(res.check_rmse or ()),
        "band_us": list(res.amap.input_range[0]),
    }


def _k_metrics(k_value: float, kc: ThrustConstant | None) -> dict[str, Any]:
    """k used and its derivation (None where it was not derived)."""
    return {
        "k_thrust_N_s2": k_value,
        "k_thrust_from_slope_N_s2": kc.k_N_s2 if kc else None,
        "k_thrust_from_level_N_s2": kc.k_from_level_N_s2 if kc else None,
        "mean_slope_N_per_us": kc.mean_slope_N_per_us if kc else None,
    }


def _fit_plots(folder: Path, data: PaperData, res: TrainResult, best_poly: PolynomialFit,
               thrust: Callable[[ThrustDataset], np.ndarray], idle_us: float) -> None:
    """Paper 000 Figs. 4-6: learning curves, validation overlay, thrust curve against the best polynomial."""
    from identification.common import plots

    train, val, amap = data.train, data.val, res.amap
    plots.thrust_training(folder / "fig4_training.png", res.train_rmse, res.check_rmse, res.best_epoch)
    plots.thrust_validation(
        folder / "fig5_validation.png",
        val.time_s,
        val.fz_N,
        thrust(val),
        val.sample_period_s,
        title=f"validation on {data.val_name}",
    )
    lo = min(train.pwm_sum_us.min(), val.pwm_sum_us.min())
    hi = max(train.pwm_sum_us.max(), val.pwm_sum_us.max())
    grid = np.linspace(lo, hi, 300)
    band = amap.input_range[0]
    plots.thrust_curve(
        folder / "fig6_thrust_curve.png",
        np.concatenate([train.pwm_sum_us, val.pwm_sum_us]),
        np.concatenate([train.fz_N, val.fz_N]),
        [
            ("ANFIS (as the FMU evaluates it)", grid, thrust_sum(amap, grid, N_MOTORS * idle_us, *band)),
            (f"polynomial degree {best_poly.degree}", grid, best_poly(grid)),
        ],
        amap.input_range[0],
    )

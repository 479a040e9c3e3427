"""The fixed wing's discrepancy learned where the truth is known: every segment of ``identify aero`` left out in turn.

A prediction band is honest on a new flight when its discrepancy was learned on replays the parameters were not
fitted on. One excitation log of a fixed wing holds a handful of segments, and its held-out ones (one per axis
on a planned timeline) are too few to learn from: a band learned on the aileron and rudder segments is several
times too wide on the elevator one, and too narrow on the next rough one (docs/validation.md#prediction-bands).
Here each segment is left out in turn: ``identify aero`` runs on the others with the same options, and the
left-out segment is replayed with that fold's estimate (its out-of-sample replay); the discrepancy is learned and
calibrated (``discrepancy.learn``, ``mc_bands.calibrate``) on every segment's out-of-sample replay. That is the
usual cross-validation estimate of the full estimate's error on new data (slightly pessimistic: each fold fits on
one segment fewer). Costs one identification per segment.

One FMU serves every fold: each fold's parameters are start values (the freed ones from its ``uncertainty``
mean, drawn in the Monte Carlo runs; every other fixed-wing parameter at the fold's value), so no fold's replay
carries another's estimate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.params import Discrepancy, Uncertainty
from identification.validation.job import ValidationJob
from identification.validation.replay import ReplayResult, ValidationInputError, ValidationOptions

#: the fewest segments a leave-one-out discrepancy is learned from (two folds: one left out, one learned on)
MIN_SEGMENTS = 3
#: the most segments (one identification each; a log of more should be split or given fewer)
MAX_SEGMENTS = 60


@dataclass
class Fold:
    """One segment left out: the replay job with the fold's parameters, their uncertainty, the out-of-sample
    replay at the fold's estimate, and (with Monte Carlo draws) each signal's draws minus it."""

    segment: Any  #: ``identification.aero.model.Segment``
    job: ValidationJob
    uncertainty: Uncertainty
    replay: ReplayResult
    keep: dict[str, np.ndarray] = field(default_factory=dict)
    failures: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return f"{self.job.log.name} {self.segment.t0_s:g}-{self.segment.t1_s:g} s"


@dataclass(frozen=True)
class CrossFitResult:
    """What :func:`cross_fitted_discrepancy` learned, fold by fold, and where it was written."""

    folds: tuple[Fold, ...]
    discrepancy: Discrepancy
    skipped: tuple[str, ...] = ()
    written: Path | None = None

    def lines(self) -> list[str]:
        """The folds, then each signal's learned discrepancy as ``uavfmu discrepancy`` prints it."""
        from identification.validation.discrepancy import DiscrepancyResult

        out = [f"discrepancy from {len(self.folds)} out-of-sample segment replays (each segment's identification "
               "left it out):"]
        for f in self.folds:
            res = f.replay
            out.append(f"  {f.segment.t0_s:g}-{f.segment.t1_s:g} s: {len(res.windows) - res.excluded} windows"
                       + (f"; the fold's identification recorded: {'; '.join(f.failures)}" if f.failures else ""))
        out += [f"  skipped: {s}" for s in self.skipped]
        replays = tuple({"log": f.name, "windows_scored": len(f.replay.windows) - f.replay.excluded}
                        for f in self.folds)
        return out + DiscrepancyResult(self.discrepancy, replays, self.written).lines()


def fold_start_values(identified: dict[str, Any], uncertainty: Uncertainty) -> dict[str, float]:
    """Every numeric fixed-wing parameter of a fold's estimate except those its uncertainty draws."""
    drawn = set(uncertainty.names)
    return {k: float(v) for k, v in identified.items()
            if k not in drawn and isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)}


def segment_folds(log_path: Path, segments: Sequence[Any], fmu: Path, opt: Any, init: Any,
                  replay_options: ValidationOptions | None = None, draws: int = 0, seed: int = 0, *,
                  mapping_file: Path | None = None, channel_map: Path | None = None, executor: Any = None,
                  progress: Callable[[str], None] | None = None) -> tuple[list[Fold], list[str]]:
    """Each of ``segments`` (of the single log ``log_path``) left out in turn: ``identify aero`` on the others with
    ``opt`` (``AeroOptions``; its segments replaced) from ``init`` (``FixedWingParams``), and the left-out segment
    replayed through ``fmu`` (a fixed-wing FMU; every parameter set from the fold) with ``replay_options``. With
    ``draws`` the replay is also run with the fold's parameters drawn (``executor`` required), keeping each signal's
    draws minus the nominal replay, which :func:`learn_folds` calibrates on. Returns the folds and, per segment
    whose identification raised, why it was skipped."""
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.aero.identify import AeroSource, identify_aero
    from identification.estimation.oem import EstimationError
    from identification.logs.readers import read_log
    from identification.validation.discrepancy import learn
    from identification.validation.workflow import validate, validate_mc

    if not MIN_SEGMENTS <= len(segments) <= MAX_SEGMENTS:
        raise ValidationInputError(f"{log_path}: {len(segments)} segments; leaving each out in turn needs "
                                   f"{MIN_SEGMENTS} to {MAX_SEGMENTS}")
    if draws and executor is None:
        raise ValidationInputError("segment folds: Monte Carlo draws need an executor")
    log = read_log(log_path, channel_map=channel_map)
    mapping = PwmMapping.load(mapping_file) if mapping_file else PwmMapping.from_ardupilot(log.params)
    folds, skipped = [], []
    for i, seg in enumerate(segments):
        others = [g for j, g in enumerate(segments) if j != i]
        try:
            r = identify_aero([AeroSource(log, mapping, None, others, [seg])], None, init,
                              replace(opt, segments=None, validate_segments=None, timeline=None, progress=False))
        except (EstimationError, ValueError) as err:
            skipped.append(f"{seg.t0_s:g}-{seg.t1_s:g} s: its identification failed: {err}")
            continue
        est = r.estimate
        n = est.n_global
        unc = Uncertainty(names=list(est.names[:n]), mean=[float(v) for v in est.values[:n]],
                          covariance=est.covariance_printed().tolist())
        job = ValidationJob(fmu, log_path, replay_options or ValidationOptions(), mapping=mapping_file,
                            channel_map=channel_map, start_values=fold_start_values(r.identified, unc),
                            embedded_params=False, t_range_s=(seg.t0_s, seg.t1_s))
        mean = dict(zip(unc.names, unc.mean, strict=True))
        res = validate(replace(job, start_values={**mean, **job.start_values})).replay
        if res is None:  # validate keeps the replay in this process; a result without it has nothing to learn from
            raise ValidationInputError(f"{log_path}: the replay of {seg.t0_s:g}-{seg.t1_s:g} s returned no arrays")
        folds.append(Fold(seg, job, unc, res, failures=tuple(r.failures)))
        if progress is not None:
            progress(f"fold {i + 1}/{len(segments)}: {seg.t0_s:g}-{seg.t1_s:g} s left out")
    if len(folds) < 2:
        raise ValidationInputError(f"{log_path}: {len(folds)} of {len(segments)} segment folds identified; the "
                                   "discrepancy needs two ({})".format("; ".join(skipped) or "none failed"))
    if draws:
        shape = learn([f.replay for f in folds], [f.name for f in folds])  # the signals the draws leave noiseless
        for f in folds:
            keep: dict[str, np.ndarray] = {}
            f.replay = validate_mc(f.job, f.uncertainty, draws, seed, executor=executor, discrepancy=shape,
                                   keep=keep).replay
            f.keep = keep
    return folds, skipped


def learn_folds(folds: Sequence[Fold], exclude: int | None = None, scaled: bool = True,
                weights: Sequence[float] = (1.0, 0.0)) -> Discrepancy:
    """The discrepancy learned on the folds' out-of-sample replays (fold ``exclude`` left out: to score that
    segment's band on replays that taught it nothing) and, where the folds hold Monte Carlo draws, calibrated on
    them (``mc_bands.calibrate``). ``scaled``, ``weights``: as ``discrepancy.learn`` and ``calibrate`` take them."""
    from identification.validation.discrepancy import learn
    from identification.validation.mc_bands import calibrate

    use = [f for i, f in enumerate(folds) if i != exclude]
    disc = learn([f.replay for f in use], [f.name for f in use], scaled=scaled, note=(
        "empirical quantiles of logged - FMU per horizon bin (identification.validation.discrepancy), learned "
        "from out-of-sample replays: each listed segment replayed with the estimate of identify aero on the other "
        "segments (identification.validation.cross_fit)"))
    if all(f.keep for f in use):
        disc = calibrate(disc, [(f.replay, f.keep) for f in use], weights=weights)
    return disc


def replay_fmu(work_dir: Path) -> Path:
    """The fixed-wing FMU the folds replay through, built into ``work_dir``: the built-in defaults (every parameter
    is set per fold), co-simulation only, for this machine's platform only (the replays run here)."""
    from fmu_models.fmi.fmus import BuildOptions, build_fmus
    from fmu_models.fmi.zigcc import host_platform

    here = BuildOptions(kinds=("cs",), platforms=(host_platform().fmi_name,))
    (fmu,) = build_fmus(None, Path(work_dir), ["fixed_wing"], "native", here).fmus
    return fmu


def cross_fitted_discrepancy(log_path: Path, segments: Sequence[Any], opt: Any, init: Any, work_dir: Path,
                             params_out: Path | None = None, replay_options: ValidationOptions | None = None,
                             draws: int = 19, seed: int = 0, *, mapping_file: Path | None = None,
                             channel_map: Path | None = None, workers: int | None = 2,
                             progress: Callable[[str], None] | None = None) -> CrossFitResult:
    """The discrepancy of ``identify aero`` on one log, learned on every segment's out-of-sample replay
    (:func:`segment_folds`, :func:`learn_folds`) and, with ``params_out`` (the JSON parameter file ``identify
    aero`` wrote), stored there under ``discrepancy`` beside ``uncertainty``; ``validate --mc`` then uses it. The
    replays run through :func:`replay_fmu`, built into ``work_dir``. ``draws``: Monte Carlo draws per segment to
    calibrate the combined band on (0: none)."""
    from contextlib import nullcontext

    from identification.common.parallel import Executor
    from identification.validation.discrepancy import write_discrepancy
    from identification.validation.mc_bands import check_draws

    if draws:
        check_draws(draws, 3, 1, (replay_options or ValidationOptions()).max_memory_mb)  # before anything runs
    fmu = replay_fmu(Path(work_dir))
    with Executor(None, workers) if draws else nullcontext() as ex:
        folds, skipped = segment_folds(log_path, segments, fmu, opt, init, replay_options, draws, seed,
                                       mapping_file=mapping_file, channel_map=channel_map, executor=ex,
                                       progress=progress)
    disc = learn_folds(folds)
    if params_out is not None:
        write_discrepancy(params_out, disc)
    return CrossFitResult(tuple(folds), disc, tuple(skipped), params_out)

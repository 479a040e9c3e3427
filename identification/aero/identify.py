"""``identify aero`` as a library: fixed-wing derivatives from a flight log by output error, typed in and out.

:func:`identify_aero` takes a read log, its PWM mapping, start parameters and :class:`AeroOptions`, and returns
an :class:`AeroResult`: estimates with their bounds (and which bound), nuisance parameters apart, the
identifiability before and after the solve, the chosen nuisance set and input delay, fit metrics per output
on fitted and held-out segments. Steps after the solve that fail (scoring, plots) are recorded in
``failures``; the estimate is kept. :func:`write_results` writes the parameter file and the metrics JSON first,
then the plots.

Nuisance parameters (Jategaonkar ch. 5; Klein & Morelli ch. 6): with ``nuisance="auto"`` the fit is run
without and with per-segment initial body rates and output biases of the gyro and accelerometer outputs, and
the set with the lower Akaike criterion ``n ln det R + 2 k`` is kept. A command -> surface delay (0 to
``max_delay_s``) is scanned at the estimate; if the best delay lowers the criterion it is refitted with it.

Longer than 700 lines because it is one workflow whose steps (free-set and nuisance choice, delay search,
solve, bounds, held-out scoring, files) share the option and result types; each step is its own function.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.model import init_function
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero import HORIZON_RANGE_S
from identification.aero import model as aero
from identification.aero import segments as aero_segments
from identification.aero.priors import CONSIDERED, Prior, fixed_sd, geometry_priors
from identification.common.metrics import FitMetrics, skill_interval
from identification.estimation.identifiability import Identifiability
from identification.estimation.oem import (
    FREE_IMPACT,
    FREE_ROUNDS,
    Consider,
    Estimate,
    EstimationError,
    HorizonDivergedError,
    Manoeuvre,
    OutputErrorEstimator,
    consider_covariance,
    fixed_worth_freeing,
    start_consider_terms,
)
from identification.estimation.unlogged_inputs import fit_with_unlogged
from identification.logs.flightlog import DEFAULT_MAX_DAMAGE, FlightLog, check_quality
from identification.logs.sensor_chain import LoopClock, loop_clock, sensor_chain

#: sign constraints that keep the identified model stable (paper 001 rejects diverging models)
STABILITY_SIGNS = {"C_ell_p": -1, "C_m_q": -1, "C_n_r": -1, "C_m_alpha": -1, "C_n_beta": +1}
#: the primary derivatives, the start of ``free="auto"``
PRIMARY = ("C_ell_p", "C_ell_beta", "C_ell_r", "C_ell_delta_a", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta",
           "C_m_alpha", "C_m_q", "C_m_delta_e")
#: zero-order coefficients that ``free="auto"`` estimates with the primaries: every segment starts from a logged
#: trim, where ``C_m_0 + C_m_alpha alpha + C_m_delta_e delta_e ~ 0``; with C_m_0 held at a value that is not the
#: aircraft's, that trim ties C_m_alpha to C_m_delta_e (r = +0.999 on the excitation log) and biases both
#: (intercept always in, as in equation error's stepwise regression)
TRIM_OFFSETS = ("C_m_0",)
#: fitted outputs that see the pitch axis: without one, the pitch derivatives rest on their priors and the trim
#: offset is left fixed (one more parameter that only its prior would determine)
PITCH_OUTPUTS = ("pitch_rad", "rate_body_y_rad_s", "accel_body_x_m_s2", "accel_body_z_m_s2", "airspeed_m_s")
#: zero-order force coefficients and the specific force each offsets. A per-segment bias of that accelerometer
#: axis is confounded with the coefficient: an offset common to every segment fits either way, so the estimate
#: drifts along that ridge. ``nuisance="auto"`` drops the bias when ``free="auto"`` frees the coefficient. On the
#: shared excitation log, keeping the bias put C_Y_0 at 0.0028 against a common accel-y bias of -0.04 m/s^2 (a
#: study, not kept); a held-out replay, which has no bias, then read the lateral specific force 0.04 m/s^2 off
#: (identification/aero/readme.md, "Zero-order coefficients and accelerometer biases")
ZERO_FORCE_AXES = {"C_Y_0": "accel_body_y_m_s2", "C_L_0": "accel_body_z_m_s2", "C_D_p": "accel_body_x_m_s2"}
#: held-out outputs scored against persistence with a block-bootstrap interval over blocks of this length [s]
SKILL_BLOCK_S = 2.0
#: per-segment nuisance candidates of ``nuisance="auto"``
AUTO_STATES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")
AUTO_BIASES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s", "accel_body_x_m_s2",
               "accel_body_y_m_s2", "accel_body_z_m_s2")


@dataclass(frozen=True)
class AeroOptions:
    """What to estimate and how. ``free="auto"`` picks a well-conditioned set; ``nuisance`` is "auto", "none"
    or "given" (use ``estimate_initial`` and ``biases`` as listed)."""

    free: Sequence[str] | str = "auto"
    outputs: Sequence[str] = aero.DEFAULT_OUTPUTS
    segments: Sequence[aero.Segment] | None = None
    validate_segments: Sequence[aero.Segment] | None = None
    window_s: float = 2.0
    rate_hz: float = 50.0
    nuisance: str = "auto"
    estimate_initial: Sequence[str] = ()
    #: estimated initial state -> the std [state unit] of the start the log gives for it: each segment's logged
    #: start enters as a measurement of that state (a prior at the logged value), so the state takes up the
    #: start's noise but not, as a free one can, the force of a model that is not the aircraft's
    #: (identification.estimation.oem.OutputErrorEstimator ``initial_sd``); {}: estimated states are free
    initial_sd: dict[str, float] = field(default_factory=dict)
    biases: Sequence[str] = ()
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    sigma: dict[str, float] | None = None
    stability_constraints: bool = True
    max_iter: int = 40
    horizon_s: float = 1.0
    #: further continuation schedules (first fitted span [s], doubled up to the whole segment) each fit from the
    #: start values is restarted with; the lowest criterion is kept (:func:`_cold_fit`). The output-error cost of
    #: long lateral records has several minima, and which one a start walks into depends on the spans it walks
    #: (identification/aero/readme.md, "Several minima from one start"). (): one schedule
    restart_horizons_s: Sequence[float] = (0.5, 2.0)
    #: the error of each segment's start state read from the log (the white noise of the signals it is read from,
    #: estimated on the fit segments) enters the bounds as a consider covariance of the states not estimated, and
    #: the small-sample test expects the scatter it brings (``oem.start_consider_terms``); False: the logged
    #: starts count as exact (the bound before 2026-11-29)
    start_noise: bool = True
    max_delay_s: float = 0.1
    #: most negative delay scanned [s] (the surfaces act the logged command of a later time: servo outputs logged
    #: after they took effect, or below the loop rate); None: one servo-log interval when the servo outputs are
    #: logged slower than the main loop (identification.logs.sensor_chain), else 0. Default 0 (opt-in): the
    #: negative scan has been checked on the shared excitation log and a synthetic flight only
    min_delay_s: float | None = 0.0
    progress: bool = False
    force: bool = False  #: use a log whose damage exceeds ``max_damage`` (its damage is still reported)
    max_damage: float = DEFAULT_MAX_DAMAGE  #: largest damaged or lost share of the log accepted (0..1)
    priors: str = "geometry"  #: "geometry": built-in estimates of six derivatives as a MAP term; "none"
    prior_values: dict[str, Prior] = field(default_factory=dict)  #: user priors (override the geometry ones)
    consider: bool = True  #: fixed aerodynamic coefficients enter the bounds with their prior std
    timeline: Path | None = None  #: timeline file of the (single) log; else ``NAME.timeline.json`` beside it
    equation_error: bool = True  #: equation-error estimate as the output-error start and as a rival
    #: sensor low-pass per fitted output [Hz] applied to the model before it meets the log; None: the log's own
    #: filter parameters (identification.logs.sensor_chain); {} (default): none. Not the default: on the
    #: closed-loop ArduPlane SITL takeoff log (SIM_Plane, not our model class) it moves C_n_r's interval off
    #: SIM_Plane's value (tests/identification/aero/test_aero_sitl.py)
    sensor_filters: dict[str, float] | None = field(default_factory=dict)
    #: step the fit on the autopilot's loop ticks and take each loop's command, the unlogged loops' as the mean of
    #: their logged neighbours (identification.logs.sensor_chain.LoopClock; logs with SCHED_LOOP_RATE and the
    #: gyro logged once per loop); False (default): hold each logged servo sample on a grid from the segment
    #: start. Not the default: on the closed-loop SITL takeoff log (SIM_Plane, whose surfaces pass SITL's servo
    #: model, SIM_SERVO_SPEED, an element not modelled) it moves C_n_r off SIM_Plane's value as the filters do
    loop_ticks: bool = False
    #: with ``loop_ticks``: estimate the unlogged loops' commands from the response after the fit, within their
    #: logged neighbours, and refit (identification.estimation.unlogged_inputs); False: their mean
    estimate_unlogged: bool = False
    #: the derivatives' data bound (``identification.estimation.oem.BOUNDS``): "ar", the coloured Cramér-Rao bound
    #: with an autoregressive residual model and the small-sample bound only where the segments scatter more
    #: (default); "bootstrap", the larger of the Bartlett-tapered coloured Cramér-Rao bound and the segment
    #: bootstrap times Student's t (before 2026-11-28; its median 95 % half-width was 2.3-10x the RMS error on three
    #: replica draws, identification/aero/readme.md)
    bound: str = "ar"


@dataclass
class Fit:
    """One output-error fit: its estimator, data and estimate, and the information criterion."""

    oe: OutputErrorEstimator
    data: list[Manoeuvre]
    estimate: Estimate
    aic: float
    delay_s: float = 0.0


@dataclass
class AeroResult:
    """Everything ``identify aero`` found; ``as_dict()`` is the metrics JSON."""

    free: list[str]
    outputs: list[str]
    fit_segments: list[aero.Segment]
    validation_segments: list[aero.Segment]
    start: dict[str, float]
    before: Identifiability
    fit: Fit
    identified: dict[str, Any]
    nuisance_choice: str
    scores: dict[str, dict[str, FitMetrics]] = field(default_factory=dict)
    replay: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    baselines: dict[str, dict[str, Any]] = field(default_factory=dict)
    quality: dict[str, Any] | None = None  #: the log's data-quality summary (``DataQuality.to_dict``)
    delay_range_s: tuple[float, float] | None = None  #: the command -> surface delays scanned [s]
    pool: Pool | None = None  #: the logs and their segments
    rival: Any = None  #: the equation-error estimate (``identification.aero.equation_error.EquationErrorResult``)
    consider: Consider | None = None  #: the fixed parameters and their effect on the bounds
    #: per model state, the std of the segments' start read from the log (RMS over the fit segments of each
    #: segment's, from the logged signals' noise; ``_start_consider``); {}: the starts counted as exact
    start_state_sd: dict[str, float] = field(default_factory=dict)

    @property
    def losing_outputs(self) -> list[str]:
        """Held-out outputs where a rival (persistence, segment mean) beats the model: its skill
        (``identification.common.metrics.skill_interval``) is below ``-SAME_SKILL`` (0.1 % in RMSE)."""
        return [n for n, b in self.baselines.items() if b["loses_to"]]

    @property
    def tied_outputs(self) -> list[str]:
        """Held-out outputs that lose to no rival but do not beat every one beyond noise (a skill interval
        reaches zero): not a win, and not a failure."""
        return [n for n, b in self.baselines.items() if b["ties_with"] and not b["loses_to"]]

    @property
    def estimate(self) -> Estimate:
        return self.fit.estimate

    def _main_fixed(self, names: list[str]) -> str:
        """The fixed parameters that move ``names`` most (largest |influence| x std)."""
        con = self.consider
        if con is None or not con.names:
            return "-"
        rows = [self.estimate.names.index(n) for n in names]
        share = (np.abs(con.influence[rows]) * con.sd[None, :]).max(axis=0)
        return ", ".join(con.names[j] for j in np.argsort(-share)[:3])

    def as_dict(self) -> dict[str, Any]:
        return {
            "free": self.free, "outputs": self.outputs,
            "fit_segments": [str(s) for s in self.fit_segments],
            "validation_segments": [str(s) for s in self.validation_segments],
            "start": self.start, "estimate": self.estimate.as_dict(),
            "identifiability_before": self.before.as_dict(),
            "nuisance_choice": self.nuisance_choice, "input_delay_s": self.fit.delay_s,
            "metrics": {k: {n: m.as_dict() for n, m in v.items()} for k, v in self.scores.items()},
            "failures": self.failures, "notes": self.notes,
            "baselines_validation": self.baselines, "losing_outputs": self.losing_outputs,
            "tied_outputs": self.tied_outputs,
            "quality": self.quality,
            "prior_dominated": self.estimate.prior_dominated(),
            "not_data_dominated": self.estimate.not_data_dominated(),
            "considered_fixed": self.estimate.considered,
            "start_state_sd": self.start_state_sd,
            "equation_error": self.rival.as_dict() if self.rival is not None else None,
        }

    def summary(self) -> str:
        est = self.estimate
        lines = [f"log: {line}" for line in (self.quality or {}).get("lines", [])]
        lines += ["identifiability before the solve:", *("  " + x for x in self.before.lines()), "", est.table()]
        if not est.converged:
            lines.append("NOT CONVERGED within max_iter; the estimates are the last accepted iterate")
        lines.append(f"nuisance: {self.nuisance_choice}; command -> surface delay {self.fit.delay_s * 1e3:.0f} ms"
                     + (f" (scanned {self.delay_range_s[0] * 1e3:.0f}..{self.delay_range_s[1] * 1e3:.0f} ms; negative:"
                        " the surfaces moved before the logged command)" if self.delay_range_s else ""))
        if self.scores:
            lines.append(f"{'output':<22} " + " ".join(f"{'Theil U ' + k:>20}" for k in self.scores))
            for name in next(iter(self.scores.values())):
                lines.append(f"{name:<22} " + " ".join(f"{self.scores[k][name].theil_u:>20.3f}" for k in self.scores))
        for n, b in self.baselines.items():
            verdicts = ", ".join(f"{k} {v['outcome']} (skill {v['skill']:+.2f} [{v['skill_lo']:+.2f}, "
                                 f"{v['skill_hi']:+.2f}])" for k, v in b["skill"].items())
            word = "LOSES" if b["loses_to"] else ("ties (not a win)" if b["ties_with"] else "beats")
            lines.append(f"held-out {n}: {word} - against {verdicts}")
        if self.rival is not None:
            lines += ["", *self.rival.beside(self.estimate)]
        dominated, joint = self.estimate.prior_dominated(), self.estimate.not_data_dominated()
        if dominated:
            lines.append(f"only the prior determines {', '.join(dominated)}: the data do not (posterior std without "
                         "the consider share above 0.8 of the prior's); add manoeuvres that excite them")
        fixed = [n for n, d in zip(self.estimate.names, self.estimate.dominance(), strict=False) if d == "fixed"]
        if fixed:
            lines.append(f"the values held fixed determine {', '.join(fixed)} more than the data do (consider share "
                         f"above the data's std; mainly {self._main_fixed(fixed)}): free those or give priors")
        joint = [n for n in joint if n not in dominated and n not in fixed]
        if joint:
            lines.append(f"the prior co-determines {', '.join(joint)} (posterior std 0.5-0.8 of the prior's): "
                         "not the data's alone")
        if self.estimate.considered:
            lines.append(f"bounds include the consider covariance of {len(self.estimate.considered)} fixed "
                         "coefficients (each at its prior std): " + ", ".join(self.estimate.considered))
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"warning: {w}" for w in est.warnings] + [f"FAILED after the solve: {f}" for f in self.failures]
        return "\n".join(lines)


class AeroInputError(ValueError):
    """Options that name unknown parameters, outputs or states, or give bad bounds."""


def _check_names(model: FixedWingModel, opt: AeroOptions) -> None:
    """Every name the options give must be known to the model (all problems in one message)."""
    bad = []
    if opt.free != "auto":
        bad += [f"parameter {n!r}" for n in opt.free if n not in model.params.index]
        bad += [f"bounds for {n!r} (not free)" for n in opt.bounds if n not in opt.free]
    bad += [f"output {n!r}" for n in opt.outputs if n not in model.outputs.index]
    bad += [f"state {n!r}" for n in opt.estimate_initial if n not in model.states.index]
    bad += [f"biased output {n!r} (not fitted)" for n in opt.biases if n not in opt.outputs]
    estimated = {"given": opt.estimate_initial, "auto": AUTO_STATES}.get(opt.nuisance, ())
    bad += [f"initial-state std {n}={sd!r} (needs a state estimated per segment, with nuisance {opt.nuisance!r} "
            f"{', '.join(estimated) or 'none'}: name it in estimate_initial; and a finite std > 0)"
            for n, sd in opt.initial_sd.items() if n not in estimated or not (math.isfinite(sd) and sd > 0)]
    bad += [f"bounds {n}={lo:g}:{hi:g} (need finite lo < hi)" for n, (lo, hi) in opt.bounds.items()
            if not lo < hi]
    bad += [f"horizon {opt.horizon_s!r} s (needs {HORIZON_RANGE_S[0]:g}..{HORIZON_RANGE_S[1]:g} s)"] if not (
        HORIZON_RANGE_S[0] <= opt.horizon_s <= HORIZON_RANGE_S[1]) else []
    if len(opt.restart_horizons_s) > MAX_RESTARTS:
        bad.append(f"restart_horizons_s {tuple(opt.restart_horizons_s)} (at most {MAX_RESTARTS} restarts: each is "
                   "a whole fit)")
    bad += [f"restart horizon {h!r} s (needs {HORIZON_RANGE_S[0]:g}..{HORIZON_RANGE_S[1]:g} s)"
            for h in opt.restart_horizons_s if not HORIZON_RANGE_S[0] <= h <= HORIZON_RANGE_S[1]]
    if bad:
        raise AeroInputError(f"not known to the fixed-wing model or not valid: {', '.join(bad)}")


def _weight(sigma: dict[str, float] | None, outputs: list[str]) -> np.ndarray | None:
    """``sigma`` per output into W = B^-1 (paper 001 eq. 9)."""
    if not sigma:
        return None
    if set(sigma) != set(outputs) or not all(v > 0 and math.isfinite(v) for v in sigma.values()):
        raise ValueError(f"sigma needs a positive value for each fitted output ({', '.join(outputs)}), got {sigma}")
    return np.diag([1.0 / sigma[n] ** 2 for n in outputs])


@dataclass
class AeroSource:
    """One log with its PWM mapping and, optionally, its timeline file or hand-given segments."""

    log: FlightLog
    mapping: PwmMapping
    timeline: Path | None = None
    segments: Sequence[aero.Segment] | None = None
    validate_segments: Sequence[aero.Segment] | None = None


@dataclass
class Pool:
    """The segments of every log: ``fit`` and ``val`` as (log index, segment), grouped by log."""

    sources: list[AeroSource]
    fit: list[tuple[int, aero.Segment]]
    val: list[tuple[int, aero.Segment]]
    clocks: list[LoopClock | None] = field(default_factory=list)  #: each log's loop ticks (None: not used)

    def label(self, k: int, seg: aero.Segment) -> str:
        return str(seg) if len(self.sources) == 1 else f"log{k + 1}@{seg}"

    def manoeuvres(self, model: FixedWingModel, p: np.ndarray, items: list[tuple[int, aero.Segment]],
                   outputs: Sequence[str], rate_hz: float, delay_s: float = 0.0) -> list[Manoeuvre]:
        out = []
        for k, src in enumerate(self.sources):
            segs = [s for i, s in items if i == k]
            if segs:
                clock = self.clocks[k] if k < len(self.clocks) else None
                out += aero.manoeuvres(model, p, src.log, src.mapping, segs, outputs, rate_hz, delay_s, clock)
        return out


def _source_segments(src: AeroSource, model: FixedWingModel, opt: AeroOptions, notes: list[str]
                     ) -> tuple[list[aero.Segment], list[aero.Segment]]:
    """Fit and held-out segments of one log: given, from its timeline, from input activity, else windows."""
    log = src.log
    if src.segments:
        return list(src.segments), list(src.validate_segments or [])
    name = Path(log.source).name
    timeline = src.timeline or aero_segments.timeline_beside(Path(log.source))
    if timeline is not None:
        tl, extra = aero_segments.planned_on_log(aero_segments.load_timeline_blocks(timeline), log)
        fit, val, more = aero_segments.timeline_segments(tl, log.duration_s)
        notes += [*extra, *more, f"{name}: {len(fit)} fit and {len(val)} held-out segments from the "
                  f"timeline {timeline.name}"]
        return fit, list(src.validate_segments or val)
    flown = aero_segments.flown_blocks(log)
    if flown is not None:
        tl, blocks = flown
        fit, val, more = aero_segments.timeline_segments(tl, log.duration_s)
        role = {**{(s.t0_s, s.t1_s): "fit" for s in fit}, **{(s.t0_s, s.t1_s): "held out" for s in val}}
        notes += [*more, f"{name}: {len(blocks)} blocks found in the log ({blocks[0].source}); "
                  f"{len(fit)} fit, {len(val)} held out"]
        for b, tb in zip(blocks, tl.blocks, strict=True):
            seg = aero.Segment(round(max(tb.start_s, 0.0), 3),
                               round(min(tb.end_s + aero_segments.TAIL_S, log.duration_s), 3))
            notes.append(f"  {b.line()} -> {role.get((seg.t0_s, seg.t1_s), 'skipped')} {seg}")
        return fit, list(src.validate_segments or val)
    t = np.arange(0.0, log.duration_s, 0.04)
    surfaces = [n for n in model.inputs.index if n != "throttle"]
    u = aero.log_inputs(model, log, src.mapping, t)[:, [list(model.inputs.index).index(n) for n in surfaces]]
    active = aero_segments.active_segments(t, u, aero_segments.airborne(log, t))
    if len(active) >= 2:
        notes.append(f"{Path(log.source).name}: {len(active)} segments where a control surface moves (no "
                     "timeline); every third held out")
        return [s for i, s in enumerate(active) if i % 3 != 1], list(src.validate_segments or active[1::3])
    fit, val = aero_segments.fallback_windows(log, opt.window_s)
    notes.append(f"{Path(log.source).name}: no manoeuvre found in the inputs; alternating {opt.window_s:g} s "
                 "airborne windows")
    return fit, list(src.validate_segments or val)


def _pool(sources: list[AeroSource], model: FixedWingModel, opt: AeroOptions, notes: list[str]) -> Pool:
    fit, val = [], []
    for k, src in enumerate(sources):
        f, v = _source_segments(src, model, opt, notes)
        f, cut = aero_segments.airborne_parts(src.log, f)
        v, cut_v = aero_segments.airborne_parts(src.log, v)
        notes += cut + cut_v
        fit += [(k, s) for s in f]
        val += [(k, s) for s in v]
    if not fit:
        raise aero.SegmentError(f"no fit segment left: none is airborne for {aero_segments.MIN_AIRBORNE_S:g} s "
                                f"({'; '.join(notes[-3:])})")
    return Pool(sources, fit, val)


def _estimator(model: FixedWingModel, p: np.ndarray, free: list[str], opt: AeroOptions, states: Sequence[str],
               biases: Sequence[str]) -> OutputErrorEstimator:
    constraints = []
    if opt.stability_constraints:
        for name, sign in STABILITY_SIGNS.items():
            if name in free:
                constraints.append(lambda th, n=name, s=sign: s * th[n] > 0)
    return OutputErrorEstimator(model, p, free, list(opt.outputs), bounds=opt.bounds, constraints=constraints,
                                estimate_states=list(states), estimate_biases=list(biases),
                                output_filters={n: fc for n, fc in (opt.sensor_filters or {}).items()
                                                if n in opt.outputs},
                                prior={n: (v.value, v.sd) for n, v in _priors(model, free, opt).items()},
                                bound=opt.bound, initial_sd={n: sd for n, sd in opt.initial_sd.items() if n in states})


def _priors(model: FixedWingModel, free: Sequence[str], opt: AeroOptions) -> dict[str, Prior]:
    """Priors of the free parameters: the user's, else the geometry estimate (``opt.priors == "geometry"``),
    else, with ``free="auto"``, the start value with the spread a fixed parameter gets."""
    start = dict(zip(model.params.index, model.params.starts(), strict=True))
    known = dict(geometry_priors(start)) if opt.priors == "geometry" else {}
    known.update(opt.prior_values)
    out = {n: known[n] for n in free if n in known}
    if opt.free == "auto":
        out.update({n: Prior(float(start[n]), fixed_sd(n, float(start[n])), "start value")
                    for n in free if n not in out})
    return out


def _considered(model: FixedWingModel, free: Sequence[str], opt: AeroOptions) -> dict[str, float]:
    """The fixed aerodynamic coefficients and the std each is given (its prior's, else :func:`fixed_sd`)."""
    if not opt.consider:
        return {}
    start = dict(zip(model.params.index, model.params.starts(), strict=True))
    known = dict(geometry_priors(start)) if opt.priors == "geometry" else {}
    known.update(opt.prior_values)
    return {n: known[n].sd if n in known else fixed_sd(n, float(start[n])) for n in CONSIDERED
            if n not in free and n in start}


def _aic(est: Estimate, data: list[Manoeuvre]) -> float:
    """Akaike criterion of an ML output-error fit: ``n ln det R + 2 k`` (R the residual covariance)."""
    n = sum(m.y.shape[0] for m in data)
    sign, logdet = np.linalg.slogdet(est.residual_cov)
    return float(n * logdet + 2 * len(est.values)) if sign > 0 else float("inf")


#: most continuation restarts (``AeroOptions.restart_horizons_s``): each is a whole cold fit
MAX_RESTARTS = 4
#: criterion spread over the restarts above which the notes say the cost has several minima (an AIC
#: difference of 10: one fit is e^5 ~ 150 times less likely)
RESTART_SPREAD = 10.0
#: criterion difference below which a restart is no better than the first schedule's fit (an AIC difference
#: below 2 is no evidence for one model over another; Burnham & Anderson)
RESTART_TIE = 2.0


def _criterion(fit: Fit) -> float:
    """What a cold fit's restarts are compared by: the Akaike criterion ``n ln det R + 2 k`` (equal ``k``) plus
    twice the prior term, i.e. twice the negative log posterior of the ML output-error fit up to constants."""
    return fit.aic + 2.0 * fit.oe.prior_cost(fit.estimate.values, fit.data)


def _cold_fit(oe: OutputErrorEstimator, data: list[Manoeuvre], opt: AeroOptions, weight: np.ndarray | None,
              notes: list[str]) -> Fit:
    """A fit from the start values with ``opt.horizon_s``'s continuation, restarted with every schedule of
    ``opt.restart_horizons_s``; kept: the lowest :func:`_criterion` (a fit stopped at ``max_iter`` included: a lower
    criterion is a better point whether or not it converged; the warm refits go on from it), the first schedule's
    unless another is lower by more than :data:`RESTART_TIE`. The first schedule's errors propagate (the caller's
    fallbacks handle them); a restart that fails is named and skipped."""
    first = _fit(oe, data, opt, weight)
    fits = [(opt.horizon_s, first)]
    for h in dict.fromkeys(opt.restart_horizons_s):
        if h == opt.horizon_s:
            continue
        try:
            fits.append((h, _fit(oe, data, dataclasses.replace(opt, horizon_s=h), weight)))
        except EstimationError as err:
            notes.append(f"output-error restart with {h:g} s continuation spans failed ({err}); not compared")
    if len(fits) == 1:
        return first
    crit = {h: _criterion(f) for h, f in fits}
    kept, best = min(fits, key=lambda hf: crit[hf[0]])
    if crit[opt.horizon_s] <= crit[kept] + RESTART_TIE:
        kept, best = opt.horizon_s, first  # the same minimum, or one no better: the first schedule's fit
    lo = min(crit.values())
    spread = max(crit.values()) - lo
    text = [f"{h:g} s spans {crit[h] - lo:+.0f}{'' if f.estimate.converged else ' (not converged)'}" for h, f in fits]
    notes.append("output-error restarts from the start values, criterion n ln det R + 2 k + prior above the "
                 f"lowest: {'; '.join(text)}; kept the "
                 f"{kept:g} s spans" + ("" if spread < RESTART_SPREAD else
                                        "; the cost has several minima from this start, and a start nearer the "
                                        "aircraft (identify aero --init, an identified parameter file) may find "
                                        "a lower one"))
    return best


def _fit(oe: OutputErrorEstimator, data: list[Manoeuvre], opt: AeroOptions, weight: np.ndarray | None,
         delay_s: float = 0.0, warm: bool = False) -> Fit:
    """One output-error fit from ``oe``'s nominal values; ``warm``: they are a converged estimate (a refit with
    more parameters free), so the whole records are fitted at once: the continuation in record length is for
    cold starts, and its short spans, where the added freedom is barely informed, can lead a warm start away
    into another minimum."""
    est = oe.estimate(data, weight=weight, max_iter=opt.max_iter, progress=opt.progress,
                      horizon_s=None if warm else opt.horizon_s)
    return Fit(oe, data, est, _aic(est, data), delay_s)


def _choose_free(model: FixedWingModel, p: np.ndarray, data: list[Manoeuvre], opt: AeroOptions) -> list[str]:
    """``free="auto"``: every primary derivative, and :data:`TRIM_OFFSETS` when a fitted output sees the pitch
    axis (the priors keep the ones the data leave open in place, and the summary names them); the fixed
    parameters that matter are freed after the first fit."""
    pitch_seen = any(n in PITCH_OUTPUTS for n in opt.outputs)
    return [n for n in (*PRIMARY, *(TRIM_OFFSETS if pitch_seen else ())) if n in model.params.index]


def _given_text(opt: AeroOptions) -> str:
    """The nuisance set given by hand, with the std of each initial state whose logged start is its measurement."""
    states = [f"{n} (logged start +- {opt.initial_sd[n]:g})" if n in opt.initial_sd else n
              for n in opt.estimate_initial]
    return f"given: per-segment initial {', '.join(states) or 'none'}; biases of {', '.join(opt.biases) or 'none'}"


def _nuisance_fits(model: FixedWingModel, p: np.ndarray, free: list[str], data: list[Manoeuvre],
                   opt: AeroOptions, weight: np.ndarray | None) -> tuple[Fit, str, list[str]]:
    """The fit with the nuisance set of ``opt.nuisance``; "auto" keeps the lower Akaike criterion."""
    notes: list[str] = []
    if opt.nuisance == "given":
        return _cold_fit(_estimator(model, p, free, opt, opt.estimate_initial, opt.biases), data, opt, weight,
                         notes), _given_text(opt), notes
    plain = _cold_fit(_estimator(model, p, free, opt, (), ()), data, opt, weight, notes)
    if opt.nuisance == "none":
        return plain, "none", notes
    biases = [b for b in AUTO_BIASES if b in opt.outputs]
    # the richer, nested model starts at the plain fit's optimum (its nuisance parameters at the logged initial
    # rates and zero biases) over the whole records: it can only lower the cost from there, and does not walk
    # the short continuation spans, where the per-segment freedom can lead the derivatives into another minimum
    warm = p.copy()
    warm[plain.oe.i_free] = plain.estimate.values[:plain.estimate.n_global]
    try:
        rich = _fit(_estimator(model, warm, free, opt, AUTO_STATES, biases), data, opt, weight, warm=True)
    except EstimationError as err:
        notes.append(f"per-segment initial rates and biases not estimable ({err}); fitted without")
        return plain, "none", notes
    if rich.estimate.unbounded and not plain.estimate.unbounded:
        return plain, "none (with per-segment states and biases the fitted model runs away in " \
            f"{', '.join(rich.estimate.unbounded)})", notes
    confounded = [f"{a}~{b}" for a, b, _ in (rich.estimate.identifiability.pairs
                                              if rich.estimate.identifiability else []) if "." in a + b]
    if confounded:
        return plain, f"none (per-segment states and biases are confounded with derivatives: " \
            f"{', '.join(confounded[:4])}{' ...' if len(confounded) > 4 else ''})", notes
    if rich.aic < plain.aic:
        priors = "".join(f"; {n} with its logged start +- {sd:g}" for n, sd in opt.initial_sd.items())
        return rich, f"per-segment initial rates and biases of {', '.join(biases)} (AIC {rich.aic:.0f} < " \
            f"{plain.aic:.0f} without{priors})", notes
    return plain, f"none (per-segment states and biases did not lower the AIC: {rich.aic:.0f} >= {plain.aic:.0f})", \
        notes


#: most profiled Gauss-Newton steps (the unlogged commands re-estimated after each) after the fit
UNLOGGED_ROUNDS = 8


def _refine_unlogged(model: FixedWingModel, pool: Pool, fit: Fit, opt: AeroOptions, weight: np.ndarray | None,
                     notes: list[str]) -> Fit:
    """The fit with the commands of the unlogged loops estimated (``AeroOptions.estimate_unlogged``); the fit as
    it was, with a note, when a log has no loop ticks."""
    brackets = []
    for k, src in enumerate(pool.sources):
        segs = [s for i, s in pool.fit if i == k]
        clock = pool.clocks[k] if k < len(pool.clocks) else None
        if segs and clock is None:
            notes.append("measurement chain: unlogged commands not estimated: no loop ticks (needs --loop-ticks "
                         "and a log with SCHED_LOOP_RATE and the gyro logged once per loop)")
            return fit
        brackets += aero.unlogged_brackets(model, src.log, src.mapping, segs, clock, fit.delay_s) if segs else []
    if [b.before.shape for b in brackets] != [m.u.shape for m in fit.data]:
        notes.append("measurement chain: unlogged commands not estimated: the fit grid is not the loop ticks")
        return fit
    est, data = fit_with_unlogged(fit.oe, fit.data, brackets, weight, rounds=UNLOGGED_ROUNDS, start=fit.estimate,
                                  max_iter=opt.max_iter, horizon_s=None)
    n = sum(len(b.free()) for b in brackets)
    notes.append(f"measurement chain: {n} unlogged loop commands estimated from the response within their logged "
                 f"neighbours (with the parameters, at most {UNLOGGED_ROUNDS} profiled steps; the printed bound "
                 "does not include their uncertainty)")
    return Fit(fit.oe, data, est, _aic(est, data), fit.delay_s)


def _delay(model: FixedWingModel, p: np.ndarray, pool: Pool, fit: Fit, opt: AeroOptions,
           weight: np.ndarray | None, notes: list[str]) -> Fit:
    """Scan command -> surface delays of whole samples (a short refit from the estimate at each). The data
    support a delay when the Akaike criterion has an interior minimum below the no-delay fit by more than 2
    (one more parameter) and the refit makes no derivatives inseparable; a criterion still falling at
    ``max_delay_s`` means the lag trades against the dynamics (closed-loop data): no delay is kept."""
    steps = round(opt.max_delay_s * opt.rate_hz)
    lowest = -round(-(opt.min_delay_s or 0.0) * opt.rate_hz)
    if steps < 1 and lowest > -1:
        return fit
    oe, theta = fit.oe, fit.estimate.values
    trials: list[Fit | None] = [fit]
    scanned = [d for d in range(min(lowest, 0), steps + 1) if d != 0]
    for d in scanned:
        data = pool.manoeuvres(model, p, pool.fit, opt.outputs, opt.rate_hz, d / opt.rate_hz)
        try:  # a short refit from the estimate: the no-delay estimate has absorbed part of the lag
            est = oe.estimate(data, theta0=theta, weight=weight, max_iter=6)
            trials.append(Fit(oe, data, est, _aic(est, data), d / opt.rate_hz))
        except EstimationError:
            trials.append(None)
    aic = [t.aic if t is not None else np.inf for t in trials]
    k = int(np.argmin(aic))
    if k == 0:
        return fit
    if scanned[k - 1] == steps and steps > 1:
        notes.append(f"delay not identifiable: the criterion still falls at the longest scanned delay "
                     f"({opt.max_delay_s * 1e3:.0f} ms), the lag trades against the dynamics; none kept")
        return fit
    best = trials[k]
    assert best is not None
    new = _fit(oe, best.data, opt, weight, best.delay_s)
    new = new if new.aic <= best.aic else best
    if _new_pairs(fit.estimate, new.estimate) or not new.aic + 2.0 < fit.aic:
        return fit
    return new


def _new_pairs(before: Estimate, after: Estimate) -> list[tuple[str, str]]:
    """Correlated pairs (|r| > 0.9) of ``after`` that ``before`` did not have: a delay that trades off against
    the derivatives (closed-loop data) is not supported by the data."""
    def pairs(e: Estimate) -> set[tuple[str, str]]:
        return {(a, b) for a, b, _ in (e.identifiability.pairs if e.identifiability else [])}
    return sorted(pairs(after) - pairs(before))


def identify_aero(log: FlightLog | Sequence[AeroSource], mapping: PwmMapping | None, init: FixedWingParams,
                 opt: AeroOptions) -> AeroResult:
    """Estimate the derivatives from one log (``log``, ``mapping``) or several (``log`` a list of
    :class:`AeroSource`, ``mapping`` None: segments pooled, nuisance parameters per segment); raises
    ``ValueError`` subclasses (bad segments, names, ...) and ``EstimationError`` before a solve exists; failures
    after it are kept in ``AeroResult.failures``."""
    if isinstance(log, FlightLog):
        if mapping is None:
            raise AeroInputError("a single log needs its PWM mapping")
        sources = [AeroSource(log, mapping, opt.timeline, opt.segments, opt.validate_segments)]
    else:
        sources = list(log)
    if not sources:
        raise AeroInputError("no log given")
    for src in sources:
        check_quality(src.log, opt.force, opt.max_damage)  # a badly damaged log is refused unless forced
    model = FixedWingModel(init)
    _check_names(model, opt)
    notes: list[str] = []
    chains = [sensor_chain(src.log) for src in sources]
    modelled = opt.sensor_filters is None
    if opt.min_delay_s is None:
        c = chains[0]
        slow = bool(c.loop_rate_hz and c.servo_log_rate_hz and c.servo_log_rate_hz < 0.9 * c.loop_rate_hz)
        opt = dataclasses.replace(opt, min_delay_s=-1.0 / c.servo_log_rate_hz if slow else 0.0)  # type: ignore[operator]
    if opt.sensor_filters is None:
        opt = dataclasses.replace(opt, sensor_filters=chains[0].output_filters(tuple(opt.outputs)))
        if any(c.output_filters(tuple(opt.outputs)) != opt.sensor_filters for c in chains[1:]):
            notes.append("measurement chain: the logs' sensor filters differ; the first log's are modelled")
    clocks = [loop_clock(src.log) if opt.loop_ticks else None for src in sources]
    notes += [f"measurement chain: {x}" for x in chains[0].lines(modelled, clocks[0], opt.loop_ticks)]
    if opt.sensor_filters and not modelled:
        notes.append("measurement chain: sensor low-pass modelled as given: " + ", ".join(
            f"{n} {fc:g} Hz" for n, fc in opt.sensor_filters.items()))
    p = np.array(model.params.starts(), dtype=float)
    outputs = list(opt.outputs)
    weight = _weight(opt.sigma, outputs)
    pool = _pool(sources, model, opt, notes)
    pool.clocks = clocks
    data = pool.manoeuvres(model, p, pool.fit, outputs, opt.rate_hz)
    free = _choose_free(model, p, data, opt) if opt.free == "auto" else list(opt.free)
    p_default = p.copy()
    rival, used = _equation_error_start(model, p, pool, free, opt, notes)
    probe = _estimator(model, p, free, opt, (), ())
    if used and not _fits_better(probe, data, p[probe.i_free], p_default[probe.i_free], notes):
        p[:] = p_default
        probe = _estimator(model, p, free, opt, (), ())
    elif rival is not None:
        notes.append(f"output-error start from the equation-error estimate for {', '.join(used) or 'none'}")
    before = probe.identifiability(data, weight=weight)
    start = {n: float(p[i]) for n, i in zip(free, probe.i_free, strict=True)}
    try:
        fit, choice, more = _nuisance_fits(model, p, free, data, opt, weight)
    except HorizonDivergedError as err:
        length = max(err.last_ok_s, 2.0)
        pool.fit = [(k, s) for k, seg in pool.fit for s in aero_segments.split_segments([seg], length)]
        notes.append(f"{err}: fell back to fit segments of {length:g} s, each from the log's state at its start")
        data = pool.manoeuvres(model, p, pool.fit, outputs, opt.rate_hz)
        fit, choice, more = _nuisance_fits(model, p, free, data, opt, weight)
    notes += more
    if opt.estimate_unlogged:
        fit = _refine_unlogged(model, pool, fit, opt, weight, notes)
    quality = [src.log.quality.to_dict() for src in sources if getattr(src.log, "quality", None) is not None]
    result = AeroResult(free, outputs, [s for _, s in pool.fit], [s for _, s in pool.val], start, before, fit, {},
                        choice, notes=notes, quality=quality[0] if len(quality) == 1 else
                        {"logs": quality, "lines": [x for q in quality for x in q.get("lines", [])]})
    result.pool, result.rival = pool, rival
    if opt.max_delay_s > 0 or (opt.min_delay_s or 0.0) < 0:
        result.delay_range_s = (min(opt.min_delay_s or 0.0, 0.0), opt.max_delay_s)
    result.identified = {**init.to_dict(), **fit.estimate.derivatives()}
    if opt.free == "auto":
        notes.append(f"free=auto started from {', '.join(free)} (the primary derivatives"
                     f"{' and the pitch trim offset' if set(TRIM_OFFSETS) & set(free) else ''})")
    _after_fit(result, model, p, init, opt, weight)
    return result


def _after_fit(result: AeroResult, model: FixedWingModel, p: np.ndarray, init: FixedWingParams,
               opt: AeroOptions, weight: np.ndarray | None) -> None:
    """Consider covariance (and, with ``free="auto"``, freeing the fixed parameters that matter), the delay
    scan and the scores; a failure here is recorded, the estimate kept."""
    try:
        _consider(result, model, p, opt, weight)
        if opt.free == "auto":
            for _ in range(FREE_ROUNDS):
                if not _free_fixed(result, model, p, opt, weight):
                    break
        result.identified = {**init.to_dict(), **result.fit.estimate.derivatives()}
    except (ValueError, EstimationError, np.linalg.LinAlgError) as err:
        result.failures.append(f"consider covariance: {err}")
    try:
        fit = _delay(model, p, result.pool, result.fit, opt, weight, result.notes)
        if fit is not result.fit:
            fit.estimate.consider_cov, fit.estimate.considered = result.fit.estimate.consider_cov, \
                result.fit.estimate.considered
            result.fit = fit
            result.identified = {**init.to_dict(), **fit.estimate.derivatives()}
    except (ValueError, EstimationError) as err:
        result.failures.append(f"delay scan: {err}")
    if opt.start_noise:
        try:
            _start_consider(result, model, p, opt, weight)
        except (ValueError, EstimationError, np.linalg.LinAlgError) as err:
            result.failures.append(f"start-state consider covariance: {err}")
    if result.fit.estimate.unbounded:
        result.failures.append(f"bounds: the fitted model runs away in {', '.join(result.fit.estimate.unbounded)} "
                               "(output sensitivities above 1e3 x the measured range): no printed interval is "
                               "credible; fit shorter segments (--segments) or fix the derivatives of that mode")
    _score(result, model, p, opt)


def _consider(result: AeroResult, model: FixedWingModel, p: np.ndarray, opt: AeroOptions,
              weight: np.ndarray | None) -> Consider | None:
    """Put the consider covariance of the fixed coefficients into the estimate's bounds."""
    sd = _considered(model, result.free, opt)
    if not sd:
        return None
    fit = result.fit
    con = consider_covariance(fit.oe, fit.estimate, fit.data, sd, weight)
    fit.estimate.consider_cov = con.cov
    fit.estimate.considered = dict(zip(con.names, con.sd.tolist(), strict=True))
    result.consider = con
    return con


def _start_consider(result: AeroResult, model: FixedWingModel, p: np.ndarray, opt: AeroOptions,
                    weight: np.ndarray | None) -> None:
    """Put the consider covariance of the segments' logged start states into the estimate's bounds: per log the
    noise of the signals a start is read from, estimated on its fit segments (``aero.start_noise``), per fit
    segment the covariance of its start (``aero.start_covariance``), and what those do to the estimate
    (``oem.start_consider_terms``)."""
    fit, pool = result.fit, result.pool
    init = init_function(model)
    covs = []
    for k, src in enumerate(pool.sources):
        segs = [s for i, s in pool.fit if i == k]
        if not segs:
            continue
        noise = aero.start_noise(src.log, [(s.t0_s, s.t1_s) for s in segs])
        result.notes.append(f"{Path(src.log.source).name}: the noise of the logged start (robust, on the fit "
                            "segments), in the bounds: " + ", ".join(f"{n} {v:.2g}" for n, v in noise.items()))
        clock = pool.clocks[k] if k < len(pool.clocks) else None
        for seg in segs:
            t0 = float(aero.segment_grid(seg, opt.rate_hz, clock)[0])
            covs.append(aero.start_covariance(model, p, src.log, t0, fit.data[len(covs)].u[0], noise, init))
    fit.estimate.add_start(start_consider_terms(fit.oe, fit.estimate, fit.data, covs, weight))
    rms = np.sqrt(np.mean([np.diag(c) for c in covs], axis=0))
    result.start_state_sd = {n: float(rms[i]) for n, i in model.states.index.items() if rms[i] > 0.0}


def _free_fixed(result: AeroResult, model: FixedWingModel, p: np.ndarray, opt: AeroOptions,
                weight: np.ndarray | None) -> bool:
    """One round of ``free="auto"``: free the fixed parameters that matter and that the data inform, refit
    from the estimate with the same nuisance set, and recompute the consider covariance; False when none is
    worth freeing (``identify_aero`` runs up to ``oem.FREE_ROUNDS`` rounds)."""
    con: Consider | None = getattr(result, "consider", None)
    est = result.fit.estimate
    if con is None or not con.names:
        return False
    n = est.n_global
    chosen = fixed_worth_freeing(est, con)
    if not chosen:
        result.notes.append("free=auto: no (further) fixed coefficient both matters and is informed by the data")
        return False
    free = result.free + chosen
    p2 = p.copy()
    p2[result.fit.oe.i_free] = est.values[:n]
    biases = list(result.fit.oe.biases)
    dropped = [b for b in biases if opt.nuisance == "auto" and any(ZERO_FORCE_AXES.get(c) == b for c in free)]
    biases = [b for b in biases if b not in dropped]
    oe = _estimator(model, p2, free, opt, result.fit.oe.states_est, biases)
    new = _fit(oe, result.fit.data, opt, weight, result.fit.delay_s, warm=True)
    result.fit, result.free = new, free
    result.start.update({c: float(p[model.params.index[c]]) for c in chosen})
    result.notes.append(f"free=auto freed {', '.join(chosen)}: held fixed, each shifted a free derivative by more "
                        f"than {FREE_IMPACT:g} std of its data bound and the data inform it")
    if dropped:
        what = ", ".join(f"{b} ({', '.join(c for c in free if ZERO_FORCE_AXES.get(c) == b)})" for b in dropped)
        result.nuisance_choice += f"; per-segment biases of {what} dropped when freed"
        result.notes.append(f"free=auto dropped the per-segment biases of {what}: a common offset of that specific "
                            "force in every segment is the zero-order coefficient's as much as the sensor's, and a "
                            "replay without biases (validate, the FMU) needs the coefficient to carry it")
    _consider(result, model, p, opt, weight)
    return True


def _score(result: AeroResult, model: FixedWingModel, p: np.ndarray, opt: AeroOptions) -> None:
    """Fit metrics on the fitted segments (with their nuisance parameters) and held-out ones (without)."""
    fit, pool = result.fit, result.pool
    try:
        result.replay["fit"] = _replay(fit.oe, fit.estimate.values, fit.data, result.fit_segments, opt.rate_hz)
        if pool.val:
            val = pool.manoeuvres(model, p, pool.val, result.outputs, opt.rate_hz, fit.delay_s)
            theta = fit.estimate.values[:fit.estimate.n_global]
            result.replay["validation"] = _replay(fit.oe, theta, val, result.validation_segments, opt.rate_hz)
        for k, (y, m, _t) in result.replay.items():
            result.scores[k] = aero.score(y, m, result.outputs)
        if "validation" in result.replay:
            result.baselines = _baselines(result.replay["validation"], val, result.outputs)
    except (ValueError, EstimationError, FloatingPointError) as err:
        result.failures.append(f"scoring: {err}")


def _baselines(replay: tuple[np.ndarray, np.ndarray, np.ndarray], data: list[Manoeuvre], outputs: list[str]
               ) -> dict[str, dict[str, Any]]:
    """Per held-out output: RMSE of the model and of the simplest rivals, persistence (each segment's first
    measurement held) and each segment's mean, and the model's skill against each with a block-bootstrap
    interval over blocks of :data:`SKILL_BLOCK_S`; ``loses_to`` names the rivals that beat the model (skill below
    ``-SAME_SKILL``), ``ties_with`` those it beats only within noise (the interval reaches zero: not a win)."""
    y, m, _ = replay
    lengths = [d.y.shape[0] for d in data]
    cuts = np.cumsum(lengths)[:-1]
    hold = np.vstack([np.repeat(seg[:1], len(seg), axis=0) for seg in np.split(y, cuts)])
    mean = np.vstack([np.repeat(seg.mean(axis=0, keepdims=True), len(seg), axis=0) for seg in np.split(y, cuts)])
    block = max(round(SKILL_BLOCK_S / data[0].dt_s), 1)
    starts = np.unique(np.concatenate([o + np.arange(0, n, block) for o, n in zip(np.r_[0, cuts], lengths,
                                                                                    strict=True)])).astype(int)
    out = {}
    for i, n in enumerate(outputs):
        rm = {"model": float(np.sqrt(np.mean((y[:, i] - m[:, i]) ** 2))),
              "persistence": float(np.sqrt(np.mean((y[:, i] - hold[:, i]) ** 2))),
              "segment_mean": float(np.sqrt(np.mean((y[:, i] - mean[:, i]) ** 2)))}
        skill = {k: skill_interval(y[:, i], m[:, i], b[:, i], starts).as_dict()
                 for k, b in (("persistence", hold), ("segment_mean", mean))}
        out[n] = {"rmse": rm, "skill": skill, "loses_to": [k for k, v in skill.items() if v["outcome"] == "lose"],
                  "ties_with": [k for k, v in skill.items() if v["outcome"] == "tie"]}
    return out


def _replay(oe: OutputErrorEstimator, theta: np.ndarray, data: list[Manoeuvre], segs: Sequence[aero.Segment],
            rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured and simulated outputs over all segments, with their log times."""
    ys, ms, ts = [], [], []
    for j, (m, s) in enumerate(zip(data, segs, strict=True)):
        y, _, _ = oe.simulate(theta, m, j, sensitivities=False)
        ys.append(m.y)
        ms.append(y)
        ts.append(s.t0_s + np.arange(1, len(y) + 1) / rate)
    return np.vstack(ys), np.vstack(ms), np.concatenate(ts)


def write_results(result: AeroResult, out: Path, metrics: Path, log_name: str, rate_hz: float,
                  plots_dir: Path | None = None) -> None:
    """Parameter file and metrics JSON first (the estimates are never lost), then the plots."""
    from identification.common.jsonio import write_json

    est = result.estimate
    n = est.n_global
    write_json(out, {"fixed_wing": result.identified, "_identification": {
        "method": "output error (identification.estimation.oem)", "log": log_name, "free": result.free,
        "bound_method": est.bound_method + (" + consider covariance of the fixed coefficients"
                                            if est.considered else "")
        + (" + consider covariance of the logged start states" if est.start_cov is not None else ""),
        "std": {n: float(s) for n, s in zip(result.free, est.std[:n], strict=True)},
        "prior_dominated": est.prior_dominated()},
        "uncertainty": {"names": list(est.names[:n]), "mean": [float(v) for v in est.values[:n]],
                        "covariance": est.covariance_printed().tolist()}})
    write_json(metrics, {"log": log_name, "rate_hz": rate_hz, **result.as_dict()})
    if plots_dir is None:
        return
    try:
        _plots(result, plots_dir, rate_hz)
    except (OSError, ValueError, RuntimeError) as err:
        result.failures.append(f"plots: {err}")
        write_json(metrics, {"log": log_name, "rate_hz": rate_hz, **result.as_dict()})


def _record_fit(oe: OutputErrorEstimator, data: list[Manoeuvre], theta: np.ndarray) -> float:
    """``ln det R`` of the output residuals over every record (``R`` their covariance; the maximum-likelihood
    output-error criterion up to constants), ``inf`` when the model diverges in a record."""
    res = []
    for j, m in enumerate(data):
        y, _, bad = oe.simulate(theta, m, j, sensitivities=False)
        if bad:
            return math.inf
        res.append(m.y - y)
    sign, logdet = np.linalg.slogdet(np.atleast_2d(np.cov(np.vstack(res).T, bias=True)))
    return float(logdet) if sign > 0 else math.inf


def _fits_better(oe: OutputErrorEstimator, data: list[Manoeuvre], theta_ee: np.ndarray, theta_0: np.ndarray,
                 notes: list[str]) -> bool:
    """Whether the equation-error start fits the records better than the start values (:func:`_record_fit`):
    its regression is biased towards zero by errors in the regressors (input timing, filtered rates), and a start
    that fits worse can lead the output-error continuation into another minimum. A note says which start won."""
    if np.array_equal(theta_ee, theta_0):
        return True
    ee, default = _record_fit(oe, data, theta_ee), _record_fit(oe, data, theta_0)
    if ee < default:
        return True
    notes.append(f"equation-error start not used: it fits the records worse than the start values (ln det of the "
                 f"residual covariance {ee:.2f} >= {default:.2f})")
    return False


def _equation_error_start(model: FixedWingModel, p: np.ndarray, pool: Pool, free: Sequence[str],
                          opt: AeroOptions, notes: list[str]) -> tuple[Any, list[str]]:
    """The equation-error estimate (the rival) and the free derivatives whose values it wrote into ``p`` as
    start values (where they keep the stability signs and are well determined; ``identification.aero.equation_error``).
    The caller keeps them only when they fit the records better (:func:`_fits_better`) and says which it used."""
    if not opt.equation_error:
        return None, []
    from identification.aero.equation_error import EquationErrorError, equation_error

    try:
        ee = equation_error(model, p, pool.sources, pool.fit, opt.rate_hz)
    except (EquationErrorError, ValueError) as err:
        notes.append(f"equation-error start skipped: {err}")
        return None, []
    used = []
    for n in free:
        v = ee.values.get(n)
        start = float(p[model.params.index[n]])
        if v is None or not math.isfinite(v) or (opt.stability_constraints and n in STABILITY_SIGNS
                                                 and STABILITY_SIGNS[n] * v <= 0):
            continue
        if ee.std[n] > 0.5 * abs(v) or (start != 0.0 and not 0.2 < v / start < 5.0):
            continue  # poorly determined, or far from the start: the start value is the safer guess
        p[model.params.index[n]] = v
        used.append(n)
    return ee, used


def _plots(result: AeroResult, folder: Path, rate_hz: float) -> None:
    from identification.common import plots

    dt, est, outs = 1.0 / rate_hz, result.estimate, result.outputs
    for key, title in (("fit", "fit segments"), ("validation", "held-out segments")):
        if key in result.replay and key in result.scores:
            y, m, t = result.replay[key]
            plots.aero_overlay(folder / f"{key}.png", title, t, y, m, outs, dt,
                               {n: s.theil_u for n, s in result.scores[key].items()})
    if "fit" in result.replay:
        y, m, t = result.replay["fit"]
        plots.aero_residuals(folder / "residuals.png", t, y - m, outs, dt)
    n = est.n_global
    plots.aero_parameters(folder / "parameters.png", result.free, np.array(list(result.start.values())),
                          est.values[:n], est.std[:n], result.fit.oe.lower, result.fit.oe.upper)
    correlation_plot(folder / "correlation.png", est.names[:n], est.correlation[:n, :n])


def correlation_plot(path: Path, names: Sequence[str], corr: np.ndarray) -> Path:
    """The derivatives' correlation matrix as a heat map, |r| > 0.9 cells outlined."""
    from identification.common import plots

    k = len(names)
    fig, ax = plots.figure(figsize=(max(4.0, 0.5 * k + 2.5), max(3.5, 0.5 * k + 2.0)))
    im = ax.imshow(corr, vmin=-1.0, vmax=1.0, cmap="RdBu_r")
    ax.set_xticks(range(k), names, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(k), names, fontsize=7)
    for i in range(k):
        for j in range(k):
            if i != j and abs(corr[i, j]) > 0.9:
                ax.add_patch(plots.plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=2, ec="k"))
            ax.text(j, i, f"{corr[i, j]:.2f}", ha="center", va="center", fontsize=6)
    fig.colorbar(im, ax=ax, label="correlation (|r| > 0.9 outlined)")
    ax.set_title("parameter correlation (from the information matrix)")
    return plots.save(fig, path)

"""``identify quadrotor`` as a library: a quadrotor's rate and force dynamics from logs by output error.

:func:`identify_quadrotor` takes read logs, the start parameters (the thrust map of ``identify thrust``'s file,
or the FMU defaults) and :class:`QuadrotorOptions`, and returns a :class:`QuadrotorIdResult`. The estimator is
``identification.estimation.oem`` on the quadrotor model of ``fmu_models.quadrotor`` (the FMU's equations):
outputs body rates and specific force, inputs the four motor PWMs (and battery voltage where logged), free
``Jx_kg_m2``, ``Jy_kg_m2`` (the arm's moment effectiveness ``l/J`` with the arm length of the file),
``tau_motor_s``, ``b_drag_N_m_s2`` with ``Jz_kg_m2`` (the data fix ``(b/k)/Jz``; the airframe prior fixes
``Jz``) and, where the log has velocity, ``kd_x/y/z_N_s_m``; per window the initial body rates and the
gyro and accelerometer biases. Method and references: readme.md.

A log whose motor commands are logged slower than :data:`MIN_COMMAND_HZ` cannot show the rate dynamics (the
motors change many times between two logged commands): the result says which parameters it cannot determine
and why, keeps them at their start values, and estimates drag from the specific force and the logged velocity
(equation error: ``a_body = -kd v_body / m + bias``).
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
from fmu_models.common.params import Uncertainty
from fmu_models.quadrotor.constants import MOTOR_LAG_SETTLE_TAUS, N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import command, consequent_parameters, constants_of, motor_out_of_band, motor_thrust
from fmu_models.signals.names import OUTPUT_TO_LOG
from identification.common.metrics import skill_interval
from identification.estimation.least_squares import hac_least_squares
from identification.estimation.oem import (
    Estimate,
    EstimationError,
    Manoeuvre,
    OutputErrorEstimator,
    student_factor,
)
from identification.logs.flightlog import BATTERY_VOLTAGE, FlightLog, LogError, check_quality
from identification.logs.log_state import (
    BODY_VELOCITY_SIGNALS,
    HOLD_TOLERANCE_S,
    body_velocity,
    hold,
    initial_values,
)
from identification.quadrotor import rate_commands
from identification.quadrotor import segments as qseg
from identification.quadrotor.motor_lag import ExactLagModel
from identification.quadrotor.priors import BATTERY_MASS_KG, MOTOR_MASS_KG, InertiaPrior, airframe_inertia

#: fitted outputs: body rates (gyro) and specific force (accelerometer)
RATE_OUTPUTS = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")
FORCE_OUTPUTS = ("accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2")
#: the rate-dynamics parameters and the drag
RATE_PARAMS = ("Jx_kg_m2", "Jy_kg_m2", "Jz_kg_m2", "b_drag_N_m_s2", "tau_motor_s")
DRAG_PARAMS = ("kd_x_N_s_m", "kd_y_N_s_m", "kd_z_N_s_m")
#: slowest logged motor command rate [Hz] at which the rate dynamics are fitted: a quadrotor's rate loop acts
#: within 20-50 ms (rate-loop bandwidth 5-15 Hz, motor time constants 10-50 ms); commands logged slower than this
#: leave the moments between two samples unknown
MIN_COMMAND_HZ = 50.0
#: search bounds of the free parameters (SI); the motor time constant is kept above 0.1 ms (at 0 the model
#: switches the lag off and the sensitivity vanishes; the exact discretisation of ``motor_lag`` is stable at any
#: value)
BOUNDS = {"Jx_kg_m2": (1e-5, 10.0), "Jy_kg_m2": (1e-5, 10.0), "Jz_kg_m2": (1e-5, 10.0),
          "b_drag_N_m_s2": (1e-12, 1e-3), "tau_motor_s": (1e-4, 0.3),
          "kd_x_N_s_m": (0.0, 100.0), "kd_y_N_s_m": (0.0, 100.0), "kd_z_N_s_m": (0.0, 100.0)}
#: fewest degrees of freedom of the segment bootstrap for it to widen a printed bound: the replica's roll and
#: pitch information sits in a few windows (2 degrees of freedom), where the bootstrap's spread is itself
#: uncertain by half and Student's factor doubles it (95 % half-widths 5-10x the error); with 10 its spread is
#: known to about a fifth and the factor is 1.14. Below it the coloured-residual Cramer-Rao bound is printed and
#: the bootstrap is reported as a small-sample bound with the windows that would give it 10.
BOOTSTRAP_MIN_DOF = 10.0
#: smallest internal step [s] the written file gives the FMU (``step_internal_s``' own lower limit); a motor time
#: constant under twice the file's step brings it down to half the time constant
FMU_STEP_MIN_S = 1e-5
#: motor time constant the fit starts from when the start parameters have none [s]
TAU_START_S = 0.02
#: share of the fit windows' motor samples (above idle) outside the thrust map's trained band above which the result
#: warns that the inertia and the motor lag inherit the error of the map's extrapolated slope
BAND_WARN_SHARE = 0.01
#: the inertias whose estimate scales one for one with the thrust map's slope: their moment is ``l dT/dPWM`` at the
#: motors' commands, and the body rates fix only that moment over the inertia (a map whose slope is s times too
#: low gives these inertias s times too low: ``bench/quadrotor_demo_map.py``)
SLOPE_PARAMS = ("Jx_kg_m2", "Jy_kg_m2")
#: distance of the flight's thrust scale from 1, in its standard errors, past which the flight shows the map's slope
#: off (a right map's scale is past it in 0.27 % of flights, the scale being normal): then the intervals of
#: :data:`SLOPE_PARAMS` carry the slope's error
SLOPE_SHOWN_Z = 3.0
#: exit status of ``uavfmu identify quadrotor`` (documented in the CLI module)
EXIT_OK, EXIT_BAD_INPUT, EXIT_FAILED, EXIT_LOSES, EXIT_LATE_FAILURE, EXIT_NOT_IDENTIFIABLE = 0, 2, 3, 4, 5, 6


class QuadrotorInputError(ValueError):
    """Options or logs that cannot be identified from (named with their values)."""


@dataclass(frozen=True)
class QuadrotorOptions:
    """What to fit and how (times [s], rates [Hz], masses [kg])."""

    rate_hz: float = 250.0  #: output-error sample rate (capped at the log's motor command rate)
    window_s: float = 1.0  #: each fit window is replayed from the log's state at its start
    segments: Sequence[qseg.Segment] | None = None  #: explicit segments (else the blocks file, else airborne)
    blocks: Path | None = None  #: blocks file of a single log (else ``NAME.blocks.json`` beside it)
    hold_out_every: int = 3  #: every n-th segment held out for scoring (0: none)
    score_window_s: float = 0.5  #: held-out replays restart from the logged state this often
    motor_mass_kg: float = MOTOR_MASS_KG
    battery_mass_kg: float = BATTERY_MASS_KG
    max_iter: int = 25
    progress: bool = False
    force: bool = False  #: use a log whose damage exceeds the quality limit

    def problems(self) -> list[str]:
        out = []
        for name, lo, hi in (("rate_hz", 10.0, 1000.0), ("window_s", 0.2, 10.0), ("score_window_s", 0.1, 5.0),
                             ("max_iter", 1, 200), ("hold_out_every", 0, 100)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and lo <= v <= hi):
                out.append(f"{name} = {v!r} (allowed {lo:g}..{hi:g})")
        return out


@dataclass
class Ratio:
    """A combination the data determine, with its 1-sigma bound and what it means."""

    name: str
    value: float
    std: float
    unit: str
    meaning: str

    def as_dict(self) -> dict[str, Any]:
        return {"value": self.value, "std": self.std, "ci95": [self.value - 1.96 * self.std,
                                                              self.value + 1.96 * self.std],
                "unit": self.unit, "meaning": self.meaning}


@dataclass
class QuadrotorIdResult:
    """Everything ``identify quadrotor`` found; ``as_dict()`` is the metrics JSON."""

    params: QuadrotorParams  #: the start parameters with the estimates written in
    free: list[str]
    estimate: Estimate | None
    prior: InertiaPrior
    fit_segments: list[qseg.Segment]
    held_out_segments: list[qseg.Segment]
    command_hz: float
    not_identifiable: dict[str, str] = field(default_factory=dict)  #: parameter -> why this log cannot say
    ratios: list[Ratio] = field(default_factory=list)
    drag: dict[str, dict[str, float]] = field(default_factory=dict)  #: equation-error drag (slow commands)
    held_out: dict[str, dict[str, Any]] = field(default_factory=dict)  #: output -> skill against persistence
    notes: list[str] = field(default_factory=list)
    thrust_band: dict[str, Any] = field(default_factory=dict)  #: :func:`thrust_band_coverage` of the fit windows
    failures: list[str] = field(default_factory=list)
    #: :func:`thrust_slope_check` on the fit windows with the estimates (empty without velocity or a fit)
    thrust_slope: dict[str, Any] = field(default_factory=dict)
    #: :func:`map_slope_share` of the start file's thrust-map covariance (empty without one)
    map_slope: dict[str, Any] = field(default_factory=dict)

    def slope_share(self) -> tuple[float, str]:
        """The relative 1-sigma error of the thrust map's slope that the inertias of :data:`SLOPE_PARAMS` carry
        beside the data's bound, and what it is: where this flight shows the slope off, the thrust slope check's
        (it measures the whole error there) or the start file's map covariance's, whichever is larger; else the
        map covariance's; else none (0)."""
        cov = self.map_slope.get("relative_sd", 0.0)
        cov_why = f"the thrust map's slope ({100 * cov:.1f} % from the start file's covariance of its consequents)"
        if self.thrust_slope.get("shown") and self.thrust_slope["relative_sd"] >= cov:
            return self.thrust_slope["relative_sd"], (
                f"the thrust map's slope (off by {100 * (self.thrust_slope['scale'] - 1):+.1f} % on this flight's "
                "vertical specific force)")
        return (cov, cov_why) if cov > 0.0 else (0.0, "")

    @property
    def losing_outputs(self) -> list[str]:
        return [n for n, s in self.held_out.items() if s["outcome"] == "lose"]

    @property
    def exit_code(self) -> int:
        """0 identified and not beaten; 4 persistence beats the model on a held-out output; 5 a step after the
        solve (held-out scoring) failed; 6 parameters this log cannot determine (what it could was identified)."""
        if self.losing_outputs:
            return EXIT_LOSES
        if self.failures:
            return EXIT_LATE_FAILURE
        return EXIT_NOT_IDENTIFIABLE if self.not_identifiable else EXIT_OK

    def estimates(self) -> dict[str, dict[str, Any]]:
        """Every estimated model parameter: value, 1-sigma, 95 % interval and what determined it."""
        out: dict[str, dict[str, Any]] = {}
        est = self.estimate
        if est is not None:
            std, dom = est.std, est.dominance()
            rel, why = self.slope_share()
            for i, n in enumerate(est.names[:est.n_global]):
                v, sd = float(est.values[i]), float(std[i])
                out[n] = {"value": v, "std": sd, "determined_by": _determined(n, dom[i])}
                if rel > 0.0 and n in SLOPE_PARAMS:  # the map's slope error, which the data's bound does not carry
                    share = abs(v) * rel
                    out[n].update(std=math.hypot(sd, share), std_data=sd, std_thrust_slope=share)
                    out[n]["determined_by"] += f" + {why}"
                out[n]["ci95"] = [v - 1.96 * out[n]["std"], v + 1.96 * out[n]["std"]]
        for n, d in self.drag.items():
            out[n] = {**d, "ci95": [d["value"] - 1.96 * d["std"], d["value"] + 1.96 * d["std"]],
                      "determined_by": "data (equation error on velocity and specific force)"}
        return out

    def small_sample_bounds(self) -> dict[str, dict[str, float]]:
        """Model parameters whose segment bootstrap has fewer than :data:`BOOTSTRAP_MIN_DOF` degrees of freedom
        (left out of the printed bound): its 1-sigma with Student's factor, its degrees of freedom and about how
        many fit windows, sharing the information as these do, would give it :data:`BOOTSTRAP_MIN_DOF`."""
        est = self.estimate
        if est is None or est.bootstrap_std is None:
            return {}
        dof, used = est.bootstrap_dofs(), est.bootstrap_in_bound()
        out = {}
        for i, n in enumerate(est.names[:est.n_global]):
            if not used[i] and np.isfinite(est.bootstrap_std[i]):
                out[n] = {"std_t": float(est.bootstrap_std[i] * student_factor(dof[i])), "dof": float(dof[i]),
                          "windows_needed": math.ceil(est.n_segments * BOOTSTRAP_MIN_DOF / max(dof[i], 1e-3))}
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "free": self.free, "command_hz": self.command_hz, "estimates": self.estimates(),
            "small_sample_bounds": self.small_sample_bounds(),
            "ratios": {r.name: r.as_dict() for r in self.ratios},
            "not_identifiable": self.not_identifiable, "inertia_prior": dataclasses.asdict(self.prior),
            "fit_segments": [str(s) for s in self.fit_segments],
            "held_out_segments": [str(s) for s in self.held_out_segments],
            "held_out_vs_persistence": self.held_out, "losing_outputs": self.losing_outputs,
            "estimate": self.estimate.as_dict() if self.estimate is not None else None,
            "thrust_map_band": self.thrust_band, "thrust_slope": self.thrust_slope,
            "thrust_map_slope_covariance": self.map_slope, "notes": self.notes,
            "failures": self.failures,
            "exit_code": self.exit_code,
        }

    def summary(self) -> str:
        lines = [f"motor commands logged at {self.command_hz:.0f} Hz; {len(self.fit_segments)} fit windows, "
                 f"{len(self.held_out_segments)} held-out windows", f"inertia prior: {self.prior.source}"]
        if self.thrust_band:
            lines.append(self.thrust_band["text"])
        if self.thrust_slope:
            lines.append(self.thrust_slope["text"])
        if self.map_slope:
            lines.append(self.map_slope["text"])
        lines.append(f"{'parameter':<16} {'estimate':>11} {'95 % interval':>25}  determined by")
        for n, e in self.estimates().items():
            lo, hi = e["ci95"]
            lines.append(f"{n:<16} {e['value']:11.4g} {f'[{lo:.4g}, {hi:.4g}]':>25}  {e['determined_by']}")
        small = self.small_sample_bounds()
        if small:
            lines.append(f"printed bounds: coloured-residual Cramer-Rao; the segment bootstrap over the "
                         f"{self.estimate.n_segments if self.estimate else 0} fit windows has fewer than "
                         f"{BOOTSTRAP_MIN_DOF:g} degrees of freedom for these (a small-sample bound, not printed "
                         "above):")
            for n, b in small.items():
                lines.append(f"  {n:<14} 95 % half-width {1.96 * b['std_t']:.3g} from {b['dof']:.1f} degrees of "
                             f"freedom; about {b['windows_needed']} fit windows like these would give it "
                             f"{BOOTSTRAP_MIN_DOF:g}")
        for r in self.ratios:
            lines.append(f"{r.name:<16} {r.value:11.4g} "
                         f"{f'[{r.value - 1.96 * r.std:.4g}, {r.value + 1.96 * r.std:.4g}]':>25}  data: {r.meaning}")
        for why in dict.fromkeys(self.not_identifiable.values()):
            names = [n for n, w in self.not_identifiable.items() if w == why]
            kept = ", ".join(f"{n} = {getattr(self.params, n):.4g}" for n in names)
            lines.append(f"NOT IDENTIFIABLE from this log: {', '.join(names)}: {why}; kept at the start values "
                         f"({kept})")
        for n, s in self.held_out.items():
            word = {"win": "beats", "lose": "LOSES to", "tie": "ties with"}.get(s["outcome"], s["outcome"])
            lines.append(f"held-out {n}: {word} persistence at {s['window_s']:g} s restarts (skill "
                         f"{s['skill']:+.2f}, 90 % interval [{s['skill_lo']:+.2f}, {s['skill_hi']:+.2f}])")
        if self.estimate is not None:
            lines += [f"warning: {w}" for w in self.estimate.warnings]
        lines += [f"note: {n}" for n in self.notes] + [f"FAILED after the solve: {f}" for f in self.failures]
        return "\n".join(lines)


def thrust_band_pwm_us(params: QuadrotorParams) -> tuple[float, float]:
    """The thrust map's trained band as per-motor PWM [us] at the nominal battery voltage (a feature map's band
    is in normalised command, a summed-PWM map's in PWM times the motor count)."""
    lo, hi = params.thrust_map.input_range[0]
    if params.thrust_map.features is not None:
        span = params.pwm_full_us - params.pwm_idle_us
        return params.pwm_idle_us + lo * span, params.pwm_idle_us + hi * span
    return lo / N_MOTORS, hi / N_MOTORS


def _window_inputs(logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]],
                   params: QuadrotorParams) -> list[np.ndarray]:
    """Per window with motor commands, the model inputs (:func:`_inputs`) at its logged command samples."""
    out = []
    for k, w in windows:
        t = logs[k].signal("motor_1_pwm_us").t_s
        t = t[(t >= w.t0_s) & (t < w.t1_s)]
        if len(t):
            out.append(_inputs(logs[k], params, t))
    return out


def thrust_band_coverage(logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]],
                         params: QuadrotorParams) -> dict[str, Any]:
    """Where the motors ran in ``windows`` against the thrust map's trained band: the band (per-motor PWM at the
    nominal voltage) [us], the flown per-motor PWM (0.5 and 99.5 %) [us], and the share of logged motor samples
    above idle outside the band (the FMU's own test, ``motor_out_of_band``, at the logged battery voltage), split
    below and above it. Outside its band the map is extrapolated, and the roll and pitch inertia, identified
    through ``l dT/dPWM`` at the motors' commands, inherit that slope's error; ``warning`` says so when the share
    exceeds :data:`BAND_WARN_SHARE`."""
    c = constants_of(params)
    lo_us, hi_us = thrust_band_pwm_us(params)
    pwm, out = [], []
    for u in _window_inputs(logs, windows, params):
        p = u[:, :N_MOTORS]
        pwm.append(p[p > params.pwm_idle_us])
        out.append(np.asarray(motor_out_of_band(params.thrust_map, p, u[:, N_MOTORS:], c, N_MOTORS),
                              float)[p > params.pwm_idle_us])
    flown = np.concatenate(pwm) if pwm else np.zeros(0)
    if not flown.size:
        return {}
    outside = np.concatenate(out) > 0.5
    mid = 0.5 * (lo_us + hi_us)
    below, above = float(np.mean(outside & (flown < mid))), float(np.mean(outside & (flown >= mid)))
    p_lo, p_hi = (float(v) for v in np.percentile(flown, [0.5, 99.5]))
    share = below + above
    text = (f"thrust map: trained band {lo_us:.0f}-{hi_us:.0f} us per motor; the motors ran {p_lo:.0f}-{p_hi:.0f} us "
            f"(0.5-99.5 %) in the fit windows, {100 * share:.1f} % of their samples outside the band ("
            f"{100 * below:.1f} % below, {100 * above:.1f} % above)")
    warning = ""
    if share > BAND_WARN_SHARE:
        warning = (f"the thrust map was fitted on a narrower PWM range ({lo_us:.0f}-{hi_us:.0f} us per motor) than "
                   f"the motors use in the fit windows ({p_lo:.0f}-{p_hi:.0f} us, {100 * share:.1f} % of the samples "
                   "outside): there the map is extrapolated, and Jx, Jy (through the arm's moment effectiveness "
                   "l dT/dPWM) and the motor lag inherit the error of its slope (Jx and Jy carry it where the start "
                   "file's map covariance or this flight's vertical specific force gives it: the thrust slope lines); "
                   "identify the map on a flight whose per-motor commands span this range")
        text += "\nwarning: " + warning
    return {"band_pwm_us": [lo_us, hi_us], "flown_pwm_us": [p_lo, p_hi], "share_outside": share,
            "share_below": below, "share_above": above, "warning": warning, "text": text}


def thrust_slope_check(logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]],
                       params: QuadrotorParams, rate_hz: float) -> dict[str, Any]:
    """Whether the flight's vertical specific force shows the thrust map's slope off over the commands the motors
    ran (``windows``: the drag regression's, all airborne time but the held-out windows, which hold the inertias'
    fit windows). The scale ``s`` of the model's total thrust (``params``: the map and the fitted motor lag) in the
    drag regression with that thrust as its only thrust regressor (:func:`drag_equation_error`, one constant per
    log: only the thrust's changes count, so ``s`` is the map's slope over the flown commands, 1 when the map is
    right) and its 1-sigma (Newey-West); ``z = (s - 1) / sd``; ``shown`` when ``|z|`` exceeds
    :data:`SLOPE_SHOWN_Z`. Then ``relative_sd = sqrt((s - 1)^2 + sd^2)`` is the relative error the inertias of
    :data:`SLOPE_PARAMS` inherit, which :meth:`QuadrotorIdResult.estimates` adds to their data bound: a map off in
    shape (not only in scale) also moves the drag in this regression, so ``s - 1`` is the size of the slope's
    error, not a correction to apply (the estimates are left as fitted). Not shown, nothing is added: the data
    bound stands, as the replica with the truth's map requires. Raises ``QuadrotorInputError`` when the windows
    have too few samples."""
    got = drag_equation_error(logs, windows, params, thrust_of=MotorThrust(params).total,
                              rate_hz=rate_hz)["kd_z_N_s_m"]
    s, sd = got["thrust_scale"], got["thrust_scale_std"]
    z = (s - 1.0) / sd if sd > 0.0 else (0.0 if s == 1.0 else math.copysign(math.inf, s - 1.0))
    shown = bool(abs(z) > SLOPE_SHOWN_Z)
    out: dict[str, Any] = {"scale": s, "std": sd, "z": float(z), "shown_at_z": SLOPE_SHOWN_Z, "shown": shown}
    names = ", ".join(SLOPE_PARAMS)
    if shown:
        out["relative_sd"] = math.hypot(s - 1.0, sd)
        out["text"] = (f"thrust slope check: the map's thrust changes take a scale of {s:.3f} +- {sd:.3f} (1-sigma) "
                       f"in this flight's vertical specific force, {abs(z):.1f} std from 1 (shown past "
                       f"{SLOPE_SHOWN_Z:g}): the map's slope is off where the inertias are identified, and {names} "
                       f"(moment l dT/dPWM over the inertia) inherit it: their intervals carry a relative "
                       f"{out['relative_sd']:.3f} (1-sigma) beside the data's bound; the parameter file's replay "
                       "covariance does not take it, since the rates rest on l dT/dPWM over the inertia, which the "
                       "fit fixes")
    else:
        out["text"] = (f"thrust slope check: the map's thrust changes take a scale of {s:.3f} +- {sd:.3f} (1-sigma) "
                       f"in this flight's vertical specific force, {abs(z):.1f} std from 1: no slope error shown "
                       f"(past {SLOPE_SHOWN_Z:g}); {names} carry the data's bound")
    return out


def map_slope_share(logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]], params: QuadrotorParams,
                    uncertainty: Uncertainty | None) -> dict[str, Any]:
    """How uncertain the thrust map's slope is where the inertias are identified, from the start file's covariance
    of the map's consequents (``identify thrust`` writes it): the slope is the least-squares slope of the per-motor
    thrust on the PWM over the motors' samples above idle in ``windows`` (what the moments of the rate fit see),
    linear in the consequents, so its variance is ``g' C g`` with ``g`` its gradient over them (by differences).
    Returns ``relative_sd`` (the slope's relative 1-sigma, which the inertias of :data:`SLOPE_PARAMS` inherit one
    for one), ``slope_N_us``, the consequents' ``names`` and ``gradient`` (for the joint covariance the parameter
    file carries) and ``text``; empty when ``uncertainty`` holds none of the map's consequents or the windows no
    motor sample above idle."""
    amap = params.thrust_map
    names = [name for name, _, _ in consequent_parameters(amap)]
    if uncertainty is None or not set(names) & set(uncertainty.names):
        return {}
    pwm, volt = [], []
    for u in _window_inputs(logs, windows, params):
        pwm.append(u[:, :N_MOTORS].ravel())
        volt.append(np.repeat(u[:, N_MOTORS], N_MOTORS))
    p, v = (np.concatenate(x) if x else np.zeros(0) for x in (pwm, volt))
    above = p > params.pwm_idle_us
    p, v = p[above], v[above]
    if p.size < 2 or float(np.ptp(p)) <= 0.0:
        return {}
    c = constants_of(params)
    dp = p - p.mean()
    width = len(amap.consequents[0])
    flat = [x for row in amap.consequents for x in row]

    def slope(theta: list[float]) -> float:
        cons = tuple(tuple(theta[r * width:(r + 1) * width]) for r in range(len(amap.consequents)))
        thrust = np.asarray(motor_thrust(dataclasses.replace(amap, consequents=cons), p, v, c, N_MOTORS), float)
        return float(np.dot(thrust - thrust.mean(), dp) / np.dot(dp, dp))

    s0 = slope(flat)
    grad = np.zeros(len(flat))
    for i, x in enumerate(flat):
        h = 1e-3 * max(abs(x), 1e-6)
        grad[i] = (slope([*flat[:i], x + h, *flat[i + 1:]]) - s0) / h
    idx = {n: i for i, n in enumerate(uncertainty.names)}
    cov = np.asarray(uncertainty.covariance, float)
    sel = [(k, idx[n]) for k, n in enumerate(names) if n in idx]
    g = np.array([grad[k] for k, _ in sel])
    var = float(g @ cov[np.ix_([j for _, j in sel], [j for _, j in sel])] @ g)
    if not (s0 > 0.0 and math.isfinite(var)):
        return {}
    rel = math.sqrt(max(var, 0.0)) / s0
    missing = [n for n in names if n not in idx]
    return {"relative_sd": rel, "slope_N_us": s0, "names": [names[k] for k, _ in sel], "gradient": g.tolist(),
            "text": (f"thrust map slope: {1e3 * s0:.4g} mN/us over the fit windows' motor commands, {100 * rel:.1f} "
                     f"% (1-sigma) from the start file's covariance of the map's consequents"
                     + (f" ({', '.join(missing)} not in it: held exact)" if missing else "")
                     + f"; {', '.join(SLOPE_PARAMS)} inherit it (moment l dT/dPWM over the inertia): in their "
                     "intervals (the thrust slope check's instead where it shows a larger error) and, correlated "
                     "with the map, in the parameter file's covariance")}


def _determined(name: str, dominance: str) -> str:
    if name == "Jz_kg_m2":
        return (f"{dominance} (the yaw torque fixes only (b/k)/Jz; Jz itself comes from the gyroscopic "
                "cross-coupling of roll and pitch and the airframe inertia prior)")
    if name in ("Jx_kg_m2", "Jy_kg_m2"):
        return f"{dominance} (through the arm's moment effectiveness l/J, l from the parameter file)"
    if name == "b_drag_N_m_s2":
        return f"{dominance} (through (b/k)/Jz: its spread is mostly that of Jz)"
    return dominance


def command_rate_hz(log: FlightLog) -> float:
    """Median rate [Hz] at which the log records motor 1's command."""
    t = log.signal("motor_1_pwm_us").t_s
    d = np.diff(t)
    d = d[d > 0]
    if not d.size:
        raise LogError(f"{log.source}: motor_1_pwm_us has fewer than two samples")
    return float(1.0 / np.median(d))


def _inputs(log: FlightLog, params: QuadrotorParams, t_s: np.ndarray) -> np.ndarray:
    """Model inputs (len(t) x 5): the motor PWMs held between samples, the battery voltage where logged."""
    cols = [hold(log.signal(f"motor_{k}_pwm_us"), t_s) for k in range(1, N_MOTORS + 1)]
    volt = log.signal(BATTERY_VOLTAGE).resample(t_s) if log.has(BATTERY_VOLTAGE) else \
        np.full(len(t_s), params.battery_nominal_V)
    return np.column_stack([*cols, volt])


def on_command_grid(cmd_t_s: np.ndarray, t_s: float) -> float:
    """The first motor-command sample time at or after ``t_s`` [s] (``t_s`` itself past the last one). A record
    starts there: its inputs are the commands held from their own sample times, so a start between two samples
    would hold each command up to one sample later than the motors got it. That delay is harmless on smooth
    commands, but a rate loop passes the gyro's noise to the motors sample by sample, and the fit then takes
    the delay out of the motor time constant (measured on the replica: -0.6 ms of a 20 ms truth, Jx and Jy
    +0.2 %, with windows starting at a quarter to three quarters of a 4 ms sample)."""
    i = int(np.searchsorted(cmd_t_s, t_s - HOLD_TOLERANCE_S, side="left"))
    return float(cmd_t_s[i]) if i < len(cmd_t_s) else float(t_s)


def manoeuvres(model: QuadrotorModel, p: np.ndarray, log: FlightLog, params: QuadrotorParams,
               windows: Sequence[qseg.Segment], outputs: Sequence[str], rate_hz: float) -> list[Manoeuvre]:
    """One :class:`Manoeuvre` per window: inputs at ``t_k``, measurements at ``t_{k+1}``, the initial state from
    the log through the model's own initial-state function."""
    if isinstance(model, ExactLagModel) and abs(model.sample_s * rate_hz - 1.0) > 1e-9:
        raise QuadrotorInputError(f"records at {rate_hz:g} Hz for a model that steps {model.sample_s:g} s")
    init = init_function(model)
    lag = MotorThrust(params) if params.tau_motor_s > 0 else None
    i_lag = model.states.index["thrust_state_1_N"]
    out = []
    cmd_t = log.signal("motor_1_pwm_us").t_s
    for w in windows:
        t0 = on_command_grid(cmd_t, w.t0_s)
        n = math.floor((w.t1_s - t0) * rate_hz + 1e-9)
        if n < 3:
            continue
        t = t0 + np.arange(n + 1) / rate_hz
        u = _inputs(log, params, t[:-1])
        y = np.column_stack([log.signal(OUTPUT_TO_LOG[o]).resample(t[1:]) for o in outputs])
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(u))):
            continue
        pp = p.copy()
        # the state where the record starts: on the command grid, not at the window's own start
        for name, value in initial_values(log, t0, forward_from_airspeed=False).items():
            pp[model.params.index[name]] = value
        x0 = np.asarray(init(u[0], pp)[0]).ravel()
        if lag is not None:  # the motors still lag behind the commands before the window
            x0[i_lag:i_lag + N_MOTORS] = lag.at(log, t0)
        out.append(Manoeuvre(x0, u, y, 1.0 / rate_hz, str(w)))
    return out


def _windows(logs: Sequence[FlightLog], params: QuadrotorParams, opt: QuadrotorOptions, notes: list[str]
             ) -> tuple[list[tuple[int, qseg.Segment]], list[tuple[int, qseg.Segment]]]:
    fit, val = [], []
    for k, log in enumerate(logs):
        if opt.segments:
            segs = list(opt.segments)
            how = "given segments"
        else:
            path = opt.blocks if (opt.blocks and len(logs) == 1) else qseg.blocks_beside(Path(log.source))
            if path is not None:
                segs = qseg.load_blocks(path, log)
                how = f"excitation blocks of {Path(path).name}"
            elif qseg.sysid_segments(log):
                segs = qseg.sysid_segments(log)
                how = "ArduCopter SystemId chirps (SIDD)"
            else:
                segs = qseg.airborne_segments(log, params.pwm_idle_us)
                how = "airborne time cut into 6 s pieces (no blocks file, no SystemId chirps)"
        f, v = qseg.hold_out(segs, opt.hold_out_every)
        notes.append(f"{Path(log.source).name}: {len(f)} fit and {len(v)} held-out segments from {how}")
        fit += [(k, w) for w in qseg.split_windows(f, opt.window_s)]
        val += [(k, w) for w in qseg.split_windows(v, opt.score_window_s)]
    if not fit:
        raise QuadrotorInputError("no fit segment: give --segments or a blocks file, or a log with airborne time")
    if len(fit) > qseg.MAX_WINDOWS:
        step = math.ceil(len(fit) / qseg.MAX_WINDOWS)
        notes.append(f"{len(fit)} fit windows; every {step}th kept (at most {qseg.MAX_WINDOWS})")
        fit = fit[::step]
    return fit, val


#: drag regression: airborne time is cut into pieces of this length [s] (held-out ones dropped), and contiguous
#: kept pieces are joined into blocks of at most DRAG_BLOCK_S, the units of its bootstrap
DRAG_PIECE_S, DRAG_BLOCK_S = 0.5, 4.0
#: moving average [s] applied to velocity and specific force alike before the drag regression: white velocity
#: noise in the regressor biases a least-squares slope towards zero by var(noise) / var(velocity) (errors in
#: variables; 4 % for 0.03 m/s noise on a 0.15 m/s vertical velocity), and drag acts over seconds
DRAG_SMOOTH_S = 0.25


def _drag_windows(logs: Sequence[FlightLog], params: QuadrotorParams, fit_w: list[tuple[int, qseg.Segment]],
                  val_w: list[tuple[int, qseg.Segment]]) -> list[tuple[int, qseg.Segment]]:
    """Windows for the drag regression: all airborne time (drag wants velocity change, which the whole flight
    has more of than the excitation blocks) except the held-out windows; the fit windows when the airborne time
    cannot be told."""
    out = []
    for k, log in enumerate(logs):
        try:
            air = qseg.airborne_segments(log, params.pwm_idle_us, piece_s=DRAG_PIECE_S)
        except qseg.SegmentError:
            air = []
        held = [w for i, w in val_w if i == k]
        kept = [a for a in air if not any(a.t0_s < h.t1_s and h.t0_s < a.t1_s for h in held)]
        run: list[qseg.Segment] = []
        for a in kept:
            if run and (a.t0_s > run[-1].t1_s + 1e-6 or a.t1_s - run[0].t0_s > DRAG_BLOCK_S + 1e-6):
                out.append((k, qseg.Segment(run[0].t0_s, run[-1].t1_s, "drag")))
                run = []
            run.append(a)
        if run:
            out.append((k, qseg.Segment(run[0].t0_s, run[-1].t1_s, "drag")))
    return out if len(out) >= 2 else list(fit_w)


def _velocity_logged(log: FlightLog) -> bool:
    return all(log.has(f"vel_{a}_m_s") for a in ("north", "east", "down"))


def identify_quadrotor(logs: FlightLog | Sequence[FlightLog], init: QuadrotorParams,
                       opt: QuadrotorOptions | None = None, map_uncertainty: Uncertainty | None = None
                       ) -> QuadrotorIdResult:
    """Identify the quadrotor of ``logs`` (one vehicle); raises ``QuadrotorInputError``, ``LogError`` or
    ``SegmentError`` before a solve, ``EstimationError`` when the solve itself fails. ``map_uncertainty``: the
    start file's ``uncertainty`` (``identify thrust``'s covariance of the map, :func:`map_slope_share`)."""
    opt = opt or QuadrotorOptions()
    bad = opt.problems()
    if bad:
        raise QuadrotorInputError(f"identify quadrotor options: {'; '.join(bad)}")
    logs = [logs] if isinstance(logs, FlightLog) else list(logs)
    if not logs:
        raise QuadrotorInputError("no log given")
    for log in logs:
        check_quality(log, opt.force)
        missing = [n for n in (*[f"motor_{k}_pwm_us" for k in range(1, N_MOTORS + 1)],
                               *[OUTPUT_TO_LOG[o] for o in (*RATE_OUTPUTS, *FORCE_OUTPUTS)],
                               "roll_rad", "pitch_rad", "yaw_rad") if not log.has(n)]
        if missing:
            raise LogError(f"{log.source}: identify quadrotor needs {', '.join(missing)}")
    prior = airframe_inertia(init.mass_kg, init.arm_length_m, opt.motor_mass_kg, opt.battery_mass_kg, init.frame)
    command_hz = min(command_rate_hz(log) for log in logs)
    notes: list[str] = []
    slow_why = ""
    if command_hz < MIN_COMMAND_HZ:  # ArduCopter's RATE mixer inputs, where logged fast, give the commands between
        logs, command_hz, slow_why = rate_commands.fill_in(logs, command_hz, MIN_COMMAND_HZ, notes)
    fit_w, val_w = _windows(logs, init, opt, notes)
    band = thrust_band_coverage(logs, fit_w, init)
    velocity = all(_velocity_logged(log) for log in logs)
    not_ident: dict[str, str] = {}
    if not velocity:
        not_ident.update({n: "the log has no velocity: drag acts on it" for n in DRAG_PARAMS})
    if command_hz < MIN_COMMAND_HZ:
        why = (f"motor commands logged at {command_hz:.0f} Hz, below {MIN_COMMAND_HZ:g} Hz: the rate loop changes "
               "the motors many times between two logged commands, so the moments that drive the body rates "
               "are unknown" + (f" (no rebuilt commands: {slow_why})" if slow_why else ""))
        not_ident.update({n: why for n in RATE_PARAMS})
        if velocity:
            not_ident["kd_z_N_s_m"] = ("vertical drag needs the thrust at the log's rate, which slow motor "
                                       "commands do not give")
        result = QuadrotorIdResult(init, [], None, prior, [w for _, w in fit_w], [w for _, w in val_w], command_hz,
                                   not_ident, notes=notes, thrust_band=band)
        if velocity:
            result.drag = drag_equation_error(logs, _drag_windows(logs, init, fit_w, val_w), init,
                                              rate_hz=opt.rate_hz)
            result.free = list(result.drag)
            result.params = dataclasses.replace(init, **{n: d["value"] for n, d in result.drag.items()})
        return result
    rate = min(opt.rate_hz, command_hz)
    drag: dict[str, dict[str, float]] = {}
    fit_list = _drag_windows(logs, init, fit_w, val_w)
    if velocity:
        drag = drag_equation_error(logs, fit_list, init, rate_hz=opt.rate_hz)
    start = dataclasses.replace(
        init, Jx_kg_m2=prior.Jx_kg_m2, Jy_kg_m2=prior.Jy_kg_m2, Jz_kg_m2=prior.Jz_kg_m2,
        tau_motor_s=init.tau_motor_s if init.tau_motor_s > BOUNDS["tau_motor_s"][0] else TAU_START_S,
        **{n: d["value"] for n, d in drag.items()})
    model = ExactLagModel(start, sample_s=1.0 / rate)
    p = np.array(model.params.starts(), dtype=float)
    outputs = [*RATE_OUTPUTS, "accel_body_z_m_s2"]
    free = list(RATE_PARAMS)
    data = []
    for k, log in enumerate(logs):
        data += manoeuvres(model, p, log, start, [w for i, w in fit_w if i == k], outputs, rate)
    if len(data) < 2:
        raise QuadrotorInputError(f"only {len(data)} fit window(s) with finite data at {rate:g} Hz")
    oe = OutputErrorEstimator(model, p, free, outputs, bounds={n: BOUNDS[n] for n in free},
                              estimate_states=list(RATE_OUTPUTS), estimate_biases=["accel_body_z_m_s2"],
                              prior=prior.as_priors())
    est = oe.estimate(data, max_iter=opt.max_iter, progress=opt.progress)
    params = dataclasses.replace(start, **dict(zip(free, map(float, est.values[:len(free)]), strict=True)))
    # the windows' initial motor thrusts follow the lag: rebuild them with the fitted time constant, refit warm
    data = []
    for k, log in enumerate(logs):
        data += manoeuvres(model, p, log, params, [w for i, w in fit_w if i == k], outputs, rate)
    est = oe.estimate(data, theta0=est.values[:len(free)], max_iter=opt.max_iter, progress=opt.progress)
    est.bootstrap_min_dof = BOOTSTRAP_MIN_DOF
    params = dataclasses.replace(start, **dict(zip(free, map(float, est.values[:len(free)]), strict=True)))
    if velocity:
        try:
            drag.update(drag_equation_error(logs, fit_list, params, thrust_of=MotorThrust(params).total,
                                            rate_hz=opt.rate_hz, nuisance=ThrustNuisance.over(logs, fit_list, params)))
            params = dataclasses.replace(params, **{n: d["value"] for n, d in drag.items()})
        except QuadrotorInputError as err:
            notes.append(str(err))
    if "tau_motor_s" in free and 0.0 < params.tau_motor_s < params.step_internal_s:
        tau_hw = 1.96 * float(est.std[free.index("tau_motor_s")])
        if params.tau_motor_s - tau_hw <= 0.0:  # a lag the data cannot tell from none: no lag, not a tiny step
            notes.append(f"motor time constant {1e3 * params.tau_motor_s:.3g} ms (95 % interval reaches "
                         f"{1e3 * (params.tau_motor_s - tau_hw):.3g} ms) is shorter than the FMU's internal step "
                         f"({1e3 * params.step_internal_s:.3g} ms) and not told apart from none: written as 0 (no "
                         "motor lag)")
            params = dataclasses.replace(params, tau_motor_s=0.0)
    if 0.0 < params.tau_motor_s < 2.0 * params.step_internal_s:
        step = max(params.tau_motor_s / 2.0, FMU_STEP_MIN_S)
        notes.append(f"motor time constant {1e3 * params.tau_motor_s:.3g} ms: the FMU's internal RK4 step is set "
                     f"to {1e3 * step:.3g} ms (step_internal_s, was {1e3 * params.step_internal_s:.3g} ms) so that "
                     "it follows the motors (RK4 diverges on a lag under 0.36 of its step)")
        params = dataclasses.replace(params, step_internal_s=step)
    slope: dict[str, Any] = {}
    if velocity:
        try:
            slope = thrust_slope_check(logs, fit_list, params, opt.rate_hz)
        except QuadrotorInputError as err:
            notes.append(f"thrust slope check: {err}")
    result = QuadrotorIdResult(params, free + list(drag), est, prior, [w for _, w in fit_w], [w for _, w in val_w],
                               command_hz, not_ident, drag=drag, notes=notes, thrust_band=band, thrust_slope=slope,
                               map_slope=map_slope_share(logs, fit_w, params, map_uncertainty))
    if not est.converged:
        notes.append(f"not converged within {opt.max_iter} iterations: the estimates are the last accepted iterate")
    result.ratios = _ratios(est, params)
    try:
        result.held_out = _score_held_out(oe, est, logs, params, val_w, outputs, rate, opt.score_window_s)
    except (ValueError, EstimationError) as err:
        result.failures.append(f"held-out scoring: {err}")
    return result


def vertical_drag(logs: FlightLog | Sequence[FlightLog], params: QuadrotorParams,
                  opt: QuadrotorOptions | None = None) -> dict[str, float]:
    """``kd_z_N_s_m`` (``value``, 1-sigma ``std``) by the drag regression of :func:`identify_quadrotor` alone, without
    the output-error fit: the body specific force on the body velocity, with ``params``' thrust (map and motor lag)
    and the flexible static thrust of :class:`ThrustNuisance` beside it, so a map off in shape does not bias it.
    Seconds, where the whole identification takes a minute: what ``identify thrust`` needs to take the vertical drag
    out of ``-m a_z`` (``ThrustConfig.vertical_drag_N_s_m``) before the map the inertia is identified through."""
    opt = opt or QuadrotorOptions()
    logs = [logs] if isinstance(logs, FlightLog) else list(logs)
    missing = [f"{Path(log.source).name}: vel_*_m_s" for log in logs if not _velocity_logged(log)]
    if missing:
        raise QuadrotorInputError(f"vertical drag needs the logged velocity ({', '.join(missing)})")
    fit_w, val_w = _windows(logs, params, opt, [])
    windows = _drag_windows(logs, params, fit_w, val_w)
    d = drag_equation_error(logs, windows, params, thrust_of=MotorThrust(params).total, rate_hz=opt.rate_hz,
                            nuisance=ThrustNuisance.over(logs, windows, params))["kd_z_N_s_m"]
    return {"value": float(d["value"]), "std": float(d["std"])}


class MotorThrust:
    """Per-motor thrust [N] of the model with ``params`` over a log: the thrust map of the logged PWMs (the
    model's own ``commanded_thrust``) through the first-order motor lag, discretised exactly between command
    samples."""

    def __init__(self, params: QuadrotorParams) -> None:
        import casadi as ca

        m = QuadrotorModel(params)
        u = m.inputs.sym("u")
        self.params = params
        self.fn = ca.Function("cmd", [u], [ca.vertcat(*m.commanded_thrust(u, np.array(m.params.starts(), float)))])

    def samples(self, log: FlightLog, t0_s: float, t1_s: float) -> np.ndarray:
        """Motor-command sample times in ``[t0 - lead, t1]``: the lead (``MOTOR_LAG_SETTLE_TAUS`` time constants and
        50 ms) lets the lag forget the steady state it is started in."""
        tau = max(self.params.tau_motor_s, 1e-6)
        ts = log.signal("motor_1_pwm_us").t_s
        ts = ts[(ts >= t0_s - MOTOR_LAG_SETTLE_TAUS * tau - 0.05) & (ts <= t1_s)]
        return ts if len(ts) else np.array([t0_s])

    def lagged(self, ts: np.ndarray, cmd: np.ndarray) -> np.ndarray:
        """Columns of ``cmd`` (held from their sample times ``ts``) through the motor lag, exactly (n x k)."""
        tau = max(self.params.tau_motor_s, 1e-6)
        out = np.empty_like(cmd)
        out[0] = cmd[0]
        for i in range(1, len(ts)):
            a = 1.0 - math.exp(-(ts[i] - ts[i - 1]) / tau)
            out[i] = out[i - 1] + a * (cmd[i - 1] - out[i - 1])
        return out

    def history(self, log: FlightLog, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Command sample times in ``[t0 - lead, t1]`` and the lagged thrust there (n x 4)."""
        ts = self.samples(log, t0_s, t1_s)
        cmd = np.asarray(self.fn.map(len(ts))(_inputs(log, self.params, ts).T)).T.reshape(len(ts), N_MOTORS)
        return ts, self.lagged(ts, cmd)

    def at(self, log: FlightLog, t_s: float) -> np.ndarray:
        """Per-motor lagged thrust at ``t_s`` (the state a replay starting there begins with)."""
        ts, out = self.history(log, t_s, t_s)
        return np.array([np.interp(t_s, ts, out[:, k]) for k in range(N_MOTORS)])

    def total(self, log: FlightLog, t: np.ndarray) -> np.ndarray:
        ts, out = self.history(log, float(t[0]), float(t[-1]))
        return np.interp(t, ts, out.sum(axis=1))


#: vertical drag: rules of the flexible static thrust that stands in for the thrust map's shape in the regression
#: (Gaussian memberships evenly over the flown motor commands, consequents ``u^2, u``). ``bench/quadrotor_demo_map.py``
#: (the demo's stick flight through identify thrust's map, truth 0.25 N s/m): the scaled map alone 0.554, 1-3 rules
#: 0.58, 0.33, 0.25, 4-8 rules 0.21-0.26 (5: 0.264 +- 0.050)
DRAG_THRUST_RULES = 5


class ThrustNuisance:
    """The motors' thrust as a flexible static function of their commands, for the vertical drag regression.

    Per motor ``sum_r w_r(u) (a_r u^2 + b_r u)`` with normalised Gaussian memberships ``w_r`` at
    :data:`DRAG_THRUST_RULES` centres evenly over the flown command range ``u`` (``fmu_models.quadrotor.thrust
    .command``), through the motor lag; summed over the motors, each feature is one regressor, so the fit may take
    any thrust of that family, and ``kd_z`` is what only the vertical velocity explains. With the model's own
    thrust as the only thrust regressor (scaled), the map's shape error, which follows the climb rate (climbing
    takes thrust), went into ``kd_z`` (the demo: 0.52 for a truth of 0.25 with the scale at 1.17)."""

    def __init__(self, params: QuadrotorParams, lo: float, hi: float, rules: int = DRAG_THRUST_RULES) -> None:
        if not 0.0 <= lo < hi:
            raise QuadrotorInputError(f"drag: flown motor commands span {lo:.3g}..{hi:.3g}: no range to fit thrust on")
        self.params = params
        self.lag = MotorThrust(params)
        self.centres = np.linspace(lo, hi, rules)
        self.sigma = (hi - lo) / max(rules - 1, 1)

    @classmethod
    def over(cls, logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]],
             params: QuadrotorParams) -> ThrustNuisance:
        """Centres over the commands flown in ``windows`` (0.5-99.5 % of every motor's samples above idle)."""
        us = []
        for k, w in windows:
            t = logs[k].signal("motor_1_pwm_us").t_s
            t = t[(t >= w.t0_s) & (t <= w.t1_s)]
            if len(t):
                us.append(_commands(logs[k], params, t).ravel())
        u = np.concatenate(us) if us else np.zeros(0)
        u = u[u > 0]
        if not u.size:
            raise QuadrotorInputError("drag: no motor command above idle in the drag windows")
        return cls(params, float(np.percentile(u, 0.5)), float(np.percentile(u, 99.5)))

    def features(self, u: np.ndarray) -> np.ndarray:
        """Per-sample features of per-motor commands ``u`` (n x 4): summed over the motors (n x 2 rules)."""
        w = np.exp(-(((u[..., None] - self.centres) / self.sigma) ** 2))
        w = w / np.maximum(w.sum(axis=-1, keepdims=True), 1e-300)
        return np.concatenate([w * (u ** 2)[..., None], w * u[..., None]], axis=-1).sum(axis=1)

    def __call__(self, log: FlightLog, t: np.ndarray) -> np.ndarray:
        """The features at ``t`` through the motor lag (len(t) x 2 rules)."""
        ts = self.lag.samples(log, float(t[0]), float(t[-1]))
        f = self.lag.lagged(ts, self.features(_commands(log, self.params, ts)))
        return np.column_stack([np.interp(t, ts, f[:, i]) for i in range(f.shape[1])])


def _commands(log: FlightLog, params: QuadrotorParams, t: np.ndarray) -> np.ndarray:
    """Per-motor normalised commands ``u`` held at ``t`` (len(t) x 4)."""
    return command(_inputs(log, params, t)[:, :N_MOTORS], params.pwm_idle_us, params.pwm_full_us)


def _ratios(est: Estimate, params: QuadrotorParams) -> list[Ratio]:
    """The combinations the data determine: ``l/Jx``, ``l/Jy`` and ``(b/k)/Jz`` (delta method on the printed
    covariance)."""
    cov = est.covariance_printed()
    idx = {n: i for i, n in enumerate(est.names[:est.n_global])}
    out = []
    for ax in ("x", "y"):
        i = idx[f"J{ax}_kg_m2"]
        j = est.values[i]
        v = params.arm_length_m / j
        out.append(Ratio(f"l/J{ax}", v, v * math.sqrt(cov[i, i]) / j, "1/(kg m)",
                         f"arm moment effectiveness about {ax} (angular acceleration per newton of differential "
                         "thrust)"))
    ib, iz = idx["b_drag_N_m_s2"], idx["Jz_kg_m2"]
    b, jz = est.values[ib], est.values[iz]
    v = b / params.k_thrust_N_s2 / jz
    g = np.array([1.0 / b, -1.0 / jz]) * v  # d ratio / d (b, Jz)
    c = cov[np.ix_([ib, iz], [ib, iz])]
    out.append(Ratio("(b/k)/Jz", v, float(math.sqrt(max(g @ c @ g, 0.0))), "1/(kg m)",
                     "yaw angular acceleration per newton of thrust moved between the spin directions"))
    return out


def _score_held_out(oe: OutputErrorEstimator, est: Estimate, logs: Sequence[FlightLog], params: QuadrotorParams,
                    val_w: list[tuple[int, qseg.Segment]], outputs: list[str], rate: float, window_s: float
                    ) -> dict[str, dict[str, Any]]:
    """Held-out windows replayed from the logged state (restarts every ``window_s``) with the identified values
    and the sensors' mean fitted biases, scored against persistence (each window's first measurement held)
    with the block-bootstrap skill interval of ``identification.common.metrics``."""
    if not val_w:
        return {}
    model = oe.model
    p = oe.p_nominal.copy()
    ng = est.n_global
    p[oe.i_free] = est.values[:ng]
    data = []
    for k, log in enumerate(logs):
        data += manoeuvres(model, p, log, params, [w for i, w in val_w if i == k], outputs, rate)
    if not data:
        return {}
    n_local = oe.n_local
    local = est.values[ng:].reshape(-1, n_local)
    bias = local[:, len(oe.i_x0):].mean(axis=0)
    theta = np.concatenate([est.values[:ng], *[np.concatenate([m.x0[oe.i_x0], bias]) for m in data]])
    ys, ms, holds, starts, n0 = [], [], [], [], 0
    for j, m in enumerate(data):
        sim, _, _ = oe.simulate(theta, m, j, sensitivities=False)
        ys.append(m.y)
        ms.append(sim)
        holds.append(np.repeat(m.y[:1], len(m.y), axis=0))
        starts.append(n0)
        n0 += len(m.y)
    y, mm, hh = np.vstack(ys), np.vstack(ms), np.vstack(holds)
    out = {}
    for i, name in enumerate(outputs):
        s = skill_interval(y[:, i], mm[:, i], hh[:, i], np.array(starts)).as_dict()
        out[name] = {**s, "window_s": window_s, "windows": len(data),
                     "rmse_model": float(np.sqrt(np.mean((y[:, i] - mm[:, i]) ** 2))),
                     "rmse_persistence": float(np.sqrt(np.mean((y[:, i] - hh[:, i]) ** 2)))}
    return out


def _body_velocity(log: FlightLog, t: np.ndarray) -> np.ndarray:
    """Logged NED velocity rotated into the body by the logged attitude (len(t) x 3) [m/s]."""
    return body_velocity({n: (log.signal(n).t_s, log.signal(n).values) for n in BODY_VELOCITY_SIGNALS}, t)


def drag_equation_error(logs: Sequence[FlightLog], windows: Sequence[tuple[int, qseg.Segment]],
                        params: QuadrotorParams, thrust_of: Any = None, rate_hz: float = 50.0,
                        nuisance: ThrustNuisance | None = None) -> dict[str, dict[str, float]]:
    """Drag per axis by least squares of ``a_b = -kd v_b / m + c_log`` over every fit window: one constant per
    log and axis (the accelerometer's bias is constant over a flight), ``v_b`` the logged NED velocity rotated by
    the logged attitude. Along z the model's thrust per mass (``thrust_of(log, t) -> N``, the fitted model's
    total thrust; None: z is left out) is a second regressor with its own scale (``thrust_scale``, 1 when the
    thrust map is right): a map that is off by a factor otherwise leaves ``(s - 1) T / m`` in the specific force,
    which follows the vertical velocity (climbing takes thrust) and biases ``kd_z``. ``nuisance`` (with
    ``thrust_of``) adds the flexible static thrust of :class:`ThrustNuisance` beside it, for a map whose shape,
    not only its scale, is off (``thrust_scale`` is then not reported: the two share the thrust). Both sides are
    smoothed alike first (:data:`DRAG_SMOOTH_S`). 1-sigma: Newey-West over time with the residual's
    autocovariance pooled over the windows (:func:`hac_least_squares`; the smoothing and the sensors colour the
    residual, and a few windows carry most of the velocity change)."""
    rows: list[tuple[int, np.ndarray, np.ndarray]] = []  # (log, regressors, specific force) per window
    n = max(round(DRAG_SMOOTH_S * rate_hz), 1)
    for k, w in windows:
        log = logs[k]
        t = np.arange(w.t0_s, w.t1_s, 1.0 / rate_hz)
        if len(t) < 3:
            continue
        acc = np.column_stack([log.signal(f"accel_body_{a}_m_s2").resample(t) for a in "xyz"])
        thrust = thrust_of(log, t) / params.mass_kg if thrust_of is not None else np.full(len(t), np.nan)
        extra = nuisance(log, t) / params.mass_kg if (nuisance is not None and thrust_of is not None) else \
            np.zeros((len(t), 0))
        reg = np.column_stack([_body_velocity(log, t), thrust, extra])
        if len(t) > 2 * n:  # the same moving average on both sides keeps the relation linear
            kernel = np.ones(n) / n
            reg = np.column_stack([np.convolve(reg[:, i], kernel, "valid") for i in range(reg.shape[1])])
            acc = np.column_stack([np.convolve(acc[:, i], kernel, "valid") for i in range(3)])
        rows.append((k, reg, acc))
    if len(rows) < 2:
        raise QuadrotorInputError("drag: fewer than two windows with velocity and specific force")
    out: dict[str, dict[str, float]] = {}
    for a, name in enumerate(DRAG_PARAMS):
        if thrust_of is None and a == 2:
            continue
        # along z: body velocity, the model's thrust per mass and the flexible thrust (``nuisance``)
        cols = [a, *range(3, rows[0][1].shape[1])] if a == 2 else [a]
        xs: list[np.ndarray] = []
        ys: list[np.ndarray] = []
        groups: list[int] = []
        for k in dict.fromkeys(r[0] for r in rows):  # one constant per log: centre each log's samples
            xk = [r[1][:, cols] for r in rows if r[0] == k]
            yk = [r[2][:, a] for r in rows if r[0] == k]
            ok = [np.all(np.isfinite(x), axis=1) & np.isfinite(y) for x, y in zip(xk, yk, strict=True)]
            mx = np.concatenate([x[o] for x, o in zip(xk, ok, strict=True)]).mean(axis=0)
            my = float(np.concatenate([y[o] for y, o in zip(yk, ok, strict=True)]).mean())
            xs += [x[o] - mx for x, o in zip(xk, ok, strict=True)]
            ys += [y[o] - my for y, o in zip(yk, ok, strict=True)]
            groups += [k] * len(xk)
        if sum(len(x) for x in xs) < 4 * n * len(cols):
            raise QuadrotorInputError(f"drag: too few samples with velocity and specific force for {name}")
        # a = beta_v v (+ beta_T T/m): beta_v = -kd / m; one centring constant per log
        beta, cov = hac_least_squares(xs, ys, min_lags=4 * n, groups=groups)
        out[name] = {"value": -float(beta[0]) * params.mass_kg,
                     "std": params.mass_kg * math.sqrt(max(float(cov[0, 0]), 0.0))}
        if a == 2 and nuisance is None:
            out[name]["thrust_scale"] = -float(beta[1])
            out[name]["thrust_scale_std"] = math.sqrt(max(float(cov[1, 1]), 0.0))
    return out


def parameter_file(result: QuadrotorIdResult, base: dict[str, Any] | None, log_names: Sequence[str]
                   ) -> dict[str, Any]:
    """The parameter file: ``quadrotor`` with the estimates written in, ``uncertainty`` with their covariance
    (beside a thrust map's, when the start file carried one) and ``_identification`` saying how."""
    est = result.estimate
    names, mean, cov = [], [], np.zeros((0, 0))
    if est is not None:
        n = est.n_global
        names, mean, cov = list(est.names[:n]), [float(v) for v in est.values[:n]], est.covariance_printed()
        if "tau_motor_s" in names and result.params.tau_motor_s == 0.0:
            # a lag the data cannot tell from none is written as none: no draw of a validate --mc may bring one
            # back (a lag under 0.36 of the FMU's internal step makes its RK4 diverge)
            keep = [i for i, k in enumerate(names) if k != "tau_motor_s"]
            names, mean, cov = [names[i] for i in keep], [mean[i] for i in keep], cov[np.ix_(keep, keep)]
    if result.drag:
        dn = list(result.drag)
        c = np.zeros((len(names) + len(dn),) * 2)
        c[:len(names), :len(names)] = cov
        c[len(names):, len(names):] = np.diag([result.drag[k]["std"] ** 2 for k in dn])
        names, mean, cov = names + dn, mean + [result.drag[k]["value"] for k in dn], c
    unc = (base or {}).get("uncertainty")
    if isinstance(unc, dict) and unc.get("names"):
        keep = [i for i, k in enumerate(unc["names"]) if k not in names]
        old = np.asarray(unc["covariance"], float)[np.ix_(keep, keep)]
        big = np.zeros((len(keep) + len(names),) * 2)
        big[:len(keep), :len(keep)] = old
        big[len(keep):, len(keep):] = cov
        names = [unc["names"][i] for i in keep] + names
        mean = [float(unc["mean"][i]) for i in keep] + mean
        cov = _with_map_slope(big, names, mean, result.map_slope)
    out: dict[str, Any] = {"quadrotor": result.params.to_dict(), "_identification": {
        "method": "output error (identification.estimation.oem) on body rates and specific force",
        "logs": list(log_names), "free": result.free, "not_identifiable": result.not_identifiable,
        "estimates": result.estimates(), "ratios": {r.name: r.as_dict() for r in result.ratios},
        "inertia_prior": dataclasses.asdict(result.prior)}}
    if names:
        out["uncertainty"] = {"names": names, "mean": mean, "covariance": np.asarray(cov).tolist(),
                              "note": "identify quadrotor: printed covariance of its estimates (and the thrust "
                                      "map's, from the start file, with the roll and pitch inertias moving with "
                                      "its slope)"}
    return out


def _with_map_slope(cov: np.ndarray, names: list[str], mean: list[float], share: dict[str, Any]) -> np.ndarray:
    """``cov`` with the inertias of :data:`SLOPE_PARAMS` moving with the thrust map's consequents: an inertia
    identified through the map is ``J (1 + ds / s)`` for a slope error ``ds = g' d(theta)``, so it gets
    ``cov(J, theta) = J C g / s`` and ``cov(J_i, J_j) += J_i J_j g' C g / s^2``. A Monte Carlo draw of the map
    then carries its inertia with it, and the moment over the inertia, which the rates fixed, stays as
    identified (drawn apart, the map's slope spread would widen every replayed rate)."""
    if not share or not share.get("names"):
        return cov
    idx = {n: i for i, n in enumerate(names)}
    th = [idx[n] for n in share["names"] if n in idx]
    js = [idx[n] for n in SLOPE_PARAMS if n in idx]
    if len(th) != len(share["names"]) or not js:
        return cov
    g = np.asarray(share["gradient"], float) / share["slope_N_us"]  # relative slope per consequent
    cg = cov[np.ix_(th, th)] @ g
    out = cov.copy()
    for a in js:
        out[a, th] = out[th, a] = mean[a] * cg
        for b in js:
            out[a, b] += mean[a] * mean[b] * float(g @ cg)
    return out


def write_results(result: QuadrotorIdResult, out: Path, metrics: Path, base: dict[str, Any] | None,
                  log_names: Sequence[str]) -> None:
    """Parameter file and metrics JSON."""
    from identification.common.jsonio import write_json

    write_json(out, parameter_file(result, base, log_names))
    write_json(metrics, {"logs": list(log_names), **result.as_dict()})

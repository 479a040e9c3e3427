"""Experiment design for the quadrotor: stick 3-2-1-1s and doublets per axis, timed by the model's rate dynamics.

A quadrotor in an altitude-holding mode (PX4 ALTCTL / Stabilized, ArduCopter AltHold) flies the sticks through
the autopilot's loops: roll and pitch sticks set an attitude, the yaw stick a yaw rate, the throttle stick a climb
rate. Each axis is modelled about hover as the autopilot sees it (:class:`AutopilotLoops`, PX4's and ArduCopter's
structure and default gains):

- the plant of a rate axis: ``ω' = K e^{-sT} / (τ s + 1) · c``, ``c`` the normalised torque command of the rate
  controller, ``K`` [rad/s² per unit command] the model's own angular acceleration when the mixer moves each
  motor by ``mix`` of its actuator range per unit command (the secant over +-50 us per motor about hover on the
  model's equations: arm length, thrust-map slope and inertia for roll and pitch, yaw torque b/k and ``Jz`` for
  yaw), ``τ`` the motor time constant ``tau_motor_s``, ``T`` the loop delay (sampling, filters, ESC);
- the rate loop: PID (derivative low-passed) ``C(s)``, closed: ``T_r = C G / (1 + C G)``;
- roll and pitch: the angle loop ``P_a`` around it, ``T_a = P_a T_r / (s + P_a T_r)`` (stick -> attitude);
  yaw: the stick drives ``T_r`` (stick -> yaw rate); throttle: a PI vertical-velocity loop on the commanded
  acceleration with the same motor lag and delay (stick -> climb rate).

The delay enters as a first-order Padé term. A loop with a closed-loop pole in the right half plane is refused
(:class:`~identification.excite.design.ExciteError`). The target frequency of each axis is the natural frequency
of its stick response, where its phase lag reaches 45 deg per integration (:func:`bandwidth`; so a lighter airframe,
a faster motor or a stiffer rate loop shortens the pulses), capped by ``max_frequency_hz`` and the plan rate; pulse
widths and pulse trains are those of the fixed-wing design (:func:`identification.excite.design.pulse_unit`,
:func:`~identification.excite.design.steps`).

A ``drag`` input (roll, pitch and throttle) is a doublet timed by the translational mode instead: ``kd / m`` of the
drag the axis moves (``kd_y``, ``kd_x``, ``kd_z``; the pulse unit at most ``max_hold_s``), since drag acts on the body
velocity that short pulses hardly build; its tilt is also capped so that ``g tan(tilt) Δt`` stays within
``speed_limit_m_s``.

Stick amplitudes keep the linear closed-loop response within ``attitude_fraction`` of the tilt limit (roll,
pitch), of the yaw-rate limit (yaw) and of the climb-rate limit (throttle), and within ``max_stick``; the throttle
stick also clears the altitude-hold deadzone.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal

from fmu_models.common.model import derivative_function, init_function
from fmu_models.common.units import G0_M_S2
from fmu_models.config import bounded, range_problems
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from identification.excite.design import (
    PULSES,
    Block,
    ExciteError,
    ExciteOptions,
    PlanTiming,
    Signal,
    max_frequency_rad_s,
    pulse_unit,
    scale_signals,
    spectrum_centre,
    steps,
)

AXES = ("roll", "pitch", "yaw", "throttle")
RATE_AXES = ("roll", "pitch", "yaw")
INPUT_KINDS = ("3211", "doublet", "drag")
#: the translational drag each stick axis moves (the drag input's timing): roll tilts towards body y, pitch body x
DRAG_OF = {"roll": "kd_y_N_s_m", "pitch": "kd_x_N_s_m", "throttle": "kd_z_N_s_m"}
AUTOPILOTS = ("px4", "ardupilot")
#: actuator range every PWM maps onto (the project's motor PWM range: PX4 PWM_MAIN_MIN/MAX, ArduCopter
#: MOT_PWM_MIN/MAX as ``uavfmu autopilot-params`` writes them) [us]
PWM_MIN_US, PWM_MAX_US = 1000.0, 2000.0
#: the FMU's rate states and body-velocity states in the state vector (fmu_models.common.vehicle.BODY_STATES)
RATE_STATES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")
IN_AIR_DOWN_M = -50.0  #: initial NED down position of the hover used for the linear analysis (no ground contact)
#: half-width of the secant that gives the effectiveness, as a fraction of the actuator range (50 us about hover): a
#: stick pulse moves the motors by about this much, and a thrust map fitted over a narrow band (the published F450 map
#: spans 1450..1554 us per motor) has local slopes that change several-fold within it
STICK_STEP = 0.05


@dataclass(frozen=True)
class AutopilotLoops:
    """Attitude, rate and vertical-velocity loops of a multicopter autopilot (per axis roll, pitch, yaw).

    Rate PID: normalised torque command per rad/s (``rate_p``), per rad (``rate_i``), per rad/s² (``rate_d``,
    low-passed at ``d_cutoff_hz``); angle P: rad/s of rate set-point per rad (``angle_p``); the mixer moves each
    motor's actuator by ``mix`` of its range per unit command (signs from the frame's geometry). Vertical:
    commanded acceleration per m/s of climb-rate error (``z_vel_p``) and per m (``z_vel_i``); climb rate per m of
    height error while the throttle stick is centred (``z_pos_p``, altitude hold). Stick full scale:
    ``tilt_max_deg``, ``yaw_rate_max_deg_s``, ``climb_max_m_s`` (up), ``descent_max_m_s``; ``throttle_deadzone``
    is the fraction of the throttle stick's half range about centre that holds altitude.
    """

    name: str
    rate_p: tuple[float, float, float]
    rate_i: tuple[float, float, float]
    rate_d: tuple[float, float, float]
    angle_p: tuple[float, float, float]
    mix: tuple[float, float, float]
    z_vel_p: float
    z_vel_i: float
    z_pos_p: float
    tilt_max_deg: float
    yaw_rate_max_deg_s: float
    climb_max_m_s: float
    descent_max_m_s: float
    throttle_deadzone: float
    d_cutoff_hz: float
    mode: str
    recovery_mode: str
    source: str

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


#: PX4 v1.13 defaults (mc_rate_control / mc_att_control / mc_pos_control params; the quad_x mixer table scales roll
#: and pitch by 0.707 and yaw by 1.0 on motor outputs in 0..1, which MultirotorMixer maps to -1..1, i.e. the PWM range)
PX4_LOOPS = AutopilotLoops(
    name="px4", rate_p=(0.15, 0.15, 0.2), rate_i=(0.2, 0.2, 0.1), rate_d=(0.003, 0.003, 0.0),
    angle_p=(6.5, 6.5, 2.8), mix=(0.707, 0.707, 1.0), z_vel_p=4.0, z_vel_i=2.0, z_pos_p=1.0, tilt_max_deg=35.0,
    yaw_rate_max_deg_s=150.0, climb_max_m_s=3.0, descent_max_m_s=1.0, throttle_deadzone=0.1, d_cutoff_hz=30.0,
    mode="ALTCTL", recovery_mode="POSCTL",
    source="PX4 v1.13 MC_ROLLRATE_P/I/D, MC_PITCHRATE_P/I/D, MC_YAWRATE_P/I, MC_ROLL_P, MC_PITCH_P, MC_YAW_P, "
           "MPC_Z_VEL_P_ACC, MPC_Z_VEL_I_ACC, MPC_Z_P, MPC_MAN_TILT_MAX, MPC_MAN_Y_MAX, MPC_Z_VEL_MAX_UP/DN, "
           "MPC_HOLD_DZ, IMU_DGYRO_CUTOFF defaults; MultirotorMixer quad_x scales")
#: ArduCopter 4.x defaults (AC_AttitudeControl_Multi, AC_PosControl; AP_MotorsMatrix normalises the roll, pitch
#: and yaw factors to 0.5; THR_DZ 100 of the 500 us half range)
ARDUCOPTER_LOOPS = AutopilotLoops(
    name="ardupilot", rate_p=(0.135, 0.135, 0.18), rate_i=(0.135, 0.135, 0.018), rate_d=(0.0036, 0.0036, 0.0),
    angle_p=(4.5, 4.5, 4.5), mix=(0.5, 0.5, 0.5), z_vel_p=5.0, z_vel_i=0.0, z_pos_p=1.0, tilt_max_deg=30.0,
    yaw_rate_max_deg_s=202.5, climb_max_m_s=2.5, descent_max_m_s=2.5, throttle_deadzone=0.2, d_cutoff_hz=20.0,
    mode="ALT_HOLD", recovery_mode="LOITER",
    source="ArduCopter 4.x ATC_RAT_RLL/PIT/YAW_P/I/D, ATC_ANG_RLL/PIT/YAW_P, PSC_VELZ_P, PSC_POSZ_P, ANGLE_MAX, "
           "PILOT_Y_RATE, PILOT_SPEED_UP/DN, THR_DZ, ATC_RAT_*_FLTD defaults")
LOOPS = {"px4": PX4_LOOPS, "ardupilot": ARDUCOPTER_LOOPS}


@dataclass(frozen=True)
class QuadExciteOptions:
    """What to plan for the quadrotor; times in seconds, angles in degrees."""

    autopilot: str = "px4"
    inputs: Sequence[str] = INPUT_KINDS
    axes: Sequence[str] = AXES
    roll_limit_deg: float = bounded(30.0, 5.0, 60.0, "deg")  #: abort tilt; the plan peaks at attitude_fraction of it
    yaw_rate_limit_deg_s: float = bounded(90.0, 10.0, 360.0, "deg/s")
    climb_limit_m_s: float = bounded(1.5, 0.2, 5.0, "m/s")
    attitude_fraction: float = bounded(0.5, 0.05, 1.0)
    max_stick: float = bounded(0.6, 0.05, 1.0)
    loop_delay_s: float = bounded(0.01, 0.0, 0.1, "s")
    rate_hz: float = bounded(100.0, 50.0, 400.0, "Hz")  #: one RK4 step per sample in the check: >= 50 Hz
    min_pulse_s: float = bounded(0.1, 0.02, 5.0, "s")
    settle_s: float = bounded(2.0, 0.0, 30.0, "s")
    tail_s: float = bounded(3.0, 0.0, 30.0, "s")
    recovery_s: float = bounded(6.0, 1.0, 300.0, "s")
    max_frequency_hz: float = bounded(5.0, 0.1, 50.0, "Hz")
    max_hold_s: float = bounded(3.0, 0.5, 20.0, "s")  #: longest pulse unit of a drag doublet
    speed_limit_m_s: float = bounded(3.0, 0.5, 15.0, "m/s")  #: a drag doublet's tilt builds at most this speed

    def problems(self) -> list[str]:
        out = range_problems(self)
        if self.autopilot not in AUTOPILOTS:
            out.append(f"autopilot: {self.autopilot!r} unknown; allowed {', '.join(AUTOPILOTS)}")
        out += [f"inputs: {k!r} unknown; allowed {', '.join(INPUT_KINDS)}" for k in self.inputs if k not in INPUT_KINDS]
        out += [f"axes: {a!r} unknown; allowed {', '.join(AXES)}" for a in self.axes if a not in AXES]
        if not self.inputs or not self.axes:
            out.append("inputs and axes must each name at least one")
        return out

    def design_options(self) -> ExciteOptions:
        """The fixed-wing design's options that its pulse rules read (plan rate, shortest pulse, top frequency)."""
        return ExciteOptions(rate_hz=self.rate_hz, min_pulse_s=self.min_pulse_s,
                             max_frequency_hz=self.max_frequency_hz)


@dataclass(frozen=True)
class Hover:
    """The model at hover: PWM of each motor [us], angular acceleration per unit torque command per rate axis
    [rad/s²] (``effectiveness``), vertical acceleration per unit collective actuator [m/s²], the mixer's per-motor
    actuator signs of each rate axis, and the motor time constant [s]."""

    pwm_us: float
    effectiveness: dict[str, float]
    collective_m_s2: float
    signs: dict[str, tuple[float, ...]]
    tau_motor_s: float


@dataclass(frozen=True)
class AxisLoop:
    """One axis's stick response: transfer function (numerator, denominator in s), stick full scale in the
    response's unit, -3 dB bandwidth [rad/s], and the rate loop's own bandwidth [rad/s] (rate axes)."""

    num: tuple[float, ...]
    den: tuple[float, ...]
    full_scale: float
    bandwidth_rad_s: float
    rate_bandwidth_rad_s: float | None


@dataclass
class QuadExcitationPlan(PlanTiming):
    """The planned stick sequence: hover, loops, targets and blocks (``signals`` keyed by axis, unit stick)."""

    params: QuadrotorParams
    options: QuadExciteOptions
    loops: AutopilotLoops
    hover: Hover
    axis_loops: dict[str, AxisLoop]
    targets_rad_s: dict[str, float]
    blocks: list[Block]

    def sticks(self, t_s: np.ndarray) -> np.ndarray:
        """Stick positions (N x 4: roll, pitch, yaw, throttle in -1..1 about centre) at plan times ``t_s``.

        Signs: roll + right side down, pitch + nose up, yaw + clockwise seen from above, throttle + climb."""
        t = np.asarray(t_s, dtype=float)
        out = np.zeros((len(t), len(AXES)))
        for b in self.blocks:
            for a, sig in b.signals.items():
                out[:, AXES.index(a)] += sig(t - b.excitation_start_s)
        return out

    def active_block(self, t_s: float) -> Block | None:
        return next((b for b in self.blocks if b.start_s <= t_s < b.end_s), None)

    def summary(self) -> str:
        h = self.hover
        lines = [f"hover at {h.pwm_us:.0f} us per motor; motor time constant {h.tau_motor_s * 1000:.0f} ms; "
                 f"{self.loops.name} loops ({self.loops.mode}, recovery {self.loops.recovery_mode})"]
        for a in AXES:
            lp = self.axis_loops[a]
            eff = f", {h.effectiveness[a]:.0f} rad/s2 per unit command" if a in h.effectiveness else ""
            rate = f", rate loop {lp.rate_bandwidth_rad_s:.1f} rad/s" if lp.rate_bandwidth_rad_s else ""
            lines.append(f"  {a:8s} stick bandwidth {lp.bandwidth_rad_s:6.2f} rad/s{rate}{eff}; target "
                         f"{self.targets_rad_s[a]:.2f} rad/s")
        for b in self.blocks:
            amp = ", ".join(f"{a} stick {sig.peak_rad():.2f}" for a, sig in b.signals.items())
            peak = ", ".join(f"{k} {v:.1f}" for k, v in b.predicted_peak_deg.items())
            lines.append(f"  block {b.index}: {b.input:7s} {b.axis:8s} {b.start_s:7.1f}..{b.end_s:7.1f} s "
                         f"({amp}, dt {b.pulse_unit_s:.2f} s; linear peak: {peak})")
        lines.append(f"total {self.duration_s:.1f} s")
        return "\n".join(lines)

    def as_dict(self) -> dict[str, Any]:
        return {"vehicle": "quadrotor", "autopilot": self.loops.as_dict(),
                "hover": dataclasses.asdict(self.hover),
                "stick_bandwidth_rad_s": {a: lp.bandwidth_rad_s for a, lp in self.axis_loops.items()},
                "rate_loop_bandwidth_rad_s": {a: lp.rate_bandwidth_rad_s for a, lp in self.axis_loops.items()
                                              if lp.rate_bandwidth_rad_s},
                "target_frequencies_rad_s": self.targets_rad_s,
                "blocks": [{"index": b.index, "axis": b.axis, "input": b.input, "start_s": round(b.start_s, 4),
                            "excitation_start_s": round(b.excitation_start_s, 4), "end_s": round(b.end_s, 4),
                            "recovery_end_s": round(b.end_s + self.options.recovery_s, 4),
                            "pulse_unit_s": b.pulse_unit_s, "stick_amplitude": b.signals[b.axis].peak_rad(),
                            "predicted_linear_peak": b.predicted_peak_deg} for b in self.blocks],
                "options": {k: (list(v) if isinstance(v, tuple | list) else v)
                            for k, v in dataclasses.asdict(self.options).items()}}


# ------------------------------------------------------------------ the model at hover
def mixer_signs(model: QuadrotorModel) -> dict[str, tuple[float, ...]]:
    """Per-motor actuator direction of a positive roll, pitch and yaw command (largest magnitude 1).

    Roll + (right side down) raises the motors left of the x axis (moment ``-l sin(γ) T``), pitch + (nose up)
    the ones ahead of the y axis (``+l cos(γ) T``), yaw + (clockwise) the counter-clockwise ones (fan torque
    ``-s b Ω²``)."""
    g = np.radians(model.gamma_deg)
    roll, pitch, yaw = -np.sin(g), np.cos(g), -np.asarray(model.spin, float)
    return {a: tuple(np.round(v / np.max(np.abs(v)), 12)) for a, v in (("roll", roll), ("pitch", pitch), ("yaw", yaw))}


def hover_point(params: QuadrotorParams, loops: AutopilotLoops) -> Hover:
    """PWM of hover (bisection on the model's vertical acceleration) and the control effectiveness there."""
    model = QuadrotorModel(params)
    f, init = derivative_function(model), init_function(model)
    p = np.array(model.params.starts())
    p[model.params.index["init_pos_down_m"]] = IN_AIR_DOWN_M
    p[model.params.index["tau_motor_s"]] = 0.0  # effectiveness: thrust = command
    u0 = np.array(model.inputs.starts())
    x0 = np.asarray(init(u0, p)[0]).ravel()  # level, at rest, in the air (no lag: its states are not read)
    w_dot = model.states.index["vel_body_z_m_s"]
    rates = [model.states.index[n] for n in RATE_STATES]

    def xdot(pwm: np.ndarray) -> np.ndarray:
        u = u0.copy()
        u[:N_MOTORS] = pwm
        return np.asarray(f(x0, u, p)).ravel()

    lo, hi = params.pwm_idle_us, PWM_MAX_US
    if xdot(np.full(N_MOTORS, hi))[w_dot] >= 0.0:
        raise ExciteError(f"the model cannot hover: at {hi:.0f} us on every motor its thrust is below its weight "
                          f"(mass_kg = {params.mass_kg})")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if xdot(np.full(N_MOTORS, mid))[w_dot] > 0.0 else (lo, mid)
    pwm0 = 0.5 * (lo + hi)
    signs = mixer_signs(model)
    du = STICK_STEP * (PWM_MAX_US - PWM_MIN_US)
    eff = {}
    for k, a in enumerate(RATE_AXES):  # secant over +-du per motor, scaled to one unit of command through the mixer
        d = du * np.asarray(signs[a])
        eff[a] = float(loops.mix[k] * (xdot(pwm0 + d)[rates[k]] - xdot(pwm0 - d)[rates[k]]) / (2 * STICK_STEP))
    coll = float(-(xdot(np.full(N_MOTORS, pwm0 + du))[w_dot] - xdot(np.full(N_MOTORS, pwm0 - du))[w_dot])
                 / (2 * STICK_STEP))
    bad = [a for a, v in eff.items() if not v > 0.0]
    if bad or not coll > 0.0:
        raise ExciteError(f"the model's response to the mixer has the wrong sign or none on {', '.join(bad) or 'z'}"
                          f" (frame {params.frame!r})")
    return Hover(pwm0, eff, coll, signs, float(params.tau_motor_s))


# ------------------------------------------------------------------ loop transfer functions
def _poly(*coeffs: float) -> np.ndarray:
    return np.asarray(coeffs, dtype=float)


def _plant(gain: float, tau_s: float, delay_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``gain e^{-sT} / (s (τ s + 1))`` with a first-order Padé delay."""
    num, den = _poly(gain), np.polymul(_poly(1.0, 0.0), _poly(tau_s, 1.0) if tau_s > 0 else _poly(1.0))
    if delay_s > 0:
        num = np.polymul(num, _poly(-delay_s / 2, 1.0))
        den = np.polymul(den, _poly(delay_s / 2, 1.0))
    return num, den


def _pid(p: float, i: float, d: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``P + I/s + D s / (s/ω_d + 1)`` over a common denominator ``s (s/ω_d + 1)``."""
    wd = 2 * math.pi * cutoff_hz
    filt = _poly(1.0 / wd, 1.0)
    num = np.polyadd(np.polyadd(p * np.polymul(_poly(1.0, 0.0), filt), i * filt), _poly(d, 0.0, 0.0))
    return num, np.polymul(_poly(1.0, 0.0), filt)


def _closed(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unity feedback around ``num/den`` (a root at s = 0 common to both cancelled first: an absent I term)."""
    num, den = np.trim_zeros(np.atleast_1d(num), "f"), np.trim_zeros(np.atleast_1d(den), "f")
    while len(num) > 1 and len(den) > 1 and num[-1] == 0.0 and den[-1] == 0.0:
        num, den = num[:-1], den[:-1]
    return num, np.polyadd(den, num)


def _trim(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    num, den = np.trim_zeros(np.atleast_1d(num), "f"), np.trim_zeros(np.atleast_1d(den), "f")
    return num / den[0], den / den[0]


def _stable(den: np.ndarray) -> bool:
    return bool(np.all(np.real(np.roots(den)) < 0.0))


def bandwidth(num: np.ndarray, den: np.ndarray, order: int) -> float:
    """Natural frequency [rad/s] of a closed loop ``num/den`` that integrates its command ``order`` times (1: a rate
    or climb-rate response, 2: an attitude response): where its phase lag first reaches ``order`` x 45 deg, the
    corner ``1/τ`` of a first-order loop and ``ωn`` of a second-order one whatever its damping (the -3 dB point of a
    resonant loop moves up as its damping falls). The -3 dB bandwidth when the phase never gets there."""
    w = np.logspace(-2, 4, 6000)
    _, h = signal.freqs(num, den, worN=w)
    phase = np.unwrap(np.angle(h))
    lag = np.flatnonzero(phase - phase[0] <= -order * math.pi / 4)
    if lag.size:
        return float(w[lag[0]])
    ref = abs(np.polyval(num, 0.0) / np.polyval(den, 0.0))
    below = np.flatnonzero(np.abs(h) < ref / math.sqrt(2.0))
    return float(w[below[0]]) if below.size else float(w[-1])


def rate_axis(hover: Hover, loops: AutopilotLoops, delay_s: float, axis: str) -> tuple[np.ndarray, ...]:
    """``(gn, gd, cn, cd)``: plant ``G = gn/gd`` (normalised torque command -> body rate) and rate controller
    ``C = cn/cd`` of a rate axis (polynomials in s)."""
    k = RATE_AXES.index(axis)
    gn, gd = _plant(hover.effectiveness[axis], hover.tau_motor_s, delay_s)
    cn, cd = _pid(loops.rate_p[k], loops.rate_i[k], loops.rate_d[k], loops.d_cutoff_hz)
    return gn, gd, cn, cd


def attitude_response(hover: Hover, loops: AutopilotLoops, delay_s: float, axis: str, at: str,
                      w_rad_s: np.ndarray) -> np.ndarray:
    """``|angle / d|`` at ``w_rad_s`` of an injection ``d`` added at ``at`` (``"mixer"``: to the rate controller's
    output, per unit command; ``"rate"``: to the rate set-point, per rad/s) with the angle loop closed
    (``1 + G C (1 + P_a / s)`` in the denominator). Yaw: the heading the angle loop holds."""
    gn, gd, cn, cd = rate_axis(hover, loops, delay_s, axis)
    kp = loops.angle_p[RATE_AXES.index(axis)]
    s = 1j * np.asarray(w_rad_s, dtype=float)
    g, c = np.polyval(gn, s) / np.polyval(gd, s), np.polyval(cn, s) / np.polyval(cd, s)
    loop = 1.0 + g * c * (1.0 + kp / s)
    return np.abs((g if at == "mixer" else g * c) / (s * loop))


def axis_loops(hover: Hover, loops: AutopilotLoops, delay_s: float) -> dict[str, AxisLoop]:
    """The stick response of each axis (see the module docstring); ExciteError when a loop is unstable."""
    out: dict[str, AxisLoop] = {}
    tau = hover.tau_motor_s
    for k, a in enumerate(RATE_AXES):
        gn, gd, cn, cd = rate_axis(hover, loops, delay_s, a)
        rn, rd = _trim(*_closed(np.polymul(cn, gn), np.polymul(cd, gd)))
        if not _stable(rd):
            raise ExciteError(f"the {loops.name} {a} rate loop is unstable on this model (effectiveness "
                              f"{hover.effectiveness[a]:.0f} rad/s2, tau_motor_s {tau:g}, delay {delay_s:g} s): "
                              "its default gains do not fit this airframe; tune the rate loop first")
        rate_bw = bandwidth(rn, rd, 1)
        if a == "yaw":
            out[a] = AxisLoop(tuple(rn), tuple(rd), math.radians(loops.yaw_rate_max_deg_s), rate_bw, rate_bw)
            continue
        kp = loops.angle_p[k]
        an, ad = _trim(kp * rn, np.polyadd(np.polymul(_poly(1.0, 0.0), rd), kp * rn))
        if not _stable(ad):
            raise ExciteError(f"the {loops.name} {a} angle loop is unstable on this model; tune it first")
        out[a] = AxisLoop(tuple(an), tuple(ad), math.radians(loops.tilt_max_deg), bandwidth(an, ad, 2), rate_bw)
    gn, gd = _plant(1.0, tau, delay_s)  # commanded vertical acceleration -> climb rate
    cn, cd = _poly(loops.z_vel_p, loops.z_vel_i), _poly(1.0, 0.0)
    zn, zd = _trim(*_closed(np.polymul(cn, gn), np.polymul(cd, gd)))
    if not _stable(zd):
        raise ExciteError(f"the {loops.name} vertical-velocity loop is unstable on this model")
    out["throttle"] = AxisLoop(tuple(zn), tuple(zd), loops.climb_max_m_s, bandwidth(zn, zd, 1), None)
    return out


def _peak(lp: AxisLoop, sig: Signal, length_s: float, rate_hz: float) -> tuple[float, float]:
    """Peak |response| of the stick loop to a unit-stick ``sig`` (in the response's unit per unit of full scale),
    and for roll/pitch nothing else; for throttle the peak height change [m] too."""
    t = np.arange(0.0, length_s, 1.0 / rate_hz)
    _, y, _ = signal.lsim((lp.num, lp.den), sig(t), t)
    height = float(np.max(np.abs(np.cumsum(y) / rate_hz)))
    return float(np.max(np.abs(y))), height


def target_frequencies(loops_: dict[str, AxisLoop], opt: QuadExciteOptions) -> dict[str, float]:
    """Each axis's pulse centre frequency [rad/s]: its stick bandwidth, capped (see the module docstring)."""
    w_max = max_frequency_rad_s(opt.design_options())
    return {a: min(lp.bandwidth_rad_s, w_max) for a, lp in loops_.items()}


def _amplitude(axis: str, lp: AxisLoop, unit_peak: float, loops: AutopilotLoops, opt: QuadExciteOptions) -> float:
    """Stick amplitude (fraction of full stick) keeping the linear peak within the limits (module docstring)."""
    if axis in ("roll", "pitch"):
        limit = opt.attitude_fraction * math.radians(opt.roll_limit_deg)
    elif axis == "yaw":
        limit = opt.attitude_fraction * math.radians(opt.yaw_rate_limit_deg_s)
    else:
        limit = opt.attitude_fraction * opt.climb_limit_m_s
    stick = min(opt.max_stick, limit / max(unit_peak * lp.full_scale, 1e-12))
    if axis == "throttle":  # the climb-rate set-point starts at the deadzone's edge
        stick = min(opt.max_stick, loops.throttle_deadzone + stick * (1.0 - loops.throttle_deadzone))
        if stick <= loops.throttle_deadzone + 0.02:
            raise ExciteError(f"max_stick = {opt.max_stick:g} leaves the throttle stick inside the altitude-hold "
                              f"deadzone ({loops.throttle_deadzone:g}); raise it")
    return stick


def plan_quadrotor_excitation(params: QuadrotorParams | None = None, opt: QuadExciteOptions | None = None,
                              loops: AutopilotLoops | None = None) -> QuadExcitationPlan:
    """Plan stick manoeuvres for the quadrotor ``params`` (default: the F450 set) flown by ``opt.autopilot``'s
    loops (or ``loops``)."""
    opt = opt or QuadExciteOptions()
    bad = opt.problems()
    if bad:
        raise ExciteError("; ".join(bad))
    params = params or QuadrotorParams()
    loops = loops or LOOPS[opt.autopilot]
    hover = hover_point(params, loops)
    lps = axis_loops(hover, loops, opt.loop_delay_s)
    targets = target_frequencies(lps, opt)
    dopt = opt.design_options()
    blocks, t = [], 0.0
    specs = [(k, a) for k in opt.inputs for a in opt.axes if k != "drag" or a in DRAG_OF]
    for i, (kind, axis) in enumerate(specs, start=1):
        if kind == "drag":  # a doublet timed by the translational mode kd / m, held at most max_hold_s
            w_drag = getattr(params, DRAG_OF[axis]) / params.mass_kg
            dt = pulse_unit("doublet", max(w_drag, spectrum_centre(PULSES["doublet"]) / opt.max_hold_s), dopt)
            unit = steps("doublet", dt)
        else:
            dt = pulse_unit(kind, targets[axis], dopt)
            unit = steps(kind, dt)
        length = unit.duration_s + opt.tail_s
        lp = lps[axis]
        peak_unit, height_unit = _peak(lp, unit, length, opt.rate_hz)
        stick = _amplitude(axis, lp, peak_unit, loops, opt)
        if kind == "drag" and axis != "throttle":  # the tilt held for dt builds about g tan(tilt) dt of speed
            tilt_cap = math.atan(opt.speed_limit_m_s / (G0_M_S2 * dt)) / (peak_unit * lp.full_scale)
            stick = min(stick, tilt_cap)
        effective = stick if axis != "throttle" else (stick - loops.throttle_deadzone) / (1 - loops.throttle_deadzone)
        peak = peak_unit * effective * lp.full_scale
        predicted = ({"tilt_deg": math.degrees(peak)} if axis in ("roll", "pitch") else
                     {"yaw_rate_deg_s": math.degrees(peak)} if axis == "yaw" else
                     {"climb_m_s": peak, "height_m": height_unit * effective * lp.full_scale})
        if kind == "drag" and axis != "throttle":
            predicted["speed_m_s"] = G0_M_S2 * math.tan(peak) * dt
        t_exc = t + opt.settle_s
        end = t_exc + length
        blocks.append(Block(i, axis, kind, scale_signals({axis: unit}, {axis: stick}), t, t_exc, end, dt, predicted))
        t = end + opt.recovery_s
    return QuadExcitationPlan(params, opt, loops, hover, lps, targets, blocks)


__all__ = ["ARDUCOPTER_LOOPS", "AUTOPILOTS", "AXES", "INPUT_KINDS", "LOOPS", "PX4_LOOPS", "AutopilotLoops", "AxisLoop",
           "Hover", "QuadExcitationPlan", "QuadExciteOptions", "attitude_response", "axis_loops", "bandwidth",
           "hover_point", "mixer_signs", "plan_quadrotor_excitation", "rate_axis", "target_frequencies"]

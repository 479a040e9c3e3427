"""Check a planned quadrotor excitation before flying it: fly the sticks in closed loop on the model, then ask the
output-error estimator how well the records would separate the quadrotor's parameters.

The flight: the quadrotor model (the same CasADi equations the FMU compiles, one RK4 step per plan sample) starts
hovering in the air; an autopilot of PX4's / ArduCopter's structure (:class:`~identification.excite.quadrotor.
AutopilotLoops`: sticks -> attitude and yaw-rate set-points -> angle P -> rate PID with the derivative on the
measurement, low-passed -> mixer; throttle stick -> climb-rate set-point, altitude hold inside the deadzone ->
PI on the commanded acceleration -> collective with tilt compensation) flies the plan's sticks, computed once per
sample. The records are cut as an identification would cut a log: one output-error manoeuvre per block (hand-over
to end), inputs the four motor PWMs, outputs body rates and specific force, with per-block initial rates and body
velocities and output biases estimated as nuisance parameters.

Two sets are checked, each from the blocks that move it (figures as :mod:`identification.excite.check`):

- ``rotation``: ``Jx_kg_m2``, ``Jy_kg_m2`` (the arm's moment effectiveness over inertia, the arm length fixed),
  ``tau_motor_s``, ``b_drag_N_m_s2`` (yaw torque with ``Jz_kg_m2`` fixed: the data give b/(k Jz), the ratio) from the
  roll, pitch and yaw blocks;
- ``drag``: ``kd_x_N_s_m``, ``kd_y_N_s_m``, ``kd_z_N_s_m`` from the roll, pitch and throttle blocks.

A model without motor lag (``tau_motor_s`` = 0) has no sensitivity to it: the check then flies and evaluates at
:data:`CHECK_TAU_S` and says so.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fmu_models.common.model import NumericCall
from fmu_models.common.simulate import Simulator
from fmu_models.fmi.jit import compiled
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from identification.estimation.identifiability import CONDITION_LIMIT, CORRELATION_LIMIT, normalised
from identification.estimation.oem import RELATIVE_STD_WARN, Manoeuvre, OutputErrorEstimator
from identification.excite.check import NOISE_SIGMA, SetCheck, conditioning
from identification.excite.design import ExciteError
from identification.excite.quadrotor import (
    AXES,
    IN_AIR_DOWN_M,
    PWM_MAX_US,
    PWM_MIN_US,
    RATE_AXES,
    QuadExcitationPlan,
)

ROTATION_SET = ("Jx_kg_m2", "Jy_kg_m2", "tau_motor_s", "b_drag_N_m_s2")
DRAG_SET = ("kd_x_N_s_m", "kd_y_N_s_m", "kd_z_N_s_m")
#: each checked set and the stick axes whose blocks move it
SETS = {"rotation": (ROTATION_SET, ("roll", "pitch", "yaw")), "drag": (DRAG_SET, ("roll", "pitch", "throttle"))}
OUTPUTS = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s", "accel_body_x_m_s2", "accel_body_y_m_s2",
           "accel_body_z_m_s2")
NUISANCE_STATES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s", "vel_body_x_m_s", "vel_body_y_m_s",
                   "vel_body_z_m_s")
CHECK_TAU_S = 0.02  #: motor time constant the check uses when the parameters have none [s]
RATE_I_LIMIT = 0.3  #: rate-loop integrator clamp [normalised torque command]
ACCEL_LIMIT_M_S2 = 6.0  #: commanded vertical acceleration clamp [m/s2]
DIVERGED_RAD = math.radians(80.0)  #: a check flight tilting beyond this has lost control


@dataclass
class QuadFlight:
    """Closed-loop records at the plan rate: time [s], state (N+1 x nx), inputs (N x nu), outputs (N x ny), the
    sticks flown (N x 4), peaks, and the parameter vector flown."""

    t_s: np.ndarray
    x: np.ndarray
    u: np.ndarray
    y: np.ndarray
    output_names: tuple[str, ...]
    sticks: np.ndarray
    p: np.ndarray
    max_tilt_deg: float
    max_yaw_rate_deg_s: float
    height_range_m: float
    notes: list[str] = field(default_factory=list)


def _wrap(a: float) -> float:
    return math.remainder(a, 2 * math.pi)


def fly_closed_loop(plan: QuadExcitationPlan, compile: bool = True) -> QuadFlight:
    """Fly ``plan``'s sticks on the model under the autopilot loops (see the module docstring); ``compile``: the
    model step compiled to C once and cached (:func:`fmu_models.fmi.jit.compiled`)."""
    lp, h = plan.loops, plan.hover
    params = plan.params
    notes = []
    if params.tau_motor_s <= 0.0:
        params = dataclasses.replace(params, tau_motor_s=CHECK_TAU_S)
        notes.append(f"tau_motor_s = 0 in the parameters has no sensitivity: flown and checked at {CHECK_TAU_S:g} s")
    model = QuadrotorModel(params)
    sim = Simulator(model)
    step = NumericCall(compiled([sim.step], "excite_quadrotor_step")[0] if compile else sim.step)
    p = sim.params(init_pos_down_m=IN_AIR_DOWN_M)
    dt = 1.0 / plan.options.rate_hz
    t = plan.times()
    sticks = plan.sticks(t)
    span = PWM_MAX_US - PWM_MIN_US
    a_hover = (h.pwm_us - PWM_MIN_US) / span
    u = sim.full_inputs(sim.inputs(**{f"pwm_{i + 1}_us": h.pwm_us for i in range(N_MOTORS)}))
    x, y = sim.initial(u, p)
    out = {n: model.outputs.index[n] for n in ("roll_rad", "pitch_rad", "yaw_rad", "vel_down_m_s", "altitude_m",
                                               "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")}
    tilt_max, yaw_max = math.radians(lp.tilt_max_deg), math.radians(lp.yaw_rate_max_deg_s)
    wd = 2 * math.pi * lp.d_cutoff_hz
    alpha = dt * wd / (1 + dt * wd)  # first-order low-pass of the rate derivative
    integ, d_filt = np.zeros(3), np.zeros(3)
    prev_rate = np.array([y[out[n]] for n in ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")])
    yaw_sp, alt_sp, z_int = float(y[out["yaw_rad"]]), float(y[out["altitude_m"]]), 0.0
    xs, us, ys = [x], [], []
    for k in range(len(t)):
        st = sticks[k]
        rate = np.array([y[out[n]] for n in ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")])
        roll, pitch, yaw = (float(y[out[n]]) for n in ("roll_rad", "pitch_rad", "yaw_rad"))
        yaw_rate_ff = st[2] * yaw_max
        yaw_sp = _wrap(yaw_sp + yaw_rate_ff * dt) if abs(st[2]) > 0 else yaw_sp
        rate_sp = np.array([lp.angle_p[0] * (st[0] * tilt_max - roll), lp.angle_p[1] * (st[1] * tilt_max - pitch),
                            yaw_rate_ff + lp.angle_p[2] * _wrap(yaw_sp - yaw)])
        err = rate_sp - rate
        integ = np.clip(integ + np.asarray(lp.rate_i) * err * dt, -RATE_I_LIMIT, RATE_I_LIMIT)
        d_filt = d_filt + alpha * ((rate - prev_rate) / dt - d_filt)
        prev_rate = rate
        cmd = np.clip(np.asarray(lp.rate_p) * err + integ - np.asarray(lp.rate_d) * d_filt, -1.0, 1.0)
        climb = -float(y[out["vel_down_m_s"]])
        s, dz = float(st[3]), lp.throttle_deadzone
        if abs(s) <= dz:
            climb_sp = lp.z_pos_p * (alt_sp - float(y[out["altitude_m"]]))
        else:
            climb_sp = math.copysign((abs(s) - dz) / (1 - dz), s) * (lp.climb_max_m_s if s > 0 else lp.descent_max_m_s)
            alt_sp = float(y[out["altitude_m"]])
        z_int = min(max(z_int + lp.z_vel_i * (climb_sp - climb) * dt, -ACCEL_LIMIT_M_S2), ACCEL_LIMIT_M_S2)
        acc_up = min(max(lp.z_vel_p * (climb_sp - climb) + z_int, -ACCEL_LIMIT_M_S2), ACCEL_LIMIT_M_S2)
        tilt = max(math.cos(roll) * math.cos(pitch), 0.5)
        a_coll = (a_hover + acc_up / h.collective_m_s2) / tilt
        act = np.full(N_MOTORS, a_coll)
        for j, a in enumerate(RATE_AXES):
            act += lp.mix[j] * np.asarray(h.signs[a]) * cmd[j]
        u = u.copy()
        u[:N_MOTORS] = np.clip(PWM_MIN_US + act * span, PWM_MIN_US, PWM_MAX_US)
        x, y = step(x, u, p, dt)
        if not (np.all(np.isfinite(x)) and max(abs(y[out["roll_rad"]]), abs(y[out["pitch_rad"]])) < DIVERGED_RAD):
            raise ExciteError(f"the closed-loop check flight diverged at {t[k]:.2f} s of the plan (tilt beyond "
                              f"{math.degrees(DIVERGED_RAD):.0f} deg or a non-finite state): the {lp.name} loops at "
                              f"{plan.options.rate_hz:g} Hz do not hold this airframe; raise --rate or tune the loops")
        xs.append(x)
        us.append(u)
        ys.append(y)
    X, U, Y = np.array(xs), np.array(us), np.array(ys)
    names = tuple(model.outputs.names)
    tilt_deg = np.degrees(np.maximum(np.abs(Y[:, out["roll_rad"]]), np.abs(Y[:, out["pitch_rad"]])))
    alt = Y[:, out["altitude_m"]]
    return QuadFlight(t, X, U, Y, names, sticks, p, float(np.max(tilt_deg)),
                      float(np.degrees(np.max(np.abs(Y[:, out["rate_body_z_rad_s"]])))), float(np.ptp(alt)), notes)


def block_manoeuvres(plan: QuadExcitationPlan, flight: QuadFlight, axes: Sequence[str],
                     outputs: Sequence[str] = OUTPUTS) -> tuple[list[Manoeuvre], list[int]]:
    """One manoeuvre per block on one of ``axes``: hand-over to end, inputs the PWMs and voltage."""
    rate = plan.options.rate_hz
    cols = [flight.output_names.index(n) for n in outputs]
    data, used = [], []
    for b in plan.blocks:
        if b.axis not in axes:
            continue
        k0, k1 = round(b.start_s * rate), min(round(b.end_s * rate), len(flight.u))
        data.append(Manoeuvre(flight.x[k0], flight.u[k0:k1], flight.y[k0:k1][:, cols], 1.0 / rate, f"block {b.index}"))
        used.append(b.index)
    return data, used


@dataclass
class QuadSetCheck:
    """The identifiability figures of one set (:class:`~identification.excite.check.SetCheck`) and each parameter's
    Cramér-Rao standard deviation over its value (white residuals of :data:`NOISE_SIGMA`, nuisance included): a
    parameter the blocks do not move has a huge one even when the normalised condition number looks small."""

    figures: SetCheck
    relative_std: dict[str, float]

    @property
    def ok(self) -> bool:
        return self.figures.ok and max(self.relative_std.values()) <= RELATIVE_STD_WARN

    @property
    def names(self) -> list[str]:
        return self.figures.names

    @property
    def condition_number(self) -> float:
        return self.figures.condition_number

    @property
    def max_abs_r(self) -> float:
        return self.figures.max_abs_r

    def line(self) -> str:
        f = self.figures
        rel = ", ".join(f"{n} {100 * v:.2g} %" for n, v in self.relative_std.items())
        return (f"condition number {f.condition_number:.3g} (normalised information {f.condition_number_info:.3g}), "
                f"max |r| {f.max_abs_r:.3f} ({f.max_pair[0]} ~ {f.max_pair[1]}), Cramer-Rao std / value: {rel}; "
                f"over blocks {f.blocks}: {'well conditioned' if self.ok else 'NOT well conditioned'}")

    def as_dict(self) -> dict[str, object]:
        f = self.figures
        return {"names": f.names, "condition_number": f.condition_number,
                "condition_number_normalised_information": f.condition_number_info, "max_abs_r": f.max_abs_r,
                "max_pair": list(f.max_pair), "relative_std": self.relative_std, "blocks": f.blocks,
                "condition_limit": CONDITION_LIMIT, "correlation_limit": CORRELATION_LIMIT,
                "relative_std_limit": RELATIVE_STD_WARN, "well_conditioned": self.ok}


def cramer_rao_std(M: np.ndarray, n: int) -> np.ndarray:
    """``sqrt(diag(Mg⁻¹))`` of the first ``n`` quantities, ``Mg`` their information after the nuisance parameters are
    profiled out (Schur complement, as the condition number), inverted through the correlation-normalised matrix with
    directions without information at +inf (a pseudo-inverse would report an unexcited parameter as known exactly)."""
    Mg = M[:n, :n] - M[:n, n:] @ np.linalg.pinv(M[n:, n:]) @ M[n:, :n] if M.shape[0] > n else M[:n, :n]
    Ms, dinv = normalised(0.5 * (Mg + Mg.T))
    ev, vec = np.linalg.eigh(Ms)
    floor = 1e-12 * max(float(ev[-1]), 1e-300)
    inv_ev = np.where(ev > floor, 1.0 / np.maximum(ev, floor), np.inf)
    with np.errstate(invalid="ignore"):
        var = np.where(vec ** 2 > 1e-24, vec ** 2 * inv_ev, 0.0).sum(axis=1)
    return np.where(dinv > 0, np.sqrt(var) * dinv, np.inf)


def check_set(plan: QuadExcitationPlan, flight: QuadFlight, names: Sequence[str], axes: Sequence[str],
              compile: bool = False) -> QuadSetCheck:
    """Condition number, correlations and relative Cramér-Rao std of ``names`` from the blocks that move ``axes``."""
    model = QuadrotorModel(dataclasses.replace(plan.params, tau_motor_s=max(plan.params.tau_motor_s, CHECK_TAU_S)))
    data, used = block_manoeuvres(plan, flight, axes)
    if not data:
        raise ValueError(f"the plan has no block moving {', '.join(axes)}")
    oe = OutputErrorEstimator(model, flight.p, list(names), list(OUTPUTS), estimate_states=NUISANCE_STATES,
                              estimate_biases=OUTPUTS, compile=compile)
    weight = np.diag([1.0 / NOISE_SIGMA[n] ** 2 for n in OUTPUTS])
    M, all_names = oe.information(data, None, weight)
    if not np.all(np.isfinite(M)):
        raise ExciteError(f"the output-error sensitivities of the check flight are not finite at "
                          f"{plan.options.rate_hz:g} Hz (one RK4 step per sample): raise --rate")
    std = cramer_rao_std(M, len(names))
    value = {n: abs(float(flight.p[model.params.index[n]])) for n in names}
    rel = {n: float(std[i] / value[n]) if value[n] > 0 else float("inf") for i, n in enumerate(names)}
    return QuadSetCheck(conditioning(M, all_names, names, used), rel)


def check_quadrotor_plan(plan: QuadExcitationPlan, compile: bool = False) -> tuple[QuadFlight, dict[str, QuadSetCheck]]:
    """Fly ``plan`` in closed loop and check each set of :data:`SETS` whose axes the plan moves."""
    flight = fly_closed_loop(plan, compile)
    checks = {}
    for key, (names, axes) in SETS.items():
        if set(axes) & set(plan.options.axes):
            checks[key] = check_set(plan, flight, names, axes, compile)
    return flight, checks


__all__ = ["AXES", "DRAG_SET", "OUTPUTS", "ROTATION_SET", "SETS", "QuadFlight", "QuadSetCheck", "block_manoeuvres",
           "check_quadrotor_plan", "check_set", "cramer_rao_std", "fly_closed_loop"]

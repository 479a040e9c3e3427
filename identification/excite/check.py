"""Check a planned excitation before flying it: fly the plan in closed loop on the fixed-wing model, then ask the
output-error estimator how well the records would separate the derivatives.

The flight: the model (the same CasADi equations the FMU compiles, one RK4 step per sample) starts at the
plan's trim; a PD attitude hold (roll and pitch to the trim attitude, a yaw damper) acts the whole time, as a
stabilising mode would, and each block's deflections are added on top of its output. The records are then
treated as ``identify aero`` treats a log: one output-error manoeuvre per block, inputs = the recorded surface
commands (controller plus excitation), outputs = :data:`fmu_models.signals.names.FIXED_WING_FIT_OUTPUTS`, per-block
initial
rates and output biases estimated as nuisance parameters.

Figures, from the information matrix ``M`` of the weighted output sensitivities (measurement standard deviations
:data:`NOISE_SIGMA`), of every estimated quantity:

- ``condition_number``: the project's identifiability figure
(:func:`identification.estimation.identifiability.analyse`):
  ``sqrt(λmax / λmin)`` of ``D Mg D``, ``Mg`` the derivatives' block after the nuisance parameters are profiled
  out (Schur complement), ``D = diag(Mg)^-1/2`` (the condition number of the column-normalised sensitivities);
- ``condition_number_info``: ``λmax / λmin`` of the same correlation-normalised information matrix ``D Mg D``
  (the square of the former; the stricter reading);
- ``max_abs_r``: the largest |correlation| (from ``M⁻¹``) between a derivative and any other estimated quantity.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmu_models.common.model import NumericCall, step_function
from fmu_models.fixed_wing.model import SURFACE_LIMIT_RAD, FixedWingModel
from fmu_models.signals.names import FIXED_WING_FIT_OUTPUTS as DEFAULT_OUTPUTS
from identification.estimation.identifiability import CONDITION_LIMIT, CORRELATION_LIMIT, analyse, normalised
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.excite.design import ExcitationPlan

LATERAL_SET = ("C_ell_p", "C_ell_beta", "C_ell_r", "C_ell_delta_a", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta")
LONGITUDINAL_SET = ("C_m_alpha", "C_m_q", "C_m_delta_e", "C_L_alpha")
#: airspeed: parasitic and induced drag, static thrust (seen in airspeed and longitudinal specific force); from the
#: throttle and elevator blocks. Without a throttle block C_D_p ~ C_T0 reach |r| 0.96 on the Aerosonde test plan
SPEED_SET = ("C_D_p", "e_oswald", "C_T0")
#: measurement standard deviations (small-UAV autopilot: EKF attitude, gyros, accelerometers, airspeed)
NOISE_SIGMA = {"roll_rad": 0.01, "pitch_rad": 0.01, "rate_body_x_rad_s": 0.01, "rate_body_y_rad_s": 0.01,
               "rate_body_z_rad_s": 0.01, "accel_body_x_m_s2": 0.2, "accel_body_y_m_s2": 0.2,
               "accel_body_z_m_s2": 0.2, "airspeed_m_s": 0.5}
NUISANCE_STATES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")
NUISANCE_BIASES = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s", "accel_body_x_m_s2",
                   "accel_body_y_m_s2", "accel_body_z_m_s2")


@dataclass(frozen=True)
class Gains:
    """PD attitude hold [rad surface per rad or per rad/s], about the trim deflections."""

    roll_p: float = 0.5
    roll_d: float = 0.03
    pitch_p: float = 0.5
    pitch_d: float = 0.05
    yaw_damper: float = 0.1


@dataclass
class Flight:
    """Closed-loop records at the plan rate: time [s], state (N+1 x nx), inputs (N x 4), outputs (N x ny)."""

    t_s: np.ndarray
    x: np.ndarray
    u: np.ndarray
    y: np.ndarray
    output_names: tuple[str, ...]
    max_roll_deg: float
    max_pitch_dev_deg: float


@dataclass
class SetCheck:
    """Identifiability of one parameter set from the planned records."""

    names: list[str]
    condition_number: float
    condition_number_info: float
    max_abs_r: float
    max_pair: tuple[str, str]
    blocks: list[int]

    @property
    def ok(self) -> bool:
        return self.condition_number < CONDITION_LIMIT and self.max_abs_r <= CORRELATION_LIMIT

    def line(self) -> str:
        return (f"condition number {self.condition_number:.3g} (normalised information {self.condition_number_info:.3g}"
                f"), max |r| {self.max_abs_r:.3f} ({self.max_pair[0]} ~ {self.max_pair[1]}) over blocks "
                f"{self.blocks}: {'well conditioned' if self.ok else 'NOT well conditioned'}")


def _roll_pitch(q: np.ndarray) -> tuple[float, float]:
    """3-2-1 roll and pitch [rad] of the quaternion [w, x, y, z]."""
    w, a, b, c = q
    return (float(np.arctan2(2 * (w * a + b * c), 1 - 2 * (a * a + b * b))),
            float(np.arcsin(np.clip(2 * (w * b - c * a), -1.0, 1.0))))


def fly_closed_loop(plan: ExcitationPlan, gains: Gains = Gains(), p: np.ndarray | None = None) -> Flight:
    """Fly ``plan`` on the model with parameters ``p`` (default: the plan's) under a PD attitude hold."""
    model = FixedWingModel(plan.params)
    p = np.array(model.params.starts()) if p is None else np.asarray(p, float)
    step = NumericCall(step_function(model))
    t = plan.times()
    dt = 1.0 / plan.options.rate_hz
    du = plan.deflection(t)
    tr = plan.trim
    x = np.array(tr.x, dtype=float)
    _, theta0 = _roll_pitch(x[6:10])
    xs, us, ys = [x], [], []
    for k in range(len(t)):
        roll, pitch = _roll_pitch(x[6:10])
        pr, qr, rr = x[10:13]
        u = tr.u + du[k] + np.array([gains.roll_p * (0.0 - roll) - gains.roll_d * pr,
                                     -gains.pitch_p * (theta0 - pitch) + gains.pitch_d * qr,
                                     gains.yaw_damper * rr, 0.0])
        u[:3] = np.clip(u[:3], -SURFACE_LIMIT_RAD, SURFACE_LIMIT_RAD)
        x, y = step(x, u, p, dt)
        xs.append(x)
        us.append(u)
        ys.append(y)
    X, Y = np.array(xs), np.array(ys)
    names = tuple(model.outputs.names)
    roll_i, pitch_i = names.index("roll_rad"), names.index("pitch_rad")
    return Flight(t, X, np.array(us), Y, names, float(np.degrees(np.max(np.abs(Y[:, roll_i])))),
                  float(np.degrees(np.max(np.abs(Y[:, pitch_i] - theta0)))))


def block_manoeuvres(plan: ExcitationPlan, flight: Flight, axes: Sequence[str],
                     outputs: Sequence[str] = DEFAULT_OUTPUTS) -> tuple[list[Manoeuvre], list[int]]:
    """One manoeuvre per block that moves one of ``axes``: hand-over to end, as ``identify aero`` would cut it."""
    rate = plan.options.rate_hz
    cols = [flight.output_names.index(n) for n in outputs]
    out, used = [], []
    for b in plan.blocks:
        if not set(b.signals) & set(axes):
            continue
        k0, k1 = round(b.start_s * rate), round(b.end_s * rate)
        out.append(Manoeuvre(flight.x[k0], flight.u[k0:k1], flight.y[k0:k1][:, cols], 1.0 / rate, f"block {b.index}"))
        used.append(b.index)
    return out, used


def check_set(plan: ExcitationPlan, flight: Flight, names: Sequence[str], axes: Sequence[str],
              outputs: Sequence[str] = DEFAULT_OUTPUTS, compile: bool = False) -> SetCheck:
    """Condition number and correlations of ``names`` from the blocks that move ``axes`` (see module docstring)."""
    model = FixedWingModel(plan.params)
    p = np.array(model.params.starts())
    data, used = block_manoeuvres(plan, flight, axes, outputs)
    if not data:
        raise ValueError(f"the plan has no block moving {', '.join(axes)}")
    oe = OutputErrorEstimator(model, p, list(names), list(outputs), estimate_states=NUISANCE_STATES,
                              estimate_biases=[b for b in NUISANCE_BIASES if b in outputs], compile=compile)
    weight = np.diag([1.0 / NOISE_SIGMA[n] ** 2 for n in outputs])
    M, all_names = oe.information(data, None, weight)
    return conditioning(M, all_names, names, used)


def conditioning(M: np.ndarray, all_names: Sequence[str], names: Sequence[str], blocks: list[int]) -> SetCheck:
    """The figures of the module docstring for the first ``len(names)`` quantities of information matrix ``M``
    (over ``all_names``: the set, then the nuisance parameters), from the records of ``blocks``."""
    all_names = list(all_names)
    ident = analyse(M, all_names, len(names))
    n = len(names)
    r = np.abs(ident.correlation[:n].copy())
    r[np.arange(n), np.arange(n)] = 0.0
    i, k = np.unravel_index(int(np.argmax(r)), r.shape)
    Mg = M[:n, :n] - M[:n, n:] @ np.linalg.pinv(M[n:, n:]) @ M[n:, :n]
    ev = np.linalg.eigvalsh(normalised(0.5 * (Mg + Mg.T))[0])
    return SetCheck(list(names), ident.condition_number, float(ev[-1] / ev[0]) if ev[0] > 0 else float("inf"),
                    float(r[i, k]), (all_names[i], all_names[k]), blocks)


def check_plan(plan: ExcitationPlan, gains: Gains = Gains()) -> tuple[Flight, dict[str, SetCheck]]:
    """Fly ``plan`` in closed loop and check the lateral and the longitudinal set, and the speed set when the
    plan has a throttle block."""
    flight = fly_closed_loop(plan, gains)
    checks = {}
    if set(plan.options.surfaces) & {"aileron", "rudder"}:
        checks["lateral"] = check_set(plan, flight, LATERAL_SET, ("aileron", "rudder"))
    if "elevator" in plan.options.surfaces:
        checks["longitudinal"] = check_set(plan, flight, LONGITUDINAL_SET, ("elevator",))
    if any(b.axis == "throttle" for b in plan.blocks):
        checks["speed"] = check_set(plan, flight, SPEED_SET, ("throttle", "elevator"))
    return flight, checks


__all__ = ["LATERAL_SET", "LONGITUDINAL_SET", "SPEED_SET", "Flight", "Gains", "SetCheck", "check_plan", "check_set",
           "conditioning", "fly_closed_loop"]

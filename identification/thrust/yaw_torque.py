"""Yaw torque per thrust of a quadrotor from the logged yaw response, by output error.

The quadrotor FMU's yaw axis (paper 000 eq. 10, FRD, Jx = Jy so the gyroscopic and Euler terms vanish
about z) is ``Jz dr/dt = -sum_i s_i b Omega_i^2 = -(b/k) sum_i s_i T_i``: only the ratio ``c = b/k`` [m]
(fan torque per newton of thrust) matters, with ``T_i`` from the identified thrust model. ``c`` is
estimated by :class:`identification.estimation.oem.OutputErrorEstimator` on that one-state model, replaying the
logged PWM over short windows that each start at the logged yaw rate; the Cramer-Rao bound comes with it.
The model's output is linear in ``c``, so the fit is global and can only improve on ``c = 0`` (holding
the yaw rate). The parameter file gets ``b_drag_N_m_s2 = c k_thrust_N_s2`` (``k`` stays the one that sets
``Omega_i = sqrt(T_i / k)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from fmu_models.common.model import Layout, Variable
from fmu_models.quadrotor.params import QuadrotorParams, motor_layout

WINDOW_S = 2.0  #: replay window [s] (the validation tool's default window)
C_BOUNDS_M = (-1.0, 1.0)  #: search range of c = b/k [m] (F450-class: ~0.01-0.05 m)


class YawAxisModel:
    """One-state yaw model in the ``VehicleModel`` form: input ``sum_i s_i T_i`` [N], output yaw rate."""

    name = "quadrotor_yaw_axis"
    description = "yaw axis of the quadrotor model: Jz dr/dt = -(b/k) sum s_i T_i"

    def __init__(self, jz_kg_m2: float, c0_m: float) -> None:
        self.states = Layout((Variable("rate_z_rad_s", "rad/s", "yaw rate, body z"),))
        self.state_limits = (1e3,)
        self.inputs = Layout((Variable("spin_thrust_N", "N", "sum_i s_i T_i (s_i = +1 clockwise)"),))
        self.params = Layout((
            Variable("torque_per_thrust_m", "m", "yaw torque per thrust b/k", c0_m),
            Variable("Jz_kg_m2", "kg.m2", "inertia about body z", jz_kg_m2, 1e-6, None),
        ))
        self.outputs = Layout((Variable("rate_z_rad_s", "rad/s", "yaw rate, body z"),))

    def derivatives(self, t: Any, x: Any, u: Any, p: Any) -> Any:
        return ca.vertcat(-p[0] * u[0] / p[1])

    def outputs_fn(self, x: Any, u: Any, p: Any) -> Any:
        return ca.vertcat(x[0])

    def initial_state(self, p: Any, u: Any) -> Any:
        return ca.vertcat(0.0)

    def post_step(self, x: Any, u: Any, p: Any) -> Any:
        return x


@dataclass(frozen=True)
class YawResult:
    """``c = b/k`` [m] with its Cramer-Rao bound, the ``b`` it gives, and replayed yaw-rate RMSEs [rad/s]."""

    torque_per_thrust_m: float
    crb_std_m: float
    b_drag_N_m_s2: float
    rmse_identified_rad_s: float
    rmse_hold_rad_s: float
    rmse_default_rad_s: float
    n_windows: int

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def windows(t_s: np.ndarray, segment: np.ndarray, spin_thrust_N: np.ndarray, rate: np.ndarray,
            dt_s: float) -> list[Any]:
    """Manoeuvres of ``WINDOW_S`` inside each airborne segment: x0 = logged rate, y = the rates after."""
    from identification.estimation.oem import Manoeuvre

    n = max(3, round(WINDOW_S / dt_s))
    out = []
    for s in np.unique(segment[segment >= 0]):
        idx = np.flatnonzero(segment == s)
        for k0 in range(0, idx.size - n, n):
            w = idx[k0:k0 + n + 1]
            if np.ptp(t_s[w]) > 1.5 * n * dt_s:
                continue  # a gap inside: not one continuous replay
            out.append(Manoeuvre(np.array([rate[w[0]]]), spin_thrust_N[w[:-1], None], rate[w[1:], None], dt_s))
    return out


def replay(ms: list[Any], c_m: float, jzz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replayed and logged yaw rate [rad/s] over all windows (exact discrete solution of the linear model,
    held inputs), and the index where each window starts (blocks for a skill interval)."""
    pred = [m.x0[0] - np.cumsum(c_m * m.u[:, 0] / jzz) * m.dt_s for m in ms]
    starts = np.cumsum([0] + [len(p) for p in pred[:-1]])
    return np.concatenate(pred), np.concatenate([m.y[:, 0] for m in ms]), starts


def replay_rmse(ms: list[Any], c_m: float, jzz: float) -> float:
    """RMSE of the replayed yaw rate [rad/s] (see :func:`replay`)."""
    pred, logged = replay(ms, c_m, jzz)[:2]
    return float(np.sqrt(np.mean((pred - logged) ** 2)))


def identify_yaw_torque(ms: list[Any], params: QuadrotorParams) -> YawResult:
    """Output-error estimate of ``c = b/k`` on the windows ``ms``; ``params`` give Jz, k and the default b."""
    try:
        from identification.estimation.oem import OutputErrorEstimator as Estimator
    except ImportError:  # older name of the same class
        from identification.estimation.oem import OutputError as Estimator  # type: ignore[attr-defined,no-redef]

    if not ms:
        raise ValueError("no continuous airborne window of yaw data to identify the yaw torque from")
    c_default = params.b_drag_N_m_s2 / params.k_thrust_N_s2
    model = YawAxisModel(params.Jz_kg_m2, c_default)
    est = Estimator(model, model.params.starts(), ["torque_per_thrust_m"], ["rate_z_rad_s"],
                    bounds={"torque_per_thrust_m": C_BOUNDS_M}, compile=False, bound="ar")
    e = est.estimate(ms, weight=np.eye(1))
    c = float(e.values[0])
    c_fmu = max(c, 0.0)  # b >= 0 in the FMU: a negative c (wrong-way response) degrades to holding
    jzz = params.Jz_kg_m2
    return YawResult(c, float(e.std[0]), c_fmu * params.k_thrust_N_s2, replay_rmse(ms, c_fmu, jzz),
                     replay_rmse(ms, 0.0, jzz), replay_rmse(ms, c_default, jzz), len(ms))


def spin_thrust(motor_thrust_N: np.ndarray, frame: str = "x") -> np.ndarray:
    """``sum_i s_i T_i`` [N] per sample from per-motor thrust (N, 4), spins of ``motor_layout(frame)``."""
    _, spin = motor_layout(frame)
    return np.asarray(motor_thrust_N, float) @ np.asarray(spin, float)

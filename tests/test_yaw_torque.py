"""Yaw torque and yaw-rate damping by output error on synthetic windows with a known truth."""

from __future__ import annotations

import numpy as np

from fmu_models.quadrotor.params import QuadrotorParams
from identification.oem import Manoeuvre
from identification.yaw_torque import identify_yaw_torque, replay

C_TRUE_M, KD_TRUE_N_M_S = 0.004, 0.015  # about what the Erle flights give
DT_S, N_STEPS = 0.1, 20  # 2 s windows at 10 Hz, as the DataFlash logs


def synthetic_windows(rng: np.random.Generator, n_windows: int, noise_rad_s: float) -> list[Manoeuvre]:
    """Windows of ``Jz dr/dt = -c u - kd r`` (exact discrete solution, held inputs) with white output noise."""
    jz = QuadrotorParams().Jz_kg_m2
    out = []
    for _ in range(n_windows):
        u = np.repeat(rng.normal(0.0, 1.0, N_STEPS // 4), 4)[:, None]  # spin thrust sum s_i T_i [N], 0.4 s steps
        x0 = np.array([rng.normal(0.0, 0.5)])
        clean = Manoeuvre(x0, u, np.zeros((N_STEPS, 1)), DT_S)
        y = replay([clean], C_TRUE_M, jz, KD_TRUE_N_M_S)[0] + rng.normal(0.0, noise_rad_s, N_STEPS)
        out.append(Manoeuvre(x0, u, y[:, None], DT_S))
    return out


def test_output_error_recovers_the_yaw_torque_and_damping_within_their_bounds() -> None:
    ms = synthetic_windows(np.random.default_rng(3), 120, 0.05)
    r = identify_yaw_torque(ms, QuadrotorParams())
    assert abs(r.torque_per_thrust_m - C_TRUE_M) < 4.0 * r.crb_std_m < 0.2 * C_TRUE_M
    assert abs(r.kd_yaw_N_m_s - KD_TRUE_N_M_S) < 4.0 * r.crb_std_kd_N_m_s < 0.5 * KD_TRUE_N_M_S
    assert r.rmse_identified_rad_s < r.rmse_hold_rad_s
    assert r.b_drag_N_m_s2 == QuadrotorParams().k_thrust_N_s2 * r.torque_per_thrust_m


def test_without_damping_in_the_data_the_damping_stays_near_zero() -> None:
    """The damping is not a free fudge: data made with kd = 0 give kd within its bound of 0."""
    rng = np.random.default_rng(4)
    jz = QuadrotorParams().Jz_kg_m2
    ms = []
    for m in synthetic_windows(rng, 120, 0.05):
        y = replay([m], C_TRUE_M, jz, 0.0)[0] + rng.normal(0.0, 0.05, N_STEPS)
        ms.append(Manoeuvre(m.x0, m.u, y[:, None], DT_S))
    r = identify_yaw_torque(ms, QuadrotorParams())
    assert r.kd_yaw_N_m_s < 4.0 * r.crb_std_kd_N_m_s
    assert abs(r.torque_per_thrust_m - C_TRUE_M) < 4.0 * r.crb_std_m

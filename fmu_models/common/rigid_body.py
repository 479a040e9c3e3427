"""Rigid-body 6-DOF over a flat-earth NED frame (paper 001 eqs. 2-6), written once for CasADi.

Frames: NED world, FRD body. ``quat = [w, x, y, z]`` rotates body vectors into NED. Every function takes
and returns CasADi column vectors (SX for code generation, DM or floats for numeric use), except
:func:`body_moments_N_m`, eq. 6 solved for the moment over arrays of samples (numpy), for identification.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from fmu_models.common.mathns import CA
from fmu_models.common.rotations import euler_to_quat, quat_to_dcm_rows, quat_to_euler


def quat_to_dcm(q: Any) -> Any:
    """Rotation matrix ``R_b2n`` (body -> NED) of the unit quaternion ``q = [w, x, y, z]``."""
    return ca.vertcat(*(ca.horzcat(*row) for row in quat_to_dcm_rows(q[0], q[1], q[2], q[3])))


def quat_derivative(q: Any, rates_body_rad_s: Any) -> Any:
    """Euler-Rodrigues kinematics (paper 001 eq. 4): ``q_dot = 0.5 * Omega(P, Q, R) q``."""
    p, qq, r = rates_body_rad_s[0], rates_body_rad_s[1], rates_body_rad_s[2]
    w, x, y, z = q[0], q[1], q[2], q[3]
    return 0.5 * ca.vertcat(
        -p * x - qq * y - r * z,
        p * w + r * y - qq * z,
        qq * w - r * x + p * z,
        r * w + qq * x - p * y,
    )


def euler_from_quat(q: Any) -> Any:
    """Roll, pitch, yaw [rad] (3-2-1) from the quaternion (paper 001 eq. 5)."""
    return ca.vertcat(*quat_to_euler(q[0], q[1], q[2], q[3], CA))


def quat_from_euler(roll_rad: Any, pitch_rad: Any, yaw_rad: Any) -> Any:
    """Unit quaternion [w, x, y, z] of 3-2-1 Euler angles [rad]."""
    return ca.vertcat(*euler_to_quat(roll_rad, pitch_rad, yaw_rad, CA))


def inertia_matrix(Jx: Any, Jy: Any, Jz: Any, Jxz: Any = 0.0) -> Any:
    """Body inertia matrix [kg m^2] of a vehicle symmetric about its x-z plane (only Jxz off-diagonal)."""
    return ca.vertcat(
        ca.horzcat(Jx, 0, -Jxz),
        ca.horzcat(0, Jy, 0),
        ca.horzcat(-Jxz, 0, Jz),
    )


def body_moments_N_m(J_kg_m2: np.ndarray, rates_body_rad_s: np.ndarray, rates_dot_rad_s2: np.ndarray
                     ) -> np.ndarray:
    """The body moments [N m] that give angular accelerations ``rates_dot_rad_s2`` at ``rates_body_rad_s``: eq. 6
    solved for the moment, ``M = J w' + w x (J w)``; rows are samples (N, 3), ``J_kg_m2`` (3, 3)."""
    w = np.atleast_2d(rates_body_rad_s)
    J = np.asarray(J_kg_m2, float)
    return np.atleast_2d(rates_dot_rad_s2) @ J.T + np.cross(w, w @ J.T)


def rigid_body_derivatives(
    vel_body_m_s: Any,
    rates_body_rad_s: Any,
    quat: Any,
    force_body_N: Any,
    moment_body_N_m: Any,
    gravity_ned_m_s2: Any,
    mass_kg: Any,
    J_kg_m2: Any,
) -> tuple[Any, Any, Any, Any]:
    """Flat-earth state equations (paper 001 eqs. 2, 3, 4, 6).

    ``force_body_N`` excludes gravity. Returns ``(pos_ned_dot, vel_body_dot, quat_dot, rates_dot)``.
    """
    R = quat_to_dcm(quat)
    g_body = R.T @ gravity_ned_m_s2
    vel_dot = force_body_N / mass_kg - ca.cross(rates_body_rad_s, vel_body_m_s) + g_body
    Jw = J_kg_m2 @ rates_body_rad_s
    rates_dot = ca.solve(J_kg_m2, moment_body_N_m - ca.cross(rates_body_rad_s, Jw))
    pos_dot = R @ vel_body_m_s
    return pos_dot, vel_dot, quat_derivative(quat, rates_body_rad_s), rates_dot

"""Ground contact: spring-damper gear points on a flat ground at ``pos_down_m = 0`` (home level).

Each point pushes up with ``k*penetration + c*penetration_rate`` (never pulls), split evenly between the
points so that the whole vehicle has natural frequency ``wn`` and damping ratio ``zeta`` in heave
(critically damped by default: it settles without bouncing). Friction acts on the point's body-x and
body-y velocity, regularised near zero speed so the equations stay smooth for RK4 and for CasADi.
A vehicle at rest sinks ``g / wn^2`` (1 mm at 100 rad/s) and lifts off as soon as thrust exceeds weight.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from fmu_models.common.rigid_body import quat_to_dcm

FRICTION_SPEED_M_S = 0.05  #: below this sliding speed friction fades out linearly (regularisation)


def contact_forces(
    pos_ned_m: Any,
    vel_body_m_s: Any,
    quat: Any,
    rates_body_rad_s: Any,
    points_body_m: list[tuple[float, float, float]],
    mass_kg: Any,
    wn_rad_s: Any,
    zeta: Any,
    mu_x: Any,
    mu_y: Any,
) -> tuple[Any, Any, Any]:
    """Return ``(force_body_N, moment_body_N_m, on_ground)`` of the gear points given in body FRD [m]."""
    R = quat_to_dcm(quat)
    n = len(points_body_m)
    k = mass_kg * wn_rad_s**2 / n
    c = 2.0 * zeta * wn_rad_s * mass_kg / n
    force = ca.SX.zeros(3) if isinstance(pos_ned_m, ca.SX) else ca.DM.zeros(3)
    moment = force * 0
    on_ground = 0
    for point in points_body_m:
        r = ca.vertcat(*point)
        depth = pos_ned_m[2] + (R @ r)[2]
        v_point_body = vel_body_m_s + ca.cross(rates_body_rad_s, r)
        depth_rate = (R @ v_point_body)[2]
        normal = ca.if_else(depth > 0, ca.fmax(k * depth + c * depth_rate, 0.0), 0.0)
        fx = -mu_x * normal * v_point_body[0] / ca.sqrt(v_point_body[0] ** 2 + FRICTION_SPEED_M_S**2)
        fy = -mu_y * normal * v_point_body[1] / ca.sqrt(v_point_body[1] ** 2 + FRICTION_SPEED_M_S**2)
        f = R.T @ ca.vertcat(0, 0, -normal) + ca.vertcat(fx, fy, 0)
        force = force + f
        moment = moment + ca.cross(r, f)
        on_ground = ca.fmax(on_ground, ca.if_else(depth > 0, 1.0, 0.0))
    return force, moment, on_ground

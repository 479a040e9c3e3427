"""The part every vehicle shares: 6-DOF states, initial-state parameters, navigation outputs.

State vector (first 16 elements of every vehicle's state):
``pos_ned (3), vel_body (3), quat [w,x,y,z] (4), rates_body (3), lat_rad, lon_rad, height_m``.
Geodetic position is integrated from the NED velocity with the WGS-84 radii of curvature; the flat-earth
NED position is integrated too (paper 001 uses both: NED for the dynamics, geodetic for the GPS).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

from fmu_models.common import wgs84
from fmu_models.common.model import Variable
from fmu_models.common.rigid_body import (
    euler_from_quat,
    quat_from_euler,
    quat_to_dcm,
    rigid_body_derivatives,
)

N_BODY_STATES = 16

BODY_STATES: tuple[Variable, ...] = (
    Variable("pos_north_m", "m", "NED position north of home"),
    Variable("pos_east_m", "m", "NED position east of home"),
    Variable("pos_down_m", "m", "NED position below home"),
    Variable("vel_body_x_m_s", "m/s", "ground velocity along body x (forward)"),
    Variable("vel_body_y_m_s", "m/s", "ground velocity along body y (right)"),
    Variable("vel_body_z_m_s", "m/s", "ground velocity along body z (down)"),
    Variable("quat_w", "1", "attitude quaternion body->NED, scalar part", 1.0),
    Variable("quat_x", "1", "attitude quaternion body->NED, x part"),
    Variable("quat_y", "1", "attitude quaternion body->NED, y part"),
    Variable("quat_z", "1", "attitude quaternion body->NED, z part"),
    Variable("rate_body_x_rad_s", "rad/s", "body roll rate P"),
    Variable("rate_body_y_rad_s", "rad/s", "body pitch rate Q"),
    Variable("rate_body_z_rad_s", "rad/s", "body yaw rate R"),
    Variable("lat_rad", "rad", "WGS-84 geodetic latitude"),
    Variable("lon_rad", "rad", "WGS-84 geodetic longitude"),
    Variable("height_m", "m", "WGS-84 ellipsoidal height"),
)

#: divergence limits of the body states: position 1000 km, speed 1 km/s, rates 1000 rad/s
BODY_STATE_LIMITS: tuple[float, ...] = (1e6,) * 3 + (1e3,) * 3 + (2.0,) * 4 + (1e3,) * 3 + (4.0, 7.0, 1e6)

INIT_PARAMS: tuple[Variable, ...] = (
    Variable("init_pos_north_m", "m", "initial NED position north of home", 0.0, -1e6, 1e6),
    Variable("init_pos_east_m", "m", "initial NED position east of home", 0.0, -1e6, 1e6),
    Variable("init_pos_down_m", "m", "initial NED position below home (negative is up)", 0.0, -1e5, 1e3),
    Variable("init_vel_body_x_m_s", "m/s", "initial ground velocity along body x", 0.0, -500, 500),
    Variable("init_vel_body_y_m_s", "m/s", "initial ground velocity along body y", 0.0, -500, 500),
    Variable("init_vel_body_z_m_s", "m/s", "initial ground velocity along body z", 0.0, -500, 500),
    Variable("init_roll_rad", "rad", "initial roll angle", 0.0, -math.pi, math.pi),
    Variable("init_pitch_rad", "rad", "initial pitch angle", 0.0, -math.pi / 2, math.pi / 2),
    Variable("init_yaw_rad", "rad", "initial yaw angle (heading)", 0.0, -2 * math.pi, 2 * math.pi),
    Variable("init_rate_body_x_rad_s", "rad/s", "initial body roll rate", 0.0, -50, 50),
    Variable("init_rate_body_y_rad_s", "rad/s", "initial body pitch rate", 0.0, -50, 50),
    Variable("init_rate_body_z_rad_s", "rad/s", "initial body yaw rate", 0.0, -50, 50),
    Variable("home_lat_deg", "deg", "home WGS-84 latitude (NED origin)", 47.397742, -90, 90),
    Variable("home_lon_deg", "deg", "home WGS-84 longitude (NED origin)", 8.545594, -180, 180),
    Variable("home_height_m", "m", "home WGS-84 ellipsoidal height (ground level)", 488.0, -500, 9000),
)

#: Ground contact parameters; the gear points themselves are per vehicle (body FRD, metres).
GROUND_PARAMS: tuple[Variable, ...] = (
    Variable("ground_wn_rad_s", "rad/s", "ground contact natural frequency in heave", 100.0, 1.0, 1000.0),
    Variable("ground_zeta", "1", "ground contact damping ratio", 1.0, 0.05, 10.0),
)

NAV_OUTPUTS: tuple[Variable, ...] = (
    *BODY_STATES[:13],
    Variable("lat_deg", "deg", "WGS-84 geodetic latitude"),
    Variable("lon_deg", "deg", "WGS-84 geodetic longitude"),
    Variable("height_m", "m", "WGS-84 ellipsoidal height"),
    Variable("altitude_m", "m", "height above home (= -pos_down_m)"),
    Variable("vel_north_m_s", "m/s", "ground velocity north"),
    Variable("vel_east_m_s", "m/s", "ground velocity east"),
    Variable("vel_down_m_s", "m/s", "ground velocity down"),
    Variable("roll_rad", "rad", "roll angle (3-2-1 Euler, paper 001 eq. 5)"),
    Variable("pitch_rad", "rad", "pitch angle (3-2-1 Euler)"),
    Variable("yaw_rad", "rad", "yaw angle / heading (3-2-1 Euler)"),
    Variable("accel_body_x_m_s2", "m/s2", "specific force along body x (accelerometer)"),
    Variable("accel_body_y_m_s2", "m/s2", "specific force along body y (accelerometer)"),
    Variable("accel_body_z_m_s2", "m/s2", "specific force along body z (accelerometer; -g at rest)"),
    Variable("gravity_m_s2", "m/s2", "WGS-84 normal gravity at the vehicle"),
    Variable("on_ground", "", "ground contact", boolean=True),
)


def split(x: Any) -> tuple[Any, Any, Any, Any, Any]:
    """``(pos_ned, vel_body, quat, rates_body, geodetic[lat, lon, h])`` slices of a state vector."""
    return x[0:3], x[3:6], x[6:10], x[10:13], x[13:16]


def gravity_ned(x: Any) -> tuple[Any, Any]:
    """``(g_ned_vector, g_magnitude)`` of WGS-84 normal gravity at the state's geodetic position."""
    g = wgs84.normal_gravity(x[13], x[15])
    return ca.vertcat(0, 0, g), g


def body_derivatives(x: Any, force_body_N: Any, moment_body_N_m: Any, mass_kg: Any, J: Any) -> Any:
    """Time derivative of the 16 body states, given the non-gravitational force and the moment."""
    _pos, vel, quat, rates, geo = split(x)
    g_ned, _ = gravity_ned(x)
    pos_dot, vel_dot, quat_dot, rates_dot = rigid_body_derivatives(
        vel, rates, quat, force_body_N, moment_body_N_m, g_ned, mass_kg, J
    )
    geo_dot = wgs84.geodetic_rates(geo[0], geo[2], pos_dot)
    return ca.vertcat(pos_dot, vel_dot, quat_dot, rates_dot, geo_dot)


def nav_outputs(x: Any, force_body_N: Any, mass_kg: Any, on_ground: Any) -> list[Any]:
    """Values of ``NAV_OUTPUTS`` for state ``x`` and the non-gravitational force (for the accelerometer)."""
    pos, vel, quat, _rates, geo = split(x)
    vel_ned = quat_to_dcm(quat) @ vel
    euler = euler_from_quat(quat)
    _, g = gravity_ned(x)
    accel = force_body_N / mass_kg
    return [
        *[x[i] for i in range(13)],
        geo[0] * 180.0 / math.pi,
        geo[1] * 180.0 / math.pi,
        geo[2],
        -pos[2],
        vel_ned[0],
        vel_ned[1],
        vel_ned[2],
        euler[0],
        euler[1],
        euler[2],
        accel[0],
        accel[1],
        accel[2],
        g,
        on_ground,
    ]


def initial_body_state(pv: Any) -> Any:
    """The 16 body states from the ``INIT_PARAMS`` (named view ``pv``); geodetic from home + NED offset.

    A vehicle started on the ground (``init_pos_down_m >= 0``) starts at its ground-contact equilibrium in
    heave: sunk ``g / ground_wn_rad_s^2`` (1 mm at 100 rad/s), so the gear carries its weight from t = 0
    and the accelerometer reads -g at once instead of a free-fall transient; a start sunk deeper than that
    (e.g. a logged ground state) is kept.
    """
    q0 = quat_from_euler(pv.init_roll_rad, pv.init_pitch_rad, pv.init_yaw_rad)
    lat0 = pv.home_lat_deg * math.pi / 180.0
    h_home = pv.home_height_m
    r_m, r_n = wgs84.radii_of_curvature(lat0)
    lat = lat0 + pv.init_pos_north_m / (r_m + h_home)
    lon = pv.home_lon_deg * math.pi / 180.0 + pv.init_pos_east_m / ((r_n + h_home) * ca.cos(lat0))
    settle = wgs84.normal_gravity(lat, h_home) / pv.ground_wn_rad_s**2
    # a start sunk at least ``settle`` (a logged ground state, replayed) is kept as given
    down = ca.if_else(pv.init_pos_down_m >= 0, ca.fmax(pv.init_pos_down_m, settle), pv.init_pos_down_m)
    return ca.vertcat(
        pv.init_pos_north_m,
        pv.init_pos_east_m,
        down,
        pv.init_vel_body_x_m_s,
        pv.init_vel_body_y_m_s,
        pv.init_vel_body_z_m_s,
        q0,
        pv.init_rate_body_x_rad_s,
        pv.init_rate_body_y_rad_s,
        pv.init_rate_body_z_rad_s,
        lat,
        lon,
        h_home - down,
    )


def normalize_quaternion(x: Any) -> Any:
    """Return ``x`` with its quaternion (elements 6..9) rescaled to unit norm."""
    q = x[6:10]
    qn = q / ca.sqrt(ca.sumsqr(q))
    return ca.vertcat(x[0:6], qn, x[10:])

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
from fmu_models.common.model import Layout, Variable, fingerprint
from fmu_models.common.params import to_variables
from fmu_models.common.rigid_body import (
    euler_from_quat,
    quat_from_euler,
    quat_to_dcm,
    rigid_body_derivatives,
)
from fmu_models.common.units import DEG_TO_RAD, RAD_TO_DEG

_XYZ = {"x": "x", "y": "y", "z": "z"}


def _vector(name: str, unit: str, text: str, parts: dict[str, str], lo: float | None = None,
            hi: float | None = None) -> tuple[Variable, ...]:
    """The variables of one vector quantity (start 0, range ``[lo, hi]`` in ``unit``): ``name`` and ``text``
    formatted with each key and value of ``parts``."""
    return tuple(Variable(name.format(k), unit, text.format(v), 0.0, lo, hi) for k, v in parts.items())


BODY_STATES: tuple[Variable, ...] = (
    *_vector("pos_{}_m", "m", "NED position {}", {"north": "north of home", "east": "east of home",
                                                   "down": "below home"}),
    *_vector("vel_body_{}_m_s", "m/s", "ground velocity along body {}",
             {"x": "x (forward)", "y": "y (right)", "z": "z (down)"}),
    Variable("quat_w", "1", "attitude quaternion body->NED, scalar part", 1.0),
    *_vector("quat_{}", "1", "attitude quaternion body->NED, {} part", _XYZ),
    *_vector("rate_body_{}_rad_s", "rad/s", "body {}", {"x": "roll rate P", "y": "pitch rate Q", "z": "yaw rate R"}),
    Variable("lat_rad", "rad", "WGS-84 geodetic latitude"),
    Variable("lon_rad", "rad", "WGS-84 geodetic longitude"),
    Variable("height_m", "m", "WGS-84 ellipsoidal height"),
)

#: divergence limits of the body states: position 1000 km, speed 1 km/s, rates 1000 rad/s
BODY_STATE_LIMITS: tuple[float, ...] = (1e6,) * 3 + (1e3,) * 3 + (2.0,) * 4 + (1e3,) * 3 + (4.0, 7.0, 1e6)

INIT_PARAMS: tuple[Variable, ...] = (
    *_vector("init_pos_{}_m", "m", "initial NED position {}", {"north": "north of home", "east": "east of home"},
             -1e6, 1e6),
    Variable("init_pos_down_m", "m", "initial NED position below home (negative is up)", 0.0, -1e5, 1e3),
    *_vector("init_vel_body_{}_m_s", "m/s", "initial ground velocity along body {}", _XYZ, -500, 500),
    Variable("init_roll_rad", "rad", "initial roll angle", 0.0, -math.pi, math.pi),
    Variable("init_pitch_rad", "rad", "initial pitch angle", 0.0, -math.pi / 2, math.pi / 2),
    Variable("init_yaw_rad", "rad", "initial yaw angle (heading)", 0.0, -2 * math.pi, 2 * math.pi),
    *_vector("init_rate_body_{}_rad_s", "rad/s", "initial body {} rate", {"x": "roll", "y": "pitch", "z": "yaw"},
             -50, 50),
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
    *_vector("vel_{}_m_s", "m/s", "ground velocity {}", {"north": "north", "east": "east", "down": "down"}),
    *_vector("{}_rad", "rad", "{}", {"roll": "roll angle (3-2-1 Euler, paper 001 eq. 5)",
                                      "pitch": "pitch angle (3-2-1 Euler)",
                                      "yaw": "yaw angle / heading (3-2-1 Euler)"}),
    *_vector("accel_body_{}_m_s2", "m/s2", "specific force along body {}",
             {"x": "x (accelerometer)", "y": "y (accelerometer)", "z": "z (accelerometer; -g at rest)"}),
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
        geo[0] * RAD_TO_DEG,
        geo[1] * RAD_TO_DEG,
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
    lat0 = pv.home_lat_deg * DEG_TO_RAD
    h_home = pv.home_height_m
    r_m, r_n = wgs84.radii_of_curvature(lat0)
    lat = lat0 + pv.init_pos_north_m / (r_m + h_home)
    lon = pv.home_lon_deg * DEG_TO_RAD + pv.init_pos_east_m / ((r_n + h_home) * ca.cos(lat0))
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


def _no_structure_key(self: Any) -> None:
    """A subclass's constructor may take more than the defaults: traced anew every time."""
    return None


class BodyVehicleModel:
    """The part of a ``VehicleModel`` every vehicle shares (see ``fmu_models.common.model``).

    Layouts: the 16 body states, ``INIT_PARAMS`` + ``GROUND_PARAMS`` + the vehicle's scalar parameters
    (``defaults``, a parameter dataclass), ``NAV_OUTPUTS``, each followed by the vehicle's own variables.
    A subclass supplies ``forces_moments(x, u, p)`` (non-gravitational force [N] and moment [N m] in body axes,
    and a dict of intermediate values holding ``on_ground``) and ``inertia(p)`` [kg m2].
    """

    name: str
    description: str

    def __init__(
        self,
        defaults: Any,
        inputs: tuple[Variable, ...],
        *,
        states: tuple[Variable, ...] = (),
        state_limits: tuple[float, ...] = (),
        params: tuple[Variable, ...] = (),
        outputs: tuple[Variable, ...] = (),
    ) -> None:
        self.defaults = defaults
        self.states = Layout(BODY_STATES + states)
        self.state_limits = BODY_STATE_LIMITS + state_limits
        self.inputs = Layout(inputs)
        self.params = Layout(INIT_PARAMS + GROUND_PARAMS + to_variables(defaults) + params)
        self.outputs = Layout(NAV_OUTPUTS + outputs)

    def structure_key(self) -> str | None:
        """What determines this model's symbolic functions (``fmu_models.common.model.traced``): its class and its
        parameter defaults, the one constructor argument (every attribute the equations read is set from them at
        construction and not changed after). A subclass that defines ``__init__`` traces anew every time unless it
        defines its own ``structure_key`` holding every argument its constructor takes."""
        fp = fingerprint(self.defaults)
        return None if fp is None else f"{type(self).__module__}.{type(self).__qualname__}:{fp}"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "__init__" in cls.__dict__ and "structure_key" not in cls.__dict__:
            cls.structure_key = _no_structure_key  # type: ignore[method-assign]

    def forces_moments(self, x: Any, u: Any, p: Any) -> tuple[Any, Any, dict[str, Any]]:
        raise NotImplementedError

    def inertia(self, p: Any) -> Any:
        raise NotImplementedError

    def body_derivatives(self, x: Any, u: Any, p: Any) -> Any:
        """Time derivative of the 16 body states under the vehicle's forces and moments."""
        force, moment, _ = self.forces_moments(x, u, p)
        return body_derivatives(x, force, moment, self.params.view(p).mass_kg, self.inertia(p))

    def nav_outputs(self, x: Any, u: Any, p: Any) -> tuple[list[Any], dict[str, Any]]:
        """Values of ``NAV_OUTPUTS`` at ``(x, u, p)``, and the intermediate values of ``forces_moments``."""
        force, _, extras = self.forces_moments(x, u, p)
        return nav_outputs(x, force, self.params.view(p).mass_kg, extras["on_ground"]), extras

"""WGS-84 normal gravity and geodetic position rates (NIMA TR8350.2, 3rd ed., ch. 4).

Normal gravity is Somigliana's closed formula on the ellipsoid (it is the gravity of the rotating
ellipsoid, so it includes the centripetal acceleration of the Earth's rotation, as paper 001 asks) with the
second-order free-air correction for height (TR8350.2 eq. 4-3).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

A_M = 6378137.0  #: semi-major axis [m]
F = 1.0 / 298.257223563  #: flattening
B_M = A_M * (1.0 - F)  #: semi-minor axis [m]
E2 = F * (2.0 - F)  #: first eccentricity squared
OMEGA_RAD_S = 7.292115e-5  #: Earth rotation rate [rad/s]
GM_M3_S2 = 3.986004418e14  #: gravitational constant [m^3/s^2]
G_EQUATOR_M_S2 = 9.7803253359  #: normal gravity at the equator [m/s^2]
K_SOMIGLIANA = 0.00193185265241  #: Somigliana's constant
M_RATIO = OMEGA_RAD_S**2 * A_M**2 * B_M / GM_M3_S2  #: omega^2 a^2 b / GM


def normal_gravity(lat_rad: Any, height_m: Any) -> Any:
    """Magnitude of WGS-84 normal gravity [m/s^2] at geodetic latitude and ellipsoidal height: CasADi
    expressions for the model, plain floats (``math``, about 1 us instead of a CasADi call) for per-step users."""
    lib = math if isinstance(lat_rad, (int, float)) else ca
    s2 = lib.sin(lat_rad) ** 2
    g0 = G_EQUATOR_M_S2 * (1.0 + K_SOMIGLIANA * s2) / lib.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A_M * (1.0 + F + M_RATIO - 2.0 * F * s2) * height_m + 3.0 * height_m**2 / A_M**2)


def radii_of_curvature(lat_rad: Any) -> tuple[Any, Any]:
    """Meridian radius ``R_M`` and prime-vertical radius ``R_N`` [m] at geodetic latitude."""
    d = 1.0 - E2 * ca.sin(lat_rad) ** 2
    return A_M * (1.0 - E2) / d**1.5, A_M / ca.sqrt(d)


def geodetic_rates(lat_rad: Any, height_m: Any, vel_ned_m_s: Any) -> Any:
    """Rates of latitude [rad/s], longitude [rad/s] and height [m/s] from the NED ground velocity."""
    r_m, r_n = radii_of_curvature(lat_rad)
    return ca.vertcat(
        vel_ned_m_s[0] / (r_m + height_m),
        vel_ned_m_s[1] / ((r_n + height_m) * ca.cos(lat_rad)),
        -vel_ned_m_s[2],
    )

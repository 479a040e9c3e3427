"""International Standard Atmosphere, troposphere (ISO 2533:1975), for drag, baro and airspeed."""

from __future__ import annotations

from typing import Any

import casadi as ca

from fmu_models.common.units import G0_M_S2

T0_K = 288.15  #: sea-level temperature [K]
P0_PA = 101325.0  #: sea-level pressure [Pa]
LAPSE_K_M = 0.0065  #: temperature lapse rate [K/m]
R_AIR_J_KG_K = 287.05287  #: specific gas constant of dry air [J/(kg K)]
EXPONENT = G0_M_S2 / (R_AIR_J_KG_K * LAPSE_K_M)  #: ~5.2559


def isa(altitude_m: Any) -> tuple[Any, Any, Any]:
    """``(temperature_K, pressure_Pa, density_kg_m3)`` at geopotential altitude [m], valid to 11 km."""
    h = ca.fmin(altitude_m, 11000.0)
    t = T0_K - LAPSE_K_M * h
    p = P0_PA * (t / T0_K) ** EXPONENT
    return t, p, p / (R_AIR_J_KG_K * t)

"""International Standard Atmosphere, troposphere (ISO 2533:1975), for drag, baro and airspeed."""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

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


def eas_to_tas(altitude_amsl_m: Any) -> Any:
    """True over equivalent airspeed, ``sqrt(rho_0 / rho(h))`` [-], at altitude [m above mean sea level] (numpy,
    elementwise; held at 11 km's above it, where this troposphere model ends). An autopilot's airspeed sensor
    reads the equivalent airspeed (the dynamic pressure as sea-level air would give it): ArduPilot logs that
    (``ARSP.Airspeed``, ``VFR_HUD``) and its SITL divides the simulator's true airspeed by this factor
    (``AP_Baro::get_EAS2TAS_for_alt_amsl``); the FMUs output the true airspeed. About 1.03 at 600 m."""
    # rho_0 / rho = (p_0 / p) (t / T0) = (t / T0) ** (1 - EXPONENT)
    if isinstance(altitude_amsl_m, float):  # a plain float in, a plain float out (the HIL loop's per-step call)
        return math.sqrt(((T0_K - LAPSE_K_M * min(altitude_amsl_m, 11000.0)) / T0_K) ** (1.0 - EXPONENT))
    h = np.minimum(np.asarray(altitude_amsl_m, dtype=float), 11000.0)
    return np.sqrt(((T0_K - LAPSE_K_M * h) / T0_K) ** (1.0 - EXPONENT))

"""Wings-level trim of the fixed wing, the way the uavbook computes it (``compute_trim``).

Unknowns: angle of attack, elevator, throttle, aileron, rudder. Held: airspeed ``Va``, flight-path angle
``gamma`` (pitch = alpha + gamma), zero sideslip, roll and body rates. Residual: the derivatives of the
body velocities and rates, solved in the least-squares sense (six equations, five unknowns: the
propeller torque leaves a tiny lateral residual, as in the book).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from fmu_models.common.model import derivative_function
from fmu_models.common.rigid_body import quat_from_euler
from fmu_models.fixed_wing.model import FixedWingModel


class TrimError(RuntimeError):
    """The trim did not converge."""


@dataclass(frozen=True)
class Trim:
    """A trimmed flight condition: state vector, inputs, and the named values."""

    x: np.ndarray
    u: np.ndarray
    alpha_rad: float
    elevator_rad: float
    throttle: float
    aileron_rad: float
    rudder_rad: float
    residual_norm: float


def trim(model: FixedWingModel, p: np.ndarray, va_m_s: float, gamma_rad: float = 0.0,
         pos_down_m: float = -100.0) -> Trim:
    """Trim ``model`` with parameter vector ``p`` at airspeed ``va_m_s`` and flight-path angle ``gamma_rad``."""
    f = derivative_function(model)
    pv = model.params.view(p)
    lat = math.radians(pv.home_lat_deg)
    lon = math.radians(pv.home_lon_deg)
    wind = np.array([pv.wind_north_m_s, pv.wind_east_m_s, pv.wind_down_m_s])
    if np.any(wind != 0):
        raise TrimError("trim assumes no wind; set wind_*_m_s to 0")

    def state(alpha: float) -> np.ndarray:
        q = np.asarray(quat_from_euler(0.0, alpha + gamma_rad, 0.0)).ravel()
        return np.array([0.0, 0.0, pos_down_m, va_m_s * math.cos(alpha), 0.0, va_m_s * math.sin(alpha), *q,
                         0.0, 0.0, 0.0, lat, lon, pv.home_height_m - pos_down_m])

    def residual(z: np.ndarray) -> np.ndarray:
        alpha, de, dt, da, dr = z
        xdot = np.asarray(f(state(alpha), [da, de, dr, dt], p)).ravel()
        return xdot[3:6].tolist() + xdot[10:13].tolist()

    sol = least_squares(residual, [0.05, -0.1, 0.5, 0.0, 0.0], bounds=([-0.3, -0.7, 0.0, -0.7, -0.7],
                                                                      [0.3, 0.7, 1.0, 0.7, 0.7]),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if not sol.success:
        raise TrimError(f"trim at Va = {va_m_s} m/s did not converge: {sol.message}")
    alpha, de, dt, da, dr = sol.x
    return Trim(state(alpha), np.array([da, de, dr, dt]), float(alpha), float(de), float(dt), float(da),
                float(dr), float(np.linalg.norm(sol.fun)))

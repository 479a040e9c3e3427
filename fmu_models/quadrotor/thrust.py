"""Thrust of the ANFIS map inside its trained band, kept physical outside it.

Inside ``[lo, hi]`` (summed PWM) the map is reproduced exactly. Below, thrust rises from 0 at the idle PWM
to the map's value at ``lo`` as ``T(lo) * s^2`` with ``s = (x - idle)/(lo - idle)`` (thrust ~ Omega^2 and
Omega ~ linear in PWM above idle); at and below idle it is 0. Above ``hi`` it extends linearly from the
map's value and slope at ``hi``; the slope is floored at a small positive value
(``MIN_SLOPE_FRACTION`` of the mean slope from idle to ``hi``) so thrust keeps growing even where a map
flattens at its edge. The raw map is only ever evaluated inside the band, where it is finite.
"""

from __future__ import annotations

from typing import Any

from fmu_models.common.mathns import CA, NP
from fmu_models.quadrotor.anfis import AnfisMap

EDGE_STEP_US = 1e-3  #: step of the one-sided difference for the slope at the band top [us]
MIN_SLOPE_FRACTION = 0.05  #: floor of the extension slope, as a fraction of T(hi) / (hi - idle)


def thrust_sum(amap: AnfisMap, x_us: Any, idle_us: Any, lo_us: Any, hi_us: Any, xp: Any = NP) -> Any:
    """Thrust [N] of the map at summed PWM ``x_us`` with the physical extension outside ``[lo, hi]``."""
    x_in = xp.fmin(xp.fmax(x_us, lo_us), hi_us)
    t_in = amap.evaluate([x_in], xp)
    t_lo = xp.fmax(amap.evaluate([lo_us], xp), 0.0)
    t_hi = amap.evaluate([hi_us], xp)
    slope_edge = (t_hi - amap.evaluate([hi_us - EDGE_STEP_US], xp)) / EDGE_STEP_US
    slope = xp.fmax(slope_edge, MIN_SLOPE_FRACTION * xp.fmax(t_hi, 0.0) / (hi_us - idle_us))
    s = xp.fmax(x_us - idle_us, 0.0) / (lo_us - idle_us)
    below = t_lo * s * s
    above = t_hi + slope * (x_us - hi_us)
    return xp.where(x_us < lo_us, below, xp.where(x_us > hi_us, above, t_in))


def effective_pwm(pwm_us: Any, voltage_V: Any, idle_us: Any, nominal_V: Any, exponent: Any, xp: Any = NP) -> Any:
    """Per-motor PWM [us] that gives at ``nominal_V`` the thrust ``pwm_us`` gives at ``voltage_V``.

    An ESC sets the motor's duty cycle from the command above idle; the motor speed follows duty x
    battery voltage, so thrust ~ ((pwm - idle) V)^2. The command is rescaled by ``(V / V_nom)^exponent``
    (exponent 1: that physics; 0: voltage ignored). Voltages below 1 % of nominal count as 1 %.
    """
    ratio = xp.fmax(voltage_V / nominal_V, 0.01)
    return idle_us + xp.fmax(pwm_us - idle_us, 0.0) * ratio**exponent


def motor_thrust(amap: AnfisMap, pwm_us: Any, voltage_V: Any, idle_us: Any, lo_us: Any, hi_us: Any, nominal_V: Any,
                 exponent: Any, scale: Any = 1.0, n_motors: int = 4, xp: Any = NP) -> Any:
    """Thrust [N] of one motor at ``pwm_us`` and battery ``voltage_V``: what the quadrotor FMU evaluates.

    ``scale * thrust_sum(n * pwm_eff) / n`` with the voltage-compensated command :func:`effective_pwm`
    (``idle_us`` per motor; ``lo_us``/``hi_us`` summed). Zero at and below idle, monotone where the map is.
    """
    x = n_motors * effective_pwm(pwm_us, voltage_V, idle_us, nominal_V, exponent, xp)
    return scale * thrust_sum(amap, x, n_motors * idle_us, lo_us, hi_us, xp) / n_motors


def thrust_sum_ca(amap: AnfisMap, x_us: Any, idle_us: Any, lo_us: Any, hi_us: Any) -> Any:
    """CasADi form of :func:`thrust_sum`."""
    return thrust_sum(amap, x_us, idle_us, lo_us, hi_us, CA)


def out_of_band(x_us: Any, lo_us: Any, hi_us: Any, xp: Any = NP) -> Any:
    """1 where ``x_us`` lies outside the trained band, else 0."""
    return xp.where(x_us < lo_us, 1.0, xp.where(x_us > hi_us, 1.0, 0.0))

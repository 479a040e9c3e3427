"""Per-motor thrust of the quadrotor FMU: the ANFIS map inside its trained band, kept physical outside it.

Two kinds of map (both zero at and below idle, exactly the map inside its band ``[lo, hi]``):

* **Feature map** (``AnfisMap.features`` set; what ``uavfmu identify thrust`` writes). One input ``x``, the
  per-motor command ``u = max(pwm - idle, 0) / (full - idle)`` (input ``u``) or the voltage-compensated
  ``u r`` (input ``u_eff``), ``r = V / V_nom``; first-order Sugeno consequents over ``x^2, x`` (and
  ``x^2 r``), so every rule is zero at idle and a one-rule map is the least-squares polynomial of those
  features. Motor thrust ``T = scale r^e G(x, r)`` [N]; ``e`` (``thrust_voltage_exponent``) is 1 for maps
  identified without a voltage log, so the ``battery_voltage_V`` input carries a battery state as an
  equivalent voltage ``V_nom s`` (thrust scale ``s``), and 0 when the voltage enters through the features.
  Below ``lo``: ``G(lo) (x/lo)^2``; above ``hi``: linear from ``G(hi)`` with the map's slope there, floored
  at ``MIN_SLOPE_FRACTION G(hi)/hi``.
* **Summed-PWM map** (paper 000, Tables 2-3): input the sum of four PWMs, motor thrust
  ``scale F(n pwm_eff)/n`` with ``pwm_eff = idle + (pwm - idle)(V/V_nom)^e``; below ``lo`` ``F(lo) s^2``,
  ``s = (x - idle)/(lo - idle)``; above ``hi`` linear as above.

The FMU (``fmu_models.quadrotor.model``) evaluates these functions in CasADi with the map's values as
tunable parameters (:func:`map_param_variables`, :func:`map_from_params`); identification scores with the
same functions in numpy.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

from fmu_models.common.mathns import NP
from fmu_models.common.model import Variable
from fmu_models.quadrotor.anfis import AnfisMap

EDGE_STEP_US = 1e-3  #: step of the one-sided difference for the slope at the band top [us]
EDGE_STEP_X = 1e-6  #: the same for feature maps [normalised command]
MIN_SLOPE_FRACTION = 0.05  #: floor of the extension slope, as a fraction of T(hi) / (hi - idle)
MIN_VOLTAGE_RATIO = 0.01  #: V / V_nom below this counts as this
FEATURE_INPUTS = ("u", "u_eff")  #: input of a feature map: the command, or the command times V / V_nom


class ThrustConstants(NamedTuple):
    """Scalars the thrust function needs (numbers, or CasADi symbols in the FMU)."""

    idle_us: Any  #: per-motor PWM of zero thrust [us]
    full_us: Any  #: per-motor PWM of full command, u = 1 [us] (feature maps)
    nominal_V: Any  #: battery voltage of r = 1 [V]
    exponent: Any  #: thrust (feature map) or command (summed map) scales as r^this
    scale: Any  #: thrust calibration factor
    lo: Any  #: band lower edge (input units of the map)
    hi: Any  #: band upper edge


def constants_of(p: Any, amap: AnfisMap | None = None) -> ThrustConstants:
    """:class:`ThrustConstants` of a ``QuadrotorParams`` (no ``amap``: band from its map) or of an FMU
    parameter view of a model built with ``amap`` (band from the ``anfis_band_*`` parameters)."""
    if amap is None:
        lo, hi = p.thrust_map.input_range[0]
    else:
        suffix = "" if amap.features is not None else "_us"
        lo, hi = getattr(p, f"anfis_band_lo{suffix}"), getattr(p, f"anfis_band_hi{suffix}")
    return ThrustConstants(p.pwm_idle_us, p.pwm_full_us, p.battery_nominal_V, p.thrust_voltage_exponent,
                           p.thrust_scale, lo, hi)


# --------------------------------------------------------------------------- summed-PWM maps (paper 000)
def thrust_sum(amap: AnfisMap, x_us: Any, idle_us: Any, lo_us: Any, hi_us: Any, xp: Any = NP) -> Any:
    """Thrust [N] of a summed-PWM map at summed PWM ``x_us`` with the physical extension outside ``[lo, hi]``."""
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
    """Per-motor PWM [us] that gives at ``nominal_V`` the thrust ``pwm_us`` gives at ``voltage_V`` (summed maps).

    An ESC sets the motor's duty cycle from the command above idle; the motor speed follows duty x
    battery voltage. The command is rescaled by ``(V / V_nom)^exponent``. Ratios below 1 % count as 1 %.
    """
    ratio = xp.fmax(voltage_V / nominal_V, MIN_VOLTAGE_RATIO)
    return idle_us + xp.fmax(pwm_us - idle_us, 0.0) * ratio**exponent


# --------------------------------------------------------------------------- feature maps
def command(pwm_us: Any, idle_us: Any, full_us: Any, xp: Any = NP) -> Any:
    """Normalised per-motor command ``u = max(pwm - idle, 0) / (full - idle)`` (0 at idle, 1 at full)."""
    return xp.fmax(pwm_us - idle_us, 0.0) / (full_us - idle_us)


def feature_input(amap: AnfisMap, pwm_us: Any, voltage_V: Any, c: ThrustConstants, xp: Any = NP) -> tuple[Any, Any]:
    """(x, r): the map's input (``u`` or ``u r``) and the battery ratio ``r = V / V_nom`` (floored)."""
    r = xp.fmax(voltage_V / c.nominal_V, MIN_VOLTAGE_RATIO)
    u = command(pwm_us, c.idle_us, c.full_us, xp)
    return (u * r if amap.inputs[0] == "u_eff" else u), r


def feature_thrust(amap: AnfisMap, x: Any, r: Any, lo: Any, hi: Any, xp: Any = NP) -> Any:
    """``G(x, r)`` [N per motor] with the physical extension outside ``[lo, hi]`` (``lo > 0``)."""
    x_in = xp.fmin(xp.fmax(x, lo), hi)
    t_in = amap.evaluate([x_in], xp, r)
    t_lo = xp.fmax(amap.evaluate([lo], xp, r), 0.0)
    t_hi = amap.evaluate([hi], xp, r)
    slope_edge = (t_hi - amap.evaluate([hi - EDGE_STEP_X], xp, r)) / EDGE_STEP_X
    slope = xp.fmax(slope_edge, MIN_SLOPE_FRACTION * xp.fmax(t_hi, 0.0) / hi)
    s = xp.fmax(x, 0.0) / lo
    return xp.where(x < lo, t_lo * s * s, xp.where(x > hi, t_hi + slope * (x - hi), t_in))


# --------------------------------------------------------------------------- what the FMU evaluates
def motor_thrust(amap: AnfisMap, pwm_us: Any, voltage_V: Any, c: ThrustConstants, n_motors: int,
                 xp: Any = NP) -> Any:
    """Thrust [N] of one motor at ``pwm_us`` and battery ``voltage_V``: the function the quadrotor FMU evaluates.

    Zero at and below idle; monotone in the command where the map is; see the module docstring.
    """
    if amap.features is not None:
        x, r = feature_input(amap, pwm_us, voltage_V, c, xp)
        return c.scale * r**c.exponent * feature_thrust(amap, x, r, c.lo, c.hi, xp)
    x = n_motors * effective_pwm(pwm_us, voltage_V, c.idle_us, c.nominal_V, c.exponent, xp)
    return c.scale * thrust_sum(amap, x, n_motors * c.idle_us, c.lo, c.hi, xp) / n_motors


def motor_out_of_band(amap: AnfisMap, pwm_us: Any, voltage_V: Any, c: ThrustConstants, n_motors: int,
                      xp: Any = NP) -> Any:
    """1 where a motor above idle runs outside the map's trained band, else 0."""
    if amap.features is not None:
        x, _ = feature_input(amap, pwm_us, voltage_V, c, xp)
    else:
        x = n_motors * effective_pwm(pwm_us, voltage_V, c.idle_us, c.nominal_V, c.exponent, xp)
    above_idle = xp.where(pwm_us > c.idle_us, 1.0, 0.0)
    return above_idle * out_of_band(x, c.lo, c.hi, xp)


def out_of_band(x: Any, lo: Any, hi: Any, xp: Any = NP) -> Any:
    """1 where ``x`` lies outside the trained band, else 0."""
    return xp.where(x < lo, 1.0, xp.where(x > hi, 1.0, 0.0))


# --------------------------------------------------------------------------- the map as FMU parameters
def map_param_variables(amap: AnfisMap) -> tuple[Variable, ...]:
    """FMU parameters holding the values of a one-input thrust map (its structure stays fixed at build)."""
    feat = amap.features is not None
    unit, sfx = ("1", "") if feat else ("us", "_us")
    what = "normalised command" if feat else "summed PWM"
    out: list[Variable] = []
    for j, (m, s) in enumerate(zip(amap.mf_mean[0], amap.mf_sigma[0], strict=True), start=1):
        out.append(Variable(f"anfis_mean_{j}{sfx}", unit, f"thrust map: centre of MF {j}, {what}", m))
        out.append(Variable(f"anfis_sigma_{j}{sfx}", unit, f"thrust map: width of MF {j}", s, 1e-9, None))
        if amap.mf_type == "gbell":
            b = amap.mf_slope[0][j - 1]  # type: ignore[index]
            out.append(Variable(f"anfis_slope_{j}", "1", f"thrust map: bell exponent of MF {j}", b, 1e-3, None))
    out += [Variable(name, "N", desc, value) for name, desc, value in consequent_parameters(amap)]
    lo, hi = amap.input_range[0]
    out.append(Variable(f"anfis_band_lo{sfx}", unit, f"thrust map: lower edge of the trained band ({what})", lo))
    out.append(Variable(f"anfis_band_hi{sfx}", unit, f"thrust map: upper edge of the trained band ({what})", hi))
    return tuple(out)


def consequent_parameters(amap: AnfisMap) -> list[tuple[str, str, float]]:
    """(FMU parameter name, description, value) of every consequent coefficient, rule by rule."""
    out = []
    for r, row in enumerate(amap.consequents, start=1):
        if amap.features is not None:
            for f, v in zip(amap.features, row, strict=True):
                out.append((f"anfis_cons_{r}_{f}_N", f"thrust map: rule {r} coefficient of feature {f} [N]", v))
            continue
        if amap.order == 1:
            out.append((f"anfis_cons_{r}_p_N_us", f"thrust map: rule {r} slope [N/us]", row[0]))
        out.append((f"anfis_cons_{r}_N", f"thrust map: rule {r} constant", row[-1]))
    return out


def map_from_params(amap: AnfisMap, pv: Any) -> AnfisMap:
    """``amap`` with its values taken from the parameter view ``pv`` (symbolic in code generation)."""
    n = len(amap.mf_mean[0])
    sfx = "" if amap.features is not None else "_us"
    mean = (tuple(getattr(pv, f"anfis_mean_{j}{sfx}") for j in range(1, n + 1)),)
    sigma = (tuple(getattr(pv, f"anfis_sigma_{j}{sfx}") for j in range(1, n + 1)),)
    slope = None
    if amap.mf_type == "gbell":
        slope = (tuple(getattr(pv, f"anfis_slope_{j}") for j in range(1, n + 1)),)
    names = [name for name, _, _ in consequent_parameters(amap)]
    width = len(amap.consequents[0])
    cons = tuple(tuple(getattr(pv, names[r * width + k]) for k in range(width)) for r in range(amap.n_rules))
    return dataclasses.replace(amap, mf_mean=mean, mf_sigma=sigma, mf_slope=slope, consequents=cons)

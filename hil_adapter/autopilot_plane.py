"""ArduPlane parameters from the fixed-wing model (see ``hil_adapter.autopilot_params``).

Rate loops: ``rate_derivatives`` gives the roll, pitch and yaw axis models at a trimmed airspeed
(``fmu_models.fixed_wing.linear.rate_axes``, uavbook ch. 5). ``rate_gains`` turns one axis into ArduPilot's
FF, P, I.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fmu_models.common.units import G0_M_S2 as G_M_S2
from fmu_models.common.units import RAD_TO_DEG
from fmu_models.fixed_wing.linear import rate_axes
from fmu_models.signals.pwm_mapping import default_mapping

TECS = "ArduPilot libraries/AP_TECS/AP_TECS.cpp range"

OVERSHOOT_MAX = 0.05  #: rate-step overshoot the linear design allows (the FMU test allows 15 %)
INTEGRATOR_TIME_S = 0.5  #: P / I of the rate loops [s]


@dataclass(frozen=True)
class AxisModel:
    """One rate axis at trim, linear: ``x' = A x + B surface``, the rate is state ``rate_index``; ``throw_rad``
    the surface's full throw (positive surface = positive rate, signs folded in)."""

    a: np.ndarray
    b: np.ndarray
    rate_index: int
    throw_rad: float

    @property
    def steady_gain(self) -> float:
        """Steady rate per surface deflection [1/s]."""
        x = np.linalg.solve(self.a, -self.b)
        return float(x[self.rate_index])


def surface_throws() -> dict[str, float]:
    """Full throw [rad] of each surface in the adapter's default PWM mapping (what ArduPilot's 45 reaches)."""
    return {c.target: c.out_max for c in default_mapping("fixed_wing").channels if c.target.endswith("_rad")}


def rate_derivatives(pv: Any, va_m_s: float) -> dict[str, AxisModel]:
    """Roll ``[p]``, pitch ``[alpha, q]`` (short period) and yaw ``[beta, r]`` (Dutch roll) models at airspeed
    ``va_m_s`` from the parameter view ``pv`` (home density): ``fmu_models.fixed_wing.linear.rate_axes`` with
    the surfaces' throws of the default mapping and the signs folded in (positive surface = positive rate)."""
    throws = surface_throws()
    surface = {"roll": "aileron_rad", "pitch": "elevator_rad", "yaw": "rudder_rad"}
    return {name: AxisModel(ax.a, np.abs(ax.b), ax.rate_index, throws[surface[name]])
            for name, ax in rate_axes(pv, va_m_s).items()}


def step_metrics(axis: AxisModel, ff: float, p: float, i: float, servo_tau_s: float, dt: float = 0.0025,
                 duration_s: float = 1.5) -> tuple[float, float]:
    """(10-90 % rise [s], overshoot [fraction]) of the linear loop for a unit rate step: surface =
    ``k (FF r + P e + I int e)`` (``k = throw (180/pi) / 45``, rates in rad/s) through the servo
    ``1/(tau s + 1)``; exact discretisation of the closed loop (states: model, servo, integrator)."""
    from scipy.linalg import expm

    k = axis.throw_rad * RAD_TO_DEG / 45.0
    n = len(axis.b)
    cl = np.zeros((n + 2, n + 2))
    cl[:n, :n] = axis.a
    cl[:n, n] = axis.b
    cl[n, n] = -1.0 / servo_tau_s
    cl[n, axis.rate_index] = -k * p / servo_tau_s
    cl[n, n + 1] = k / servo_tau_s
    cl[n + 1, axis.rate_index] = -i
    drive = np.zeros(n + 2)
    drive[n] = k * (ff + p) / servo_tau_s
    drive[n + 1] = i
    big = np.zeros((n + 3, n + 3))
    big[:n + 2, :n + 2], big[:n + 2, n + 2] = cl, drive
    step = expm(big * dt)
    ad, bd = step[:n + 2, :n + 2], step[:n + 2, n + 2]
    z, rates = np.zeros(n + 2), np.empty(round(duration_s / dt))
    for j in range(len(rates)):
        z = ad @ z + bd
        rates[j] = z[axis.rate_index]
    if not np.all(np.isfinite(rates)):
        return math.inf, math.inf
    above10, above90 = np.argmax(rates >= 0.1), np.argmax(rates >= 0.9)
    rise = (above90 - above10) * dt if rates.max() >= 0.9 else math.inf
    return rise, float(rates.max() - 1.0)


def rate_gains(axis: AxisModel, servo_tau_s: float, overshoot_max: float, integrator_time_s: float) -> dict[str, float]:
    """ArduPilot FF, P, I (at speed scaler 1) for one axis: the fastest 10-90 % rise of the linear loop
    (``step_metrics``) whose overshoot stays under ``overshoot_max``, over FF from 0.2 to 1 x the steady
    feed-forward ``1 / (steady_gain k)`` (which alone makes the steady rate exact) and P on a log grid around
    the servo-limited loop gain; ``I = P / integrator_time_s``."""
    k = axis.throw_rad * RAD_TO_DEG / 45.0
    ff_steady = 1.0 / (axis.steady_gain * k)
    p_unit = 1.0 / (k * axis.b.max() * servo_tau_s)  # loop gain 1/tau: the servo's own bandwidth
    best: tuple[float, float, float, float] | None = None
    for ff_frac in np.linspace(0.2, 1.0, 9):
        for p_frac in np.geomspace(0.01, 1.0, 15):
            ff, p = ff_frac * ff_steady, p_frac * p_unit
            rise, over = step_metrics(axis, ff, p, p / integrator_time_s, servo_tau_s)
            if over <= overshoot_max and (best is None or rise < best[0] - 1e-9):
                best = (rise, ff, p, over)
    if best is None:
        raise ValueError("no rate-loop gains keep the overshoot under the limit")
    rise, ff, p, over = best
    return {"FF": ff, "P": p, "I": p / integrator_time_s, "rise_s": rise, "overshoot": over,
            "ff_steady": ff_steady}


# ------------------------------------------------------------------------------------------ trims
class _Trimmer:
    """Trims of the model at home density; ``None`` where no trim exists inside the surface throws."""

    def __init__(self, sim: Any, p: np.ndarray) -> None:
        from fmu_models.fixed_wing.trim import TrimError, trim

        self.sim, self.p, self._trim, self._err = sim, p, trim, TrimError
        self.pv = sim.model.params.view(p)
        self.elevator_limit = 0.8 * surface_throws()["elevator_rad"]  # 20 % of the throw left for control

    def at(self, va: float, gamma: float = 0.0) -> Any:
        try:
            t = self._trim(self.sim.model, self.p, va, gamma)
        except (self._err, ValueError):
            return None
        if (t.residual_norm > 1e-2 or abs(t.elevator_rad) > self.elevator_limit
                or t.alpha_rad > 0.9 * self.pv.alpha0_rad):
            return None
        return t

    def slowest(self, lo: float = 5.0, hi: float = 35.0) -> float:
        """The slowest level-flight trim speed [m/s] (stall or elevator limit, whichever comes first)."""
        if self.at(hi) is None:
            raise ValueError(f"the model has no level trim even at {hi} m/s")
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if self.at(mid) is not None else (mid, hi)
        return hi

    def gamma_at_throttle(self, va: float, throttle: float, lo: float, hi: float) -> float:
        """Flight-path angle [rad] at ``va`` whose trim throttle is ``throttle`` (bisection in [lo, hi])."""
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            t = self.at(va, mid)  # no trim: beyond full throttle (climbing) or below idle (descending)
            value = t.throttle if t is not None else (math.inf if mid > 0 else -math.inf)
            if value > throttle:
                hi = mid
            else:
                lo = mid
        return 0.5 * (lo + hi)


def _servos(out: Any) -> None:
    """SERVO1-4 as the adapter's default mapping reads them (ArduPilot functions 4, 19, 70, 21)."""
    function = {"aileron_rad": 4, "elevator_rad": 19, "throttle": 70, "rudder_rad": 21}
    for ch in sorted(default_mapping("fixed_wing").channels, key=lambda c: c.source):
        n = ch.source
        out(f"SERVO{n}_FUNCTION", function[ch.target], f"{ch.target} on output {n} (adapter default mapping)")
        out(f"SERVO{n}_MIN", ch.min_us)
        out(f"SERVO{n}_TRIM", ch.trim_us)
        out(f"SERVO{n}_MAX", ch.max_us)


#: ArduPlane's documented rate-gain ranges (AP_RollController / AP_PitchController / AP_YawController ``_RATE_*``)
RATE_GAIN_RANGES = {"FF": (0.0, 3.0), "P": (0.08, 0.35), "I": (0.01, 0.6)}
RATE_METADATA = "ArduPilot libraries/APM_Control/AP_{Roll,Pitch,Yaw}Controller.cpp _RATE_* @Range"
#: ArduPlane's documented RLL2SRV_TCONST / PTCH2SRV_TCONST range [s] (AP_RollController / AP_PitchController)
TCONST_S = (0.4, 1.0)
TCONST_SOURCE = "ArduPilot libraries/APM_Control/AP_{Roll,Pitch}Controller.cpp *2SRV_TCONST @Range"


def _rate_loops(out: Any, pv: Any, va: float, servo_tau_s: float) -> dict[str, float]:
    """RLL/PTCH/YAW_RATE_* at the cruise trim; returns the designed 10-90 % rise [s] by axis."""

    rises = {}
    for axis, prefix, model in zip(("roll", "pitch", "yaw"), ("RLL", "PTCH", "YAW"),
                                   rate_derivatives(pv, va).values(), strict=True):
        g = rate_gains(model, servo_tau_s, OVERSHOOT_MAX, INTEGRATOR_TIME_S)
        why = (f"{axis} at {va:.1f} m/s: linear {axis} model, servo {servo_tau_s} s; steady FF "
               f"{g['ff_steady']:.3g}; designed rise {g['rise_s']:.3f} s, overshoot {100 * g['overshoot']:.1f} %")
        out(f"{prefix}_RATE_FF", g["FF"], why, 4)
        out(f"{prefix}_RATE_P", g["P"], "", 4)
        out(f"{prefix}_RATE_I", g["I"], f"P / {INTEGRATOR_TIME_S} s", 4)
        out(f"{prefix}_RATE_D", 0.0, "ArduPlane's own default (AC_PID defaults d = 0)")
        for gain, key in (("FF", "FF"), ("P", "P"), ("I", "I")):
            name = f"{prefix}_RATE_{gain}"
            out.advise(name, out.values[name], *RATE_GAIN_RANGES[key], RATE_METADATA)
        rises[axis] = g["rise_s"]
    out("YAW_RATE_ENABLE", 1, "yaw rate loop on (gains above)")
    return rises


def arduplane(sim: Any, p: np.ndarray, out: Any, servo_tau_s: float) -> None:
    """Fill ``out`` with the ArduPlane set of the fixed-wing model ``sim`` with parameters ``p``."""
    trims = _Trimmer(sim, p)
    pv = trims.pv
    _servos(out)
    vs = trims.slowest()
    v_min = out("AIRSPEED_MIN", math.ceil(1.1 * vs), f"1.1 x the slowest level trim {vs:.1f} m/s (stall or 80 % "
                                                     "elevator, whichever first)")
    vc = out("AIRSPEED_CRUISE", max(v_min + 3, round(1.3 * vs)), "1.3 x the slowest trim")
    v_full = vc
    while v_full < 80 and (t := trims.at(v_full + 1)) is not None and t.throttle < 0.95:
        v_full += 1
    out("AIRSPEED_MAX", max(v_full, vc + 4), "fastest level trim below 95 % throttle")
    cruise = trims.at(vc)
    out("TRIM_THROTTLE", round(100 * cruise.throttle), f"trim throttle at {vc} m/s")
    out("SCALING_SPEED", vc, "the rate gains are computed at cruise: speed scaler 1 there")
    out("TKOFF_ROTATE_SPD", out.clamp("TKOFF_ROTATE_SPD", math.ceil(vs), 0, 30, "ArduPlane range [m/s]"),
        "the slowest trim speed: the elevator can hold the attitude from there")
    out("TKOFF_THR_MAX", 100)
    out("TKOFF_ALT", 50)
    out("TKOFF_LVL_ALT", 10)
    out("TKOFF_LVL_PITCH", 10)
    rises = _rate_loops(out, pv, vc, servo_tau_s)
    out("RLL2SRV_TCONST", out.clamp("RLL2SRV_TCONST", round(3 * rises["roll"], 2), *TCONST_S, TCONST_SOURCE),
        "3 x the designed roll-rate rise, inside ArduPlane's 0.4..1 s")
    pitch_tconst = out.clamp("PTCH2SRV_TCONST", round(3 * rises["pitch"], 2), *TCONST_S, TCONST_SOURCE)
    tconst = out("PTCH2SRV_TCONST", pitch_tconst, "3 x the designed pitch-rate rise, inside ArduPlane's 0.4..1 s")
    n_max = (vc / (1.15 * vs)) ** 2  # keep 15 % above the stall speed in the turn (Vs sqrt(n))
    bank = min(45.0, max(20.0, math.degrees(math.acos(min(1.0, 1 / n_max)))))
    # the limit is a command: the roll the controller reaches overshoots it (39.45 deg flown on a 39 deg limit)
    roll = out("ROLL_LIMIT_DEG", math.floor(bank / (1.0 + OVERSHOOT_MAX)),
               f"load factor {n_max:.2f} at cruise keeps 1.15 x the stall speed at {bank:.1f} deg (20..45); less the "
               f"{100 * OVERSHOOT_MAX:.0f} % overshoot the rate loops are designed to, so the roll reached stays "
               "inside it")
    radius = vc ** 2 / (G_M_S2 * math.tan(math.radians(roll)))
    out("WP_LOITER_RAD", 10 * math.ceil(2 * radius / 10), f"2 x the turn radius {radius:.0f} m at the roll limit")
    out("WP_RADIUS", 10 * math.ceil(radius / 10), "the turn radius at the roll limit")
    out("NAVL1_PERIOD", 20)
    out("NAVL1_DAMPING", 0.8)
    gamma_max = trims.gamma_at_throttle(vc, 0.9, 0.0, 0.4)
    climb = trims.at(vc, gamma_max)
    out("PTCH_LIM_MAX_DEG", round(min(25, max(8, math.degrees(gamma_max + climb.alpha_rad)))),
        f"climb at 90 % throttle and cruise: flight path {math.degrees(gamma_max):.1f} deg + alpha")
    gamma_glide = trims.gamma_at_throttle(vc, 0.0, -0.4, 0.0)
    out("PTCH_LIM_MIN_DEG", -round(min(25, max(10, 1.5 * abs(math.degrees(gamma_glide))))),
        f"1.5 x the idle glide angle {math.degrees(gamma_glide):.1f} deg (10..25)")
    out("TECS_CLMB_MAX", out.clamp("TECS_CLMB_MAX", round(0.8 * vc * math.sin(gamma_max), 1), 0.1, 20.0, TECS),
        "80 % of the climb rate at 90 % throttle")
    sink_min = out("TECS_SINK_MIN", out.clamp("TECS_SINK_MIN", round(vc * math.sin(abs(gamma_glide)), 1), 0.1, 10.0,
                                              TECS), "idle glide sink at cruise")
    lim_min = out.values["PTCH_LIM_MIN_DEG"]
    out("TECS_SINK_MAX", out.clamp("TECS_SINK_MAX", round(max(sink_min + 1, vc * math.sin(math.radians(-lim_min))), 1),
                                   0.0, 20.0, TECS), "the sink at cruise speed and the pitch floor (>= idle sink + 1)")
    t_ph = math.pi * math.sqrt(2) * vc / G_M_S2
    out("TECS_TIME_CONST", out.clamp("TECS_TIME_CONST", round(max(3.0, t_ph / 2.5), 1), 3.0, 10.0, TECS),
        f"phugoid period pi sqrt(2) V/g = {t_ph:.1f} s / 2.5")
    _landing(out, trims, vs, tconst)


#: AP_TECS: TECS_LAND_TCONST 1..5 s, "smaller than TECS_TIME_CONST"
LAND_TCONST_S = (1.0, 5.0)
#: approach speed over the slowest level trim: the flare, flown with the motor stopped, bleeds 3-4 m/s before
#: touchdown (tests/fakes/arduplane.py on the Aerosonde); 1.2-1.3 x the stall speed is the usual approach margin
APPROACH_MARGIN = 1.25
#: the approach glide path as a fraction of the idle glide angle at the approach speed: TECS keeps throttle to
#: steepen (down to idle) and to flatten the path
GLIDE_FRACTION = 1.0 / 3.0
#: AP_TECS LAND_PMAX @Range [deg]
LAND_PMAX_DEG = (-5.0, 40.0)


def _landing(out: Any, trims: _Trimmer, vs: float, tconst: float) -> None:
    """Approach speed and glide path, TECS landing time constant, flare trigger and the flare's pitch limits from
    the trims at the approach speed and at the slowest trim speed ``vs``; the glide path goes into the mission
    (``out.glide_deg``)."""
    v_app = out("TECS_LAND_ARSPD", math.ceil(APPROACH_MARGIN * vs),
                f"{APPROACH_MARGIN} x the slowest level trim {vs:.1f} m/s: the flare, motor stopped, bleeds speed")
    idle = trims.gamma_at_throttle(v_app, 0.0, -0.4, 0.0)
    glide_deg = round(2 * GLIDE_FRACTION * math.degrees(-idle)) / 2
    out.glide_deg = glide_deg
    approach = trims.at(v_app, -math.radians(glide_deg))
    slowest = trims.at(vs + 0.05)
    t_ph = math.pi * math.sqrt(2) * v_app / G_M_S2
    hi = min(LAND_TCONST_S[1], out.values["TECS_TIME_CONST"] - 0.1)
    land_tc = out.clamp("TECS_LAND_TCONST", round(max(2.0, t_ph / 2.5), 1), LAND_TCONST_S[0], hi,
                        "AP_TECS range, below TECS_TIME_CONST")
    out("TECS_LAND_TCONST", land_tc,
        f"landing phugoid period {t_ph:.1f} s / 2.5 (the 2 s default is faster than the airframe's height response)")
    out("TECS_LAND_SINK", 0.5, "flare sink target [m/s], under the 1 m/s touchdown aim")
    approach_pitch = math.degrees(approach.alpha_rad) - glide_deg
    out("LAND_PITCH_DEG", max(0.0, round(approach_pitch)),
        f"flare pitch floor: level, or the approach pitch {approach_pitch:.1f} deg ({glide_deg} deg glide path at "
        f"{v_app} m/s) if higher; a higher floor pitches up at flare entry and floats the aircraft to a stall")
    pmax = out.clamp("TECS_LAND_PMAX", math.floor(math.degrees(slowest.alpha_rad)), *LAND_PMAX_DEG,
                     "AP_TECS LAND_PMAX @Range")
    out("TECS_LAND_PMAX", pmax, f"flare pitch ceiling: the angle of attack of the slowest trim "
        f"{math.degrees(slowest.alpha_rad):.1f} deg (level flare: pitch = alpha)")
    flare_sec = round(max(2.0, 3 * tconst + 1.0), 1)
    sink = v_app * math.sin(math.radians(glide_deg))
    out("LAND_FLARE_SEC", flare_sec, f"3 pitch time constants + 1 s to arrest the sink (on the glide path: at "
        f"{flare_sec * sink:.1f} m, the {sink:.2f} m/s approach sink)")
    out("LAND_FLARE_ALT", 3)


#: the shipped circuit's home (ArduPilot SITL's default, CMAC): latitude, longitude [deg], altitude [m]
CIRCUIT_HOME = (-35.363261, 149.16523, 584.0)
#: the landing point [m north of home], the final approach's length [m] and its last waypoint's height [m]
LAND_NORTH_M = 300.0
FINAL_M = 600.0
SHORT_FINAL_M = 15.0
#: (MAV_CMD, north [m], east [m], height [m]) before the final approach: takeoff (10 deg) to 50 m, a rectangle
CIRCUIT = ((22, 400.0, 0.0, 50.0), (16, 800.0, 0.0, 60.0), (16, 800.0, -500.0, 60.0))


def circuit_mission(glide_deg: float) -> str:
    """The shipped ArduPlane circuit (QGC WPL 110): takeoff, a rectangle, then a straight final of ``FINAL_M`` on
    the glide path of ``glide_deg`` through the landing point: its base corner, final turn and short-final
    waypoint lie on that path (ArduPlane's landing slope runs from the waypoint before MAV_CMD_NAV_LAND to the
    landing point)."""
    from fmu_models.common.wgs84 import radii_of_curvature

    lat0, lon0, alt0 = CIRCUIT_HOME
    r_m, r_n = (float(r) for r in radii_of_curvature(math.radians(lat0)))
    deg_n = math.degrees(1.0 / r_m)
    deg_e = math.degrees(1.0 / (r_n * math.cos(math.radians(lat0))))
    slope = math.tan(math.radians(glide_deg))
    h_final = round(FINAL_M * slope)
    start = LAND_NORTH_M - h_final / slope
    legs = (*CIRCUIT, (16, start, -500.0, h_final), (16, start, 0.0, h_final),
            (16, LAND_NORTH_M - SHORT_FINAL_M / slope, 0.0, SHORT_FINAL_M), (21, LAND_NORTH_M, 0.0, 0.0))
    rows = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{lat0:.8f}\t{lon0:.8f}\t{alt0:.8f}\t1"]
    for k, (cmd, north, east, h) in enumerate(legs, start=1):
        p1 = 10 if cmd == 22 else 0  # takeoff: minimum pitch [deg]
        rows.append(f"{k}\t0\t3\t{cmd}\t{p1}\t0\t0\t0\t{lat0 + north * deg_n:.8f}\t{lon0 + east * deg_e:.8f}\t"
                    f"{h:g}\t1")
    return "\n".join(rows) + "\n"

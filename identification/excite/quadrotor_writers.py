"""What ``uavfmu excite --vehicle quadrotor`` writes for a plan: stick steps for PX4 and ArduCopter, and ArduCopter
SystemId parameter files.

Stick signs of the plan (:meth:`~identification.excite.quadrotor.QuadExcitationPlan.sticks`): roll + right side
down, pitch + nose up, yaw + clockwise seen from above, throttle + climb, each in -1..1 about centre.

- PX4 MAVLink ``MANUAL_CONTROL`` (:func:`manual_control`): ``x`` pitch, ``y`` roll, ``r`` yaw in -1000..1000 and
  ``z`` thrust. MAVLink's message definition says ``x`` positive is forward (nose down), ``y`` positive right;
  PX4 reads ``r`` positive as positive yaw (clockwise from above, its ``manual_control_setpoint``), and PX4 v1.13's
  ``mavlink_receiver`` divides every axis by 1000 and takes ``z`` in 0..1000 (what QGroundControl sends), 500 the
  centred throttle stick, which ALTCTL holds altitude at (within ``MPC_HOLD_DZ``). So ``x = -1000 pitch``,
  ``y = 1000 roll``, ``r = 1000 yaw``, ``z = 500 + 500 throttle``.
- ArduCopter ``RC_CHANNELS_OVERRIDE`` (:func:`rc_override`): channels 1-4 roll, pitch, throttle, yaw (RCMAP
  defaults) at ``centre + half_range x stick`` [us]. ArduCopter reads a high roll PWM as roll right, a high pitch
  PWM as pitch back (nose up: "pitch forward = low PWM"), a high yaw PWM as yaw right; AltHold holds altitude with
  the throttle stick within ``THR_DZ`` of mid.
- ArduCopter SystemId (:func:`sid_parameters`, flight mode 25, ``ArduCopter/mode_systemid.cpp``): one parameter
  file per axis. ``SID_AXIS`` injects at the mixer (10 roll, 11 pitch, 12 yaw, 13 thrust; magnitude in 0..1
  actuator units) or, with ``sid_injection = "rate"``, at the rate set-point (7 roll, 8 pitch, 9 yaw; deg/s).
  The chirp runs from ``sid_band_low`` x the axis's stick natural frequency to ``sid_band_high`` x its rate loop's
  (or the motor corner ``1/tau_motor_s`` when higher), within ``max_frequency_hz``; its magnitude keeps the
  closed-loop attitude (yaw rate, climb rate) response within the plan's limits across the band
  (:func:`identification.excite.quadrotor.attitude_response`). Ranges are the parameters' documented ones
  (:data:`SID_RANGES`); the mode refuses a record not longer than two periods of the start frequency, so
  ``SID_T_REC`` is that plus ``sid_sweep_s``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fmu_models.config import bounded, range_problems
from identification.excite.quadrotor import AXES, RATE_AXES, QuadExcitationPlan, attitude_response

#: MANUAL_CONTROL field limits (MAVLink common.xml; z: PX4 v1.13 takes 0..1000)
MANUAL_CONTROL_LIMITS = {"x": (-1000, 1000), "y": (-1000, 1000), "z": (0, 1000), "r": (-1000, 1000)}
#: ArduCopter RCMAP defaults: roll 1, pitch 2, throttle 3, yaw 4
RC_CHANNELS = {"roll": 1, "pitch": 2, "throttle": 3, "yaw": 4}
SYSTEMID_MODE = 25  #: ArduCopter flight-mode number of SystemId
SID_AXIS = {"mixer": {"roll": 10, "pitch": 11, "yaw": 12, "throttle": 13},
            "rate": {"roll": 7, "pitch": 8, "yaw": 9, "throttle": 13}}
INJECTIONS = ("mixer", "rate")
#: documented ranges of ArduCopter's SID_* parameters (mode_systemid.cpp @Range; SID_AXIS @Values 0..13 there)
SID_RANGES = {"SID_AXIS": (0, 13), "SID_F_START_HZ": (0.01, 100.0), "SID_F_STOP_HZ": (0.01, 100.0),
              "SID_T_FADE_IN": (0.0, 20.0), "SID_T_REC": (0.0, 255.0), "SID_T_FADE_OUT": (0.0, 5.0)}


@dataclass(frozen=True)
class QuadOutputOptions:
    """Rates, channels and chirp settings of the written files."""

    rc_rate_hz: float = bounded(50.0, 1.0, 100.0, "Hz")
    rc_centre_us: float = bounded(1500.0, 1000.0, 2000.0, "us")
    rc_half_range_us: float = bounded(500.0, 50.0, 1000.0, "us")
    sid_injection: str = "mixer"
    sid_band_low: float = bounded(0.3, 0.01, 1.0)
    sid_band_high: float = bounded(3.0, 1.0, 50.0)
    sid_sweep_s: float = bounded(40.0, 5.0, 200.0, "s")
    sid_fade_in_s: float = bounded(5.0, 0.0, 20.0, "s")
    sid_fade_out_s: float = bounded(2.0, 0.0, 5.0, "s")
    sid_max_mixer: float = bounded(0.2, 0.01, 1.0)

    def problems(self) -> list[str]:
        out = range_problems(self)
        if self.sid_injection not in INJECTIONS:
            out.append(f"sid_injection: {self.sid_injection!r} unknown; allowed {', '.join(INJECTIONS)}")
        lo, hi = self.rc_centre_us - self.rc_half_range_us, self.rc_centre_us + self.rc_half_range_us
        if lo < 800 or hi > 2200:
            out.append(f"rc_centre_us +- rc_half_range_us spans {lo:g}..{hi:g} us; allowed within 800..2200")
        return out


def _rows_times(plan: QuadExcitationPlan, rate_hz: float) -> np.ndarray:
    return np.round(np.arange(0.0, plan.duration_s, 1.0 / rate_hz), 4)


def _warnings(plan: QuadExcitationPlan, rate_hz: float) -> list[str]:
    shortest = min(b.pulse_unit_s for b in plan.blocks if b.pulse_unit_s)
    if shortest * rate_hz < 2:
        return [f"the shortest pulse ({shortest:g} s) spans fewer than 2 rows at {rate_hz:g} Hz: raise --rc-rate"]
    return []


def _phase(plan: QuadExcitationPlan, t: float) -> tuple[str, int]:
    b = plan.active_block(t)
    return ("excite", b.index) if b else ("recover", 0)


def manual_control(plan: QuadExcitationPlan, out: QuadOutputOptions = QuadOutputOptions()) -> dict[str, Any]:
    """Timed PX4 MANUAL_CONTROL fields (see the module docstring), with the modes to fly them in."""
    t = _rows_times(plan, out.rc_rate_hz)
    st = plan.sticks(t)
    rows = []
    for k, tk in enumerate(t):
        roll, pitch, yaw, thr = (float(v) for v in st[k])
        phase, block = _phase(plan, float(tk))
        rows.append({"t_s": float(tk), "phase": phase, "block": block, "x": round(-1000 * pitch),
                     "y": round(1000 * roll), "z": round(500 + 500 * thr), "r": round(1000 * yaw)})
    return {"format": "uavfmu MAVLink MANUAL_CONTROL steps (PX4)", "time_base": "seconds from the first row sent",
            "rate_hz": out.rc_rate_hz, "limits": {k: list(v) for k, v in MANUAL_CONTROL_LIMITS.items()},
            "modes": {"excite": "ALTCTL", "recover": "POSCTL"},
            "axes": {"x": "pitch stick, +1000 forward (nose down)", "y": "roll stick, +1000 right",
                     "z": "throttle stick 0..1000, 500 centred (ALTCTL: hold altitude)",
                     "r": "yaw stick, +1000 yaw right (clockwise from above)"},
            "warnings": _warnings(plan, out.rc_rate_hz), "rows": rows}


def rc_override(plan: QuadExcitationPlan, out: QuadOutputOptions = QuadOutputOptions()) -> dict[str, Any]:
    """Timed ArduCopter RC_CHANNELS_OVERRIDE pulse widths of channels 1-4 (see the module docstring)."""
    t = _rows_times(plan, out.rc_rate_hz)
    st = plan.sticks(t)
    rows = []
    for k, tk in enumerate(t):
        phase, block = _phase(plan, float(tk))
        pwm = {str(RC_CHANNELS[a]): round(out.rc_centre_us + out.rc_half_range_us * float(st[k, AXES.index(a)]))
               for a in AXES}
        rows.append({"t_s": float(tk), "phase": phase, "block": block, "pwm_us": pwm})
    return {"format": "uavfmu RC override steps (ArduCopter)", "time_base": "seconds from the first row sent",
            "rate_hz": out.rc_rate_hz, "channels": dict(RC_CHANNELS),
            "range_us": [out.rc_centre_us - out.rc_half_range_us, out.rc_centre_us + out.rc_half_range_us],
            "modes": {"excite": "ALT_HOLD", "recover": "LOITER"},
            "release": "send 0 on channels 1-4 after the last row to hand the sticks back",
            "warnings": _warnings(plan, out.rc_rate_hz), "rows": rows}


def manual_control_csv(data: dict[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["t_s", "phase", "block", "x", "y", "z", "r"])
    for r in data["rows"]:
        w.writerow([r["t_s"], r["phase"], r["block"], r["x"], r["y"], r["z"], r["r"]])
    return buf.getvalue()


def rc_override_csv(data: dict[str, Any]) -> str:
    chans = sorted(data["channels"].values())
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["t_s", "phase", "block", *(f"ch{c}_us" for c in chans)])
    for r in data["rows"]:
        w.writerow([r["t_s"], r["phase"], r["block"], *(r["pwm_us"][str(c)] for c in chans)])
    return buf.getvalue()


def _clip(name: str, value: float) -> float:
    lo, hi = SID_RANGES[name]
    return float(min(max(value, lo), hi))


def sid_values(plan: QuadExcitationPlan, axis: str, out: QuadOutputOptions = QuadOutputOptions()) -> dict[str, float]:
    """The SID_* values of one axis's chirp (see the module docstring)."""
    opt, h = plan.options, plan.hover
    w_max = 2 * math.pi * min(opt.max_frequency_hz, opt.rate_hz / 10.0)
    lp = plan.axis_loops[axis]
    top = lp.rate_bandwidth_rad_s or lp.bandwidth_rad_s
    if h.tau_motor_s > 0:
        top = max(top, 1.0 / h.tau_motor_s)
    f_stop = _clip("SID_F_STOP_HZ", min(out.sid_band_high * top, w_max) / (2 * math.pi))
    f_start = out.sid_band_low * lp.bandwidth_rad_s / (2 * math.pi)
    f_start = _clip("SID_F_START_HZ", max(f_start, 2.0 / (SID_RANGES["SID_T_REC"][1] - out.sid_sweep_s)))
    f_start = min(f_start, f_stop / 2)
    t_rec = _clip("SID_T_REC", 2.0 / f_start + out.sid_sweep_s)
    w = 2 * math.pi * np.geomspace(f_start, f_stop, 400)
    injection = out.sid_injection if axis in RATE_AXES else "mixer"
    if axis == "throttle":  # SystemId flies a manual throttle: climb rate = collective x d / w
        limit = opt.attitude_fraction * opt.climb_limit_m_s
        mag = min(out.sid_max_mixer, limit * float(w[0]) / h.collective_m_s2)
    else:
        resp = attitude_response(h, plan.loops, opt.loop_delay_s, axis, injection, w)
        if axis == "yaw":  # the yaw rate, not the heading, is the limit
            resp = resp * w
            limit = opt.attitude_fraction * math.radians(opt.yaw_rate_limit_deg_s)
        else:
            limit = opt.attitude_fraction * math.radians(opt.roll_limit_deg)
        mag = limit / float(np.max(resp))
        mag = min(out.sid_max_mixer, mag) if injection == "mixer" else math.degrees(mag)
    return {"SID_AXIS": SID_AXIS[injection][axis], "SID_MAGNITUDE": round(mag, 4),
            "SID_F_START_HZ": round(f_start, 3), "SID_F_STOP_HZ": round(f_stop, 3),
            "SID_T_FADE_IN": round(min(out.sid_fade_in_s, t_rec / 4), 2), "SID_T_REC": round(t_rec, 1),
            "SID_T_FADE_OUT": round(min(out.sid_fade_out_s, t_rec / 4), 2)}


def sid_parameters(plan: QuadExcitationPlan, out: QuadOutputOptions = QuadOutputOptions(),
                   command: str = "uavfmu excite --vehicle quadrotor") -> dict[str, str]:
    """One ArduPilot parameter file (``NAME VALUE`` lines) per planned axis: axis -> text."""
    files = {}
    for axis in plan.options.axes:
        v = sid_values(plan, axis, out)
        unit = "0..1 of the actuator range" if v["SID_AXIS"] >= 10 else "deg/s"
        head = [f"# ArduCopter SystemId chirp on {axis}, written by `{command}` (uavfmu)",
                f"# fly: load, switch to flight mode {SYSTEMID_MODE} (SystemId) in a hover with room; it sweeps "
                f"{v['SID_F_START_HZ']:g}..{v['SID_F_STOP_HZ']:g} Hz over {v['SID_T_REC']:g} s",
                f"# SID_MAGNITUDE in {unit}; band from the model: {axis} stick natural frequency "
                f"{plan.axis_loops[axis].bandwidth_rad_s:.2f} rad/s, motor time constant "
                f"{plan.hover.tau_motor_s:g} s"]
        files[axis] = "\n".join([*head, *(f"{k} {val:g}" for k, val in v.items())]) + "\n"
    return files


__all__ = ["INJECTIONS", "MANUAL_CONTROL_LIMITS", "RC_CHANNELS", "SID_AXIS", "SID_RANGES", "SYSTEMID_MODE",
           "QuadOutputOptions", "manual_control", "manual_control_csv", "rc_override",
           "rc_override_csv", "sid_parameters", "sid_values"]

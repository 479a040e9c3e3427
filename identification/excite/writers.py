"""What ``uavfmu excite`` writes for a plan: the timeline, MAVLink RC-override steps, an ArduPilot Lua script.

Surface deflections become pulse widths through the same :class:`fmu_models.signals.pwm_mapping.PwmMapping`
that ``identify aero`` and the HIL adapter use (default: ArduPlane SERVO1-4, +/-0.35 rad over 1100..1900 us,
elevator and rudder reversed into uavbook signs), so a planned +0.1 rad aileron is the pulse that ``identify
aero`` reads back as +0.1 rad.

- Timeline (:func:`timeline_dict`): the schema of :mod:`identification.logs.timeline`, times from the plan's start.
- RC override (:func:`rc_override`): timed stick offsets [us] about the sticks' positions when the sequence
  starts, for RC_CHANNELS_OVERRIDE from a ground-station script, with the phase (excite/recover) of each row
  and the mode each autopilot should be in. In ArduPlane MANUAL and PX4 Manual the sticks pass to the surfaces:
  a stick offset is ``servo offset * rc_half_range_us / servo half range`` (full stick = full throw).
- Lua (:func:`lua_script`): ArduPilot script that runs the plan on a switch, overrides the servo outputs
  (``SRV_Channels:set_output_pwm_chan_timeout``) about the outputs captured at each hand-over, and aborts to
  the recovery mode when roll, pitch, airspeed or height leave their limits or the switch goes low.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fmu_models.config import bounded, range_problems
from fmu_models.signals.pwm_mapping import PwmMapping, default_mapping
from identification.excite.design import SURFACES, Block, ExcitationPlan
from identification.logs.timeline import Timeline

#: ArduPilot SERVOn_FUNCTION numbers (Plane): aileron, elevator, rudder, throttle
SERVO_FUNCTION = {"aileron": 4, "elevator": 19, "rudder": 21, "throttle": 70}
#: ArduPlane mode numbers (Plane/mode.h): the ones a plan may use
ARDUPLANE_MODES = {"MANUAL": 0, "STABILIZE": 2, "ACRO": 4, "FBWA": 5, "FBWB": 6, "CRUISE": 7}
#: modes a ground-station script sets per autopilot (pymavlink mode names)
AUTOPILOT_MODES = {"ardupilot": {"excite": "MANUAL", "recover": "FBWA"},
                   "px4": {"excite": "MANUAL", "recover": "STABILIZED"}}
DEFAULT_RC_CHANNELS = {"aileron": 1, "elevator": 2, "throttle": 3, "rudder": 4}
_INPUT = {"aileron": "aileron_rad", "elevator": "elevator_rad", "rudder": "rudder_rad", "throttle": "throttle"}


@dataclass(frozen=True)
class Limits:
    """Abort limits of the Lua script and the ground-station example."""

    roll_deg: float
    pitch_min_deg: float
    pitch_max_deg: float
    min_airspeed_m_s: float
    min_height_m: float


@dataclass(frozen=True)
class OutputOptions:
    """Modes, channels and limits of the written files."""

    excite_mode: str = "MANUAL"
    recovery_mode: str = "FBWA"
    trigger_channel: int = bounded(8, 1, 18)
    trigger_pwm_us: int = bounded(1700, 1000, 2200, "us")
    rc_channels: Mapping[str, int] = field(default_factory=lambda: dict(DEFAULT_RC_CHANNELS))
    rc_half_range_us: float = bounded(500.0, 50.0, 1000.0, "us")
    rc_rate_hz: float = bounded(20.0, 1.0, 100.0, "Hz")
    min_airspeed_m_s: float = bounded(0.0, 0.0, 100.0, "m/s")  #: 0: 0.7 x the plan's airspeed
    min_height_m: float = bounded(40.0, 0.0, 10000.0, "m")
    mapping: PwmMapping | None = None

    def problems(self) -> list[str]:
        out = range_problems(self)
        out += [f"{m} = {v!r}: not one of {', '.join(ARDUPLANE_MODES)}" for m, v in
                (("excite_mode", self.excite_mode), ("recovery_mode", self.recovery_mode)) if v not in ARDUPLANE_MODES]
        missing = [s for s in (*SURFACES, "throttle") if s not in self.rc_channels]
        out += [f"rc_channels: no channel for {', '.join(missing)}"] if missing else []
        out += [f"rc_channels.{k} = {v!r}; allowed range [1, 8]" for k, v in self.rc_channels.items()
                if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 8]
        return out

    def servo_mapping(self) -> PwmMapping:
        return self.mapping or default_mapping("fixed_wing")


def limits(plan: ExcitationPlan, out: OutputOptions) -> Limits:
    """Roll and pitch limits of the plan (pitch about the trim pitch), airspeed and height floors."""
    o = plan.options
    theta = math.degrees(plan.linear.x_trim[4])
    vmin = out.min_airspeed_m_s or 0.7 * plan.linear.va_m_s
    return Limits(o.roll_limit_deg, theta - o.pitch_limit_deg, theta + o.pitch_limit_deg, vmin, out.min_height_m)


def servo_offset_us(mapping: PwmMapping, surface: str, delta: float) -> float:
    """Pulse offset [us] from trim that the mapping reads as ``delta`` [rad] (or throttle fraction) about trim."""
    ch = next(c for c in mapping.channels if c.target == _INPUT[surface])
    return float(ch.to_pwm(delta) - ch.to_pwm(0.0))


def servo_half_range_us(mapping: PwmMapping, surface: str) -> float:
    ch = next(c for c in mapping.channels if c.target == _INPUT[surface])
    return float(min(ch.max_us - ch.trim_us, ch.trim_us - ch.min_us))


# ------------------------------------------------------------------ timeline
def timeline_dict(plan: ExcitationPlan, out: OutputOptions = OutputOptions()) -> dict[str, Any]:
    """The plan as a timeline (schema :class:`identification.logs.timeline.Timeline`), validated before return."""
    mapping = out.servo_mapping()
    blocks = []
    for b in plan.blocks:
        amp = {s: sig.peak_rad() for s, sig in b.signals.items()}
        blocks.append({
            "index": b.index, "axis": b.axis, "axes": list(b.signals) if b.axis == "multi" else [],
            "channel": out.rc_channels.get(b.axis) if b.axis != "multi" else None,
            "mode": out.excite_mode, "recovery_mode": out.recovery_mode, "input": b.input,
            "pulse_unit_s": b.pulse_unit_s, "start_s": round(b.start_s, 4),
            "excitation_start_s": round(b.excitation_start_s, 4), "end_s": round(b.end_s, 4),
            "recovery_end_s": round(b.end_s + plan.options.recovery_s, 4),
            "amplitude_rad": amp,
            "amplitude_servo_us": {s: abs(servo_offset_us(mapping, s, a)) for s, a in amp.items()},
            "predicted_linear_peak_deg": b.predicted_peak_deg,
        })
    data = {
        "plan": "uavfmu excite", "log": None,
        "time_base": "seconds from the start of the planned sequence (Lua: the sample the trigger switch went "
                     "high, logged as EXCT phase 0; RC override: the first row sent); add that moment's log time "
                     "to use it with a log",
        "airspeed_m_s": plan.linear.va_m_s, "rate_hz": plan.options.rate_hz,
        "modes": {m.name: m.as_dict() for m in plan.modes.all()}, "blocks": blocks}
    Timeline.model_validate(data)  # the schema identify aero reads
    return data


# ------------------------------------------------------------------ RC override
def rc_override(plan: ExcitationPlan, out: OutputOptions = OutputOptions()) -> dict[str, Any]:
    """Timed RC-override stick offsets about the sticks at the start, with the phase and modes (JSON-able)."""
    mapping = out.servo_mapping()
    t = np.round(np.arange(0.0, plan.duration_s, 1.0 / out.rc_rate_hz), 4)  # the times written
    du = plan.deflection(t)
    rows = []
    for k, tk in enumerate(t):
        blk = plan.active_block(float(tk))
        offs = {}
        for s in SURFACES:
            servo = servo_offset_us(mapping, s, du[k, SURFACES.index(s)])
            offs[str(out.rc_channels[s])] = round(servo * out.rc_half_range_us / servo_half_range_us(mapping, s), 1)
        offs[str(out.rc_channels["throttle"])] = 0.0
        rows.append({"t_s": float(tk), "phase": "excite" if blk else "recover",
                     "block": blk.index if blk else 0, "offset_us": offs})
    lim = limits(plan, out)
    warnings = []
    shortest = min((b.pulse_unit_s for b in plan.blocks if b.pulse_unit_s), default=None)
    if shortest is not None and shortest * out.rc_rate_hz < 2:
        warnings.append(f"the shortest pulse ({shortest:g} s) spans fewer than 2 rows at {out.rc_rate_hz:g} Hz: "
                        "raise --rc-rate or use the Lua script")
    top = max((w for b in plan.blocks for sig in b.signals.values() for w, _, _ in sig.sines), default=0.0)
    if top and out.rc_rate_hz < 5 * top / (2 * math.pi):
        warnings.append(f"the multisine reaches {top / (2 * math.pi):.2g} Hz: fewer than 5 rows per period at "
                        f"{out.rc_rate_hz:g} Hz; raise --rc-rate or use the Lua script")
    return {"format": "uavfmu RC override steps", "warnings": warnings, "time_base": "seconds from the first row sent",
            "rate_hz": out.rc_rate_hz, "channels": dict(out.rc_channels),
            "offset_about": "each channel's RC input (RC_CHANNELS) when the sequence starts",
            "modes": {k: dict(v) for k, v in AUTOPILOT_MODES.items()},
            "limits": lim.__dict__, "rows": rows}


def rc_override_csv(data: dict[str, Any]) -> str:
    """The rows of :func:`rc_override` as CSV: t_s, phase, block, ch<N>_offset_us..."""
    chans = sorted(data["rows"][0]["offset_us"], key=int)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["t_s", "phase", "block", *(f"ch{c}_offset_us" for c in chans)])
    for r in data["rows"]:
        w.writerow([r["t_s"], r["phase"], r["block"], *(r["offset_us"][c] for c in chans)])
    return buf.getvalue()


# ------------------------------------------------------------------ Lua
def _lua_block(b: Block, mapping: PwmMapping) -> str:
    parts = []
    for s, sig in b.signals.items():
        if sig.steps:
            steps = ", ".join(f"{{{1000 * t:.0f}, {servo_offset_us(mapping, s, v):.1f}}}" for t, v in sig.steps)
            parts.append(f"{s} = {{steps = {{{steps}}}}}")
        else:
            sines = ", ".join(f"{{{w:.6f}, {ph:.6f}, {servo_offset_us(mapping, s, a):.4f}}}" for w, ph, a in sig.sines)
            parts.append(f"{s} = {{duration_ms = {1000 * sig.duration_s:.0f}, sines = {{{sines}}}}}")
    return (f"  {{index = {b.index}, start_ms = {1000 * b.start_s:.0f}, excite_ms = {1000 * b.excitation_start_s:.0f}, "
            f"end_ms = {1000 * b.end_s:.0f}, input = \"{b.input}\", axis = \"{b.axis}\",\n"
            f"   signals = {{{', '.join(parts)}}}}},")


def lua_script(plan: ExcitationPlan, out: OutputOptions = OutputOptions(), command: str = "uavfmu excite") -> str:
    """The ArduPilot Lua script of ``plan`` (see the module docstring and docs/excitation.md)."""
    bad = out.problems()
    if bad:
        raise ValueError("; ".join(bad))
    lim = limits(plan, out)
    blocks = "\n".join(_lua_block(b, out.servo_mapping()) for b in plan.blocks)
    return LUA_TEMPLATE.format(
        command=command, blocks=blocks, excite=ARDUPLANE_MODES[out.excite_mode], excite_name=out.excite_mode,
        recover=ARDUPLANE_MODES[out.recovery_mode], recover_name=out.recovery_mode, trigger=out.trigger_channel,
        trigger_pwm=out.trigger_pwm_us, roll=lim.roll_deg, pmin=lim.pitch_min_deg, pmax=lim.pitch_max_deg,
        vmin=lim.min_airspeed_m_s, hmin=lim.min_height_m, end_ms=round(1000 * plan.duration_s),
        period_ms=max(10, round(1000 / plan.options.rate_hz)))


LUA_TEMPLATE = """\
-- Identification manoeuvres for ArduPlane, written by `{command}` (uavfmu).
-- Switch RC{trigger} above {trigger_pwm} us (armed, flying, in any mode) to start; the sequence runs its blocks:
-- at each block's start the servo outputs are captured as trim and the mode becomes {excite_name}; the surfaces
-- are overridden (SRV_Channels:set_output_pwm_chan_timeout) with trim + the planned offsets; at the block's end
-- the mode becomes {recover_name} until the next block. Roll beyond {roll:.1f} deg, pitch outside
-- [{pmin:.1f}, {pmax:.1f}] deg, airspeed below {vmin:.1f} m/s, height above home below {hmin:.1f} m, or the switch
-- going low abort: overrides stop and the mode becomes {recover_name}. Times in ms from the trigger; EXCT log
-- messages (block, phase: 0 start, 1 hand-over, 2 input, 3 recovery, 4 done, 5 abort) mark them in the log.

local EXCITE_MODE = {excite}    -- {excite_name}
local RECOVERY_MODE = {recover}  -- {recover_name}
local TRIGGER_CHANNEL = {trigger}
local TRIGGER_PWM = {trigger_pwm}
local ROLL_LIMIT = math.rad({roll:.3f})
local PITCH_MIN = math.rad({pmin:.3f})
local PITCH_MAX = math.rad({pmax:.3f})
local MIN_AIRSPEED = {vmin:.3f}
local MIN_HEIGHT = {hmin:.3f}
local END_MS = {end_ms}
local PERIOD_MS = {period_ms}
local FUNCTIONS = {{aileron = 4, elevator = 19, rudder = 21, throttle = 70}}
local ORDER = {{"aileron", "elevator", "rudder", "throttle"}}

local BLOCKS = {{
{blocks}
}}

local state = "idle"
local t0 = nil
local current = nil
local trim = {{}}

local function log_phase(index, phase)
  logger:write("EXCT", "Blk,Ph", "BB", index, phase)
end

local function offset(sig, t_ms)
  if sig == nil or t_ms < 0 then return 0 end
  if sig.steps ~= nil then
    for _, s in ipairs(sig.steps) do
      if t_ms < s[1] then return s[2] end
    end
    return 0
  end
  if t_ms < 0 or t_ms >= sig.duration_ms then return 0 end
  local t = t_ms / 1000.0
  local u = 0
  for _, c in ipairs(sig.sines) do
    u = u + c[3] * math.cos(c[1] * t + c[2])
  end
  return u
end

local function capture_trim()
  for _, name in ipairs(ORDER) do
    trim[name] = SRV_Channels:get_output_pwm(FUNCTIONS[name])
  end
end

local function drive(block, t_ms)
  for _, name in ipairs(ORDER) do
    local chan = SRV_Channels:find_channel(FUNCTIONS[name])
    if chan ~= nil and trim[name] ~= nil then
      local pwm = trim[name] + offset(block.signals[name], t_ms - block.excite_ms)
      SRV_Channels:set_output_pwm_chan_timeout(chan, math.floor(pwm + 0.5), 3 * PERIOD_MS)
    end
  end
end

local function outside_limits()
  local roll = ahrs:get_roll()
  local pitch = ahrs:get_pitch()
  if math.abs(roll) > ROLL_LIMIT then return string.format("roll %.0f deg", math.deg(roll)) end
  if pitch < PITCH_MIN or pitch > PITCH_MAX then return string.format("pitch %.0f deg", math.deg(pitch)) end
  local airspeed = ahrs:airspeed_estimate()
  if airspeed ~= nil and airspeed < MIN_AIRSPEED then return string.format("airspeed %.1f m/s", airspeed) end
  local down = ahrs:get_relative_position_D_home()
  if down ~= nil and -down < MIN_HEIGHT then return string.format("height %.0f m", -down) end
  return nil
end

local function stop(reason, phase)
  vehicle:set_mode(RECOVERY_MODE)
  log_phase(current and current.index or 0, phase)
  gcs:send_text(phase == 5 and 2 or 6, "excite: " .. reason)
  state = (phase == 5) and "aborted" or "done"
  current = nil
end

local function find_block(t_ms)
  for _, b in ipairs(BLOCKS) do
    if t_ms >= b.start_ms and t_ms < b.end_ms then return b end
  end
  return nil
end

local function run(t_ms)
  local sw = rc:get_pwm(TRIGGER_CHANNEL)
  if sw == nil or sw < TRIGGER_PWM then return stop("switch low", 5) end
  if t_ms >= END_MS then return stop("sequence done", 4) end
  local b = find_block(t_ms)
  if b ~= current then
    if current ~= nil then
      vehicle:set_mode(RECOVERY_MODE)
      log_phase(current.index, 3)
    end
    if b ~= nil then
      capture_trim()
      vehicle:set_mode(EXCITE_MODE)
      log_phase(b.index, 1)
      gcs:send_text(6, string.format("excite: block %d %s %s", b.index, b.input, b.axis))
    end
    current = b
  end
  if current == nil then return end
  local why = outside_limits()
  if why ~= nil then return stop("abort, " .. why, 5) end
  if t_ms >= current.excite_ms and t_ms - PERIOD_MS < current.excite_ms then log_phase(current.index, 2) end
  drive(current, t_ms)
end

function update()
  if state == "idle" then
    local sw = rc:get_pwm(TRIGGER_CHANNEL)
    if sw ~= nil and sw >= TRIGGER_PWM and arming:is_armed() then
      state = "running"
      t0 = millis()
      log_phase(0, 0)
      gcs:send_text(6, "excite: sequence started")
    end
  elseif state == "running" then
    run((millis() - t0):tofloat())
  else
    local sw = rc:get_pwm(TRIGGER_CHANNEL)
    if sw ~= nil and sw < TRIGGER_PWM then state = "idle" end  -- re-arm: switch low, then high again
  end
  return update, PERIOD_MS
end

gcs:send_text(6, "excite: loaded, switch RC" .. TRIGGER_CHANNEL .. " high to start")
return update, PERIOD_MS
"""

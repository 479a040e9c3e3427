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
from identification.excite.design import INPUT_INDEX, SURFACES, Block, ExcitationPlan
from identification.logs.timeline import Timeline

#: ArduPilot SERVOn_FUNCTION numbers (Plane): aileron, elevator, rudder, throttle
SERVO_FUNCTION = {"aileron": 4, "elevator": 19, "rudder": 21, "throttle": 70}
#: ArduPlane mode numbers (Plane/mode.h): the ones a plan may use
ARDUPLANE_MODES = {"MANUAL": 0, "STABILIZE": 2, "ACRO": 4, "FBWA": 5, "FBWB": 6, "CRUISE": 7}
#: modes a ground-station script sets per autopilot (pymavlink mode names)
AUTOPILOT_MODES = {"ardupilot": {"excite": "MANUAL", "hold": "FBWA", "recover": "FBWA"},
                   "px4": {"excite": "MANUAL", "hold": "STABILIZED", "recover": "STABILIZED"}}
#: block axes flown in the recovery (attitude-holding) mode instead of the excitation mode
HOLD_AXES = ("throttle",)
DEFAULT_RC_CHANNELS = {"aileron": 1, "elevator": 2, "throttle": 3, "rudder": 4}
#: ArduPilot's RC auxiliary functions meant for scripts (RCx_OPTION 300..307 "Scripting1".."Scripting8")
SCRIPTING_OPTIONS = tuple(range(300, 308))
#: EXCT.Ax code of each block axis (the order of identification.logs.flown_blocks.AXIS_CODES)
AXIS_CODE = {"aileron": 0, "elevator": 1, "rudder": 2, "throttle": 3, "multi": 4}
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
    #: ArduPilot RCx_OPTION of the trigger switch: 300..307 = "Scripting1".."Scripting8" (RC_Channel.h)
    trigger_option: int = bounded(SCRIPTING_OPTIONS[0], SCRIPTING_OPTIONS[0], SCRIPTING_OPTIONS[-1])
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
            "mode": out.recovery_mode if b.axis in HOLD_AXES else out.excite_mode,
            "recovery_mode": out.recovery_mode, "input": b.input,
            "pulse_unit_s": b.pulse_unit_s, "start_s": round(b.start_s, 4),
            "excitation_start_s": round(b.excitation_start_s, 4), "end_s": round(b.end_s, 4),
            "recovery_end_s": round(b.end_s + plan.options.recovery_s, 4),
            "amplitude_rad": {k: v for k, v in amp.items() if k != "throttle"},
            "amplitude_throttle": amp.get("throttle"),
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
        thr = servo_offset_us(mapping, "throttle", du[k, INPUT_INDEX["throttle"]])
        thr_ch = next(c for c in mapping.channels if c.target == "throttle")  # one-sided: full stick = full range
        offs[str(out.rc_channels["throttle"])] = round(thr * 2 * out.rc_half_range_us
                                                       / (thr_ch.max_us - thr_ch.min_us), 1)
        phase = "recover" if blk is None else "hold" if blk.axis in HOLD_AXES else "excite"
        rows.append({"t_s": float(tk), "phase": phase,
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
            f"end_ms = {1000 * b.end_s:.0f}, input = \"{b.input}\", axis = \"{b.axis}\", "
            f"axis_code = {AXIS_CODE[b.axis]}, hold = {'true' if b.axis in HOLD_AXES else 'false'},\n"
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
        recover=ARDUPLANE_MODES[out.recovery_mode], recover_name=out.recovery_mode, option=out.trigger_option,
        scripting=out.trigger_option - SCRIPTING_OPTIONS[0] + 1, roll=lim.roll_deg, pmin=lim.pitch_min_deg,
        pmax=lim.pitch_max_deg,
        vmin=lim.min_airspeed_m_s, hmin=lim.min_height_m, end_ms=round(1000 * plan.duration_s),
        period_ms=max(10, round(1000 / plan.options.rate_hz)))


LUA_TEMPLATE = """\
-- Identification manoeuvres for ArduPlane, written by `{command}` (uavfmu).
-- Trigger: the RC channel whose RCx_OPTION is {option} ("Scripting{scripting}"), switched high (above 1800 us).
-- The script refuses a channel that is also FLTMODE_CH or a stick channel (RCMAP_*), needs the switch seen low
-- after loading, and starts only when flying: armed, airspeed >= {vmin:.1f} m/s and height above home
-- >= {hmin:.1f} m; otherwise it says why and waits for the switch to go low and high again.
-- For each block: the servo outputs are captured as trim, the mode becomes {excite_name} ({recover_name} for a
-- throttle block: attitude held while the throttle moves), the surfaces and the throttle are overridden
-- (SRV_Channels:set_output_pwm_chan_timeout) with trim + the planned offsets; at the block's end the mode
-- becomes {recover_name} until the next block. Roll beyond {roll:.1f} deg, pitch outside
-- [{pmin:.1f}, {pmax:.1f}] deg, airspeed below {vmin:.1f} m/s, height below {hmin:.1f} m, or the switch leaving
-- high abort: overrides stop and the mode becomes {recover_name}. Times in ms from the trigger.
-- Log: EXCT (Blk, Ph, Ax, Tms, Pms) = block, phase (0 start, 1 hand-over, 2 input, 3 recovery, 4 done,
-- 5 abort), axis code (0 aileron, 1 elevator, 2 rudder, 3 throttle, 4 multi), the time since the trigger and
-- the planned time [ms]; written at the first tick at or after the planned time (TimeUS: the actual time).

local EXCITE_MODE = {excite}    -- {excite_name}
local RECOVERY_MODE = {recover}  -- {recover_name}
local TRIGGER_OPTION = {option}  -- RCx_OPTION "Scripting{scripting}"
local SWITCH_HIGH = 2           -- RC_Channel_ud:get_aux_switch_pos(): 0 low, 1 middle, 2 high
local ROLL_LIMIT = math.rad({roll:.3f})
local PITCH_MIN = math.rad({pmin:.3f})
local PITCH_MAX = math.rad({pmax:.3f})
local MIN_AIRSPEED = {vmin:.3f}
local MIN_HEIGHT = {hmin:.3f}
local END_MS = {end_ms}
local PERIOD_MS = {period_ms}
local CHECK_MS = 1000  -- how often the trigger channel's parameters are read while waiting
local FUNCTIONS = {{aileron = 4, elevator = 19, rudder = 21, throttle = 70}}
local ORDER = {{"aileron", "elevator", "rudder", "throttle"}}
local STICKS = {{"RCMAP_ROLL", "RCMAP_PITCH", "RCMAP_THROTTLE", "RCMAP_YAW"}}

local BLOCKS = {{
{blocks}
}}

local state = "wait_low"  -- wait_low -> idle -> running -> done/aborted/refused -> (switch low) idle
local t0 = nil
local current = nil
local input_marked = false
local trim = {{}}
local switch = nil
local said = {{}}

local function say(severity, text)
  gcs:send_text(severity, "excite: " .. text)
end

local function say_once(key, severity, text)
  if not said[key] then say(severity, text) end
  said[key] = true
end

local function mark(index, phase, axis_code, t_ms, planned_ms)
  logger:write("EXCT", "Blk,Ph,Ax,Tms,Pms", "BBBII", index, phase, axis_code,
               math.floor(math.max(t_ms, 0)), math.floor(math.max(planned_ms, 0)))
end

local function trigger_channel_number()
  for n = 1, 16 do
    local opt = param:get("RC" .. n .. "_OPTION")
    if opt ~= nil and math.floor(opt + 0.5) == TRIGGER_OPTION then return n end
  end
  return nil
end

-- nil when the switch can be used, else why not
local function switch_problem()
  local n = trigger_channel_number()
  if n == nil then
    return string.format("no RC channel has RCx_OPTION %d (Scripting{scripting}): set one on a free switch",
                         TRIGGER_OPTION)
  end
  local fltmode = param:get("FLTMODE_CH")
  if fltmode ~= nil and math.floor(fltmode + 0.5) == n then
    return string.format("RC%d is FLTMODE_CH: the switch would change the flight mode; use another channel", n)
  end
  for _, name in ipairs(STICKS) do
    local stick = param:get(name)
    if stick ~= nil and math.floor(stick + 0.5) == n then
      return string.format("RC%d is %s, a stick channel; use a switch channel", n, name)
    end
  end
  switch = rc:find_channel_for_option(TRIGGER_OPTION)
  if switch == nil then return "the trigger channel is not available" end
  return nil
end

local function switch_high()
  return switch ~= nil and switch:get_aux_switch_pos() == SWITCH_HIGH
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

-- nil when flying within the limits, else why not
local function not_flying()
  if not arming:is_armed() then return "not armed" end
  local airspeed = ahrs:airspeed_estimate()
  if airspeed == nil or airspeed < MIN_AIRSPEED then
    return string.format("airspeed %.1f m/s below %.1f", airspeed or 0, MIN_AIRSPEED)
  end
  local down = ahrs:get_relative_position_D_home()
  if down == nil or -down < MIN_HEIGHT then
    return string.format("height %.0f m below %.0f", down and -down or 0, MIN_HEIGHT)
  end
  return nil
end

local function outside_limits()
  local roll = ahrs:get_roll()
  local pitch = ahrs:get_pitch()
  if math.abs(roll) > ROLL_LIMIT then return string.format("roll %.0f deg", math.deg(roll)) end
  if pitch < PITCH_MIN or pitch > PITCH_MAX then return string.format("pitch %.0f deg", math.deg(pitch)) end
  return not_flying()
end

local function stop(reason, phase, t_ms)
  vehicle:set_mode(RECOVERY_MODE)
  local planned = (phase == 4) and END_MS or t_ms
  mark(current and current.index or 0, phase, current and current.axis_code or 0, t_ms, planned)
  say(phase == 5 and 2 or 6, reason)
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
  if not switch_high() then return stop("abort, switch left high", 5, t_ms) end
  if t_ms >= END_MS then return stop("sequence done", 4, t_ms) end
  local b = find_block(t_ms)
  if b ~= current then
    if current ~= nil then
      vehicle:set_mode(RECOVERY_MODE)
      mark(current.index, 3, current.axis_code, t_ms, current.end_ms)
    end
    if b ~= nil then
      capture_trim()
      vehicle:set_mode(b.hold and RECOVERY_MODE or EXCITE_MODE)
      mark(b.index, 1, b.axis_code, t_ms, b.start_ms)
      say(6, string.format("block %d %s %s", b.index, b.input, b.axis))
    end
    current = b
    input_marked = false
  end
  if current == nil then return end
  local why = outside_limits()
  if why ~= nil then return stop("abort, " .. why, 5, t_ms) end
  if not input_marked and t_ms >= current.excite_ms then
    mark(current.index, 2, current.axis_code, t_ms, current.excite_ms)
    input_marked = true
  end
  drive(current, t_ms)
end

local last_check_ms = nil
local problem = nil

function update()
  if state == "running" then
    run((millis() - t0):tofloat())
    return update, PERIOD_MS
  end
  local now = millis():tofloat()
  if last_check_ms == nil or now - last_check_ms >= CHECK_MS then  -- parameters read every CHECK_MS only
    problem = switch_problem()
    if problem ~= nil then switch = nil end
    last_check_ms = now
  end
  if problem ~= nil then
    say_once(problem, 3, problem)
    state = "wait_low"
    return update, PERIOD_MS
  end
  if not switch_high() then
    if state ~= "idle" then say(6, "ready: switch high to start (flying only)") end
    state = "idle"
  elseif state == "wait_low" then
    say_once("wait_low", 4, "the trigger switch is high: switch it low first")
  elseif state == "idle" then
    local why = not_flying()
    if why ~= nil then
      say(4, "not started, not flying: " .. why .. "; switch low, then high again when flying")
      state = "refused"
    else
      state = "running"
      t0 = millis()
      current = nil
      mark(0, 0, 0, 0, 0)
      say(6, "sequence started")
    end
  end
  return update, PERIOD_MS
end

say(6, string.format("loaded: switch the RCx_OPTION %d channel low, then high to start", TRIGGER_OPTION))
return update, PERIOD_MS
"""

"""Fly the generated Lua script on the ground: a real Lua 5.3 (``lupa``, the Lua of ArduPilot's scripting)
running the script against a stand-in of the ArduPilot scripting bindings it calls.

The stand-in (:data:`FAKE_API`) implements only the bindings the script may use, with the names, argument
order and return types of ArduPilot's ``libraries/AP_Scripting/docs/docs.lua``; anything else is nil and the
script fails. It is strict where ArduPilot is: ``logger:write`` checks as ``AP_Logger_Write`` in
``lua_bindings.cpp`` does (name of at most 4 characters, one label per format character, one value per label,
``B`` an integer 0..255, ``I`` a non-negative integer); ``RC_Channel_ud:get_aux_switch_pos`` returns 0 below
1200 us, 2 above 1800 us, else 1 (``RC_Channel.h``); ``millis()`` returns a ``uint32_t`` userdata with
``tofloat``; ``SRV_Channels:set_output_pwm_chan_timeout`` takes integers.

:func:`dry_run` exercises the trigger and the abort paths on a scenario: a switch left high when the script
loads, a switch flicked high on the runway (armed, not flying), a trigger channel that is also ``FLTMODE_CH``,
then the whole sequence in flight with scheduler ticks late by up to ``jitter_ms`` (every mark must come at the
first tick at or after its planned time), then a second run aborted by a roll beyond the limit. The attitude
during the sequence is the closed-loop check flight's when one is given, else the trim.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from identification.excite.design import ExcitationPlan
from identification.excite.writers import ARDUPLANE_MODES, OutputOptions, limits

#: the scripting bindings the Lua script may call (docs.lua names and argument order); state in the table M
FAKE_API = """
local M = {now = 0, params = {}, pwm = {}, roll = 0, pitch = 0, airspeed = 0, down = 0, mode = 5, modes = {},
           outputs = {}, texts = {}, logs = {}, armed = false, servo = {}, channel_of = {}}
local U = {}
U.__index = U
U.__sub = function(a, b) return setmetatable({v = a.v - b.v}, U) end
function U:tofloat() return self.v + 0.0 end
function millis() return setmetatable({v = M.now}, U) end
local C = {}
C.__index = C
function C:get_aux_switch_pos()
  local pwm = M.pwm[self.n] or 1500
  if pwm < 1200 then return 0 elseif pwm > 1800 then return 2 else return 1 end
end
rc = {}
function rc:find_channel_for_option(aux_fun)
  assert(math.type(aux_fun) == "integer", "rc:find_channel_for_option(aux_fun integer)")
  for n = 1, 16 do
    local opt = M.params["RC" .. n .. "_OPTION"]
    if opt == aux_fun then return setmetatable({n = n}, C) end
  end
  return nil
end
function rc:get_pwm(chan) return M.pwm[chan] end
param = {}
function param:get(name)
  assert(type(name) == "string", "param:get(name string)")
  return M.params[name]
end
ahrs = {}
function ahrs:get_roll() return M.roll end
function ahrs:get_pitch() return M.pitch end
function ahrs:airspeed_estimate() return M.airspeed end
function ahrs:get_relative_position_D_home() return M.down end
vehicle = {}
function vehicle:set_mode(m)
  assert(math.type(m) == "integer", "vehicle:set_mode(mode_number integer)")
  M.mode = m; table.insert(M.modes, m); return true
end
function vehicle:get_mode() return M.mode end
arming = {}
function arming:is_armed() return M.armed end
gcs = {}
function gcs:send_text(sev, text)
  assert(math.type(sev) == "integer" and sev >= 0 and sev <= 7 and type(text) == "string", "gcs:send_text")
  table.insert(M.texts, text)
end
logger = {}
function logger:write(name, labels, fmt, ...)
  local args = table.pack(...)
  assert(#name <= 4, "Name must be 4 or less chars long")
  local commas = 1
  for _ in labels:gmatch(",") do commas = commas + 1 end
  assert(#fmt == commas, "label does not match format")
  assert(args.n == #fmt, "format does not match No. of arguments")
  local row = {M.now, name}
  for i = 1, #fmt do
    local c, v = fmt:sub(i, i), args[i]
    if c == "B" then
      assert(math.type(v) == "integer" and v >= 0 and v <= 255, "B: integer 0..255")
    elseif c == "I" then
      assert(math.type(v) == "integer" and v >= 0 and v <= 4294967295, "I: integer 0..2^32-1")
    else
      error("format " .. c .. " not expected in this script")
    end
    row[#row + 1] = v
  end
  table.insert(M.logs, row)
end
SRV_Channels = {}
function SRV_Channels:find_channel(fn) return M.channel_of[fn] end
function SRV_Channels:get_output_pwm(fn) return M.servo[fn] end
function SRV_Channels:set_output_pwm_chan_timeout(chan, pwm, timeout_ms)
  assert(math.type(chan) == "integer" and math.type(pwm) == "integer" and math.type(timeout_ms) == "integer"
         and timeout_ms > 0, "set_output_pwm_chan_timeout(chan, pwm, timeout_ms integers)")
  M.outputs[chan] = pwm
end
return M
"""

#: ArduPlane's defaults the stand-in starts from: flight-mode channel 8, sticks on 1-4 (AETR)
DEFAULT_PARAMS = {"FLTMODE_CH": 8, "RCMAP_ROLL": 1, "RCMAP_PITCH": 2, "RCMAP_THROTTLE": 3, "RCMAP_YAW": 4}
#: servo outputs (function -> output channel index, 0-based as SRV_Channels:find_channel) and trims [us]
SERVO_CHANNEL = {4: 0, 19: 1, 70: 2, 21: 3}
SERVO_TRIM_US = {4: 1500, 19: 1520, 70: 1600, 21: 1490}
#: the trigger switch's channel in the scenario (a free switch channel of a stock ArduPlane setup)
SWITCH_CHANNEL = 7
LOW_US, HIGH_US = 1000, 1900


class LuaScriptError(RuntimeError):
    """The script does not compile or fails against the stand-in bindings."""


@dataclass(frozen=True)
class Mark:
    """One EXCT message: when it was written [ms, the stand-in clock] and its fields."""

    t_ms: float
    block: int
    phase: int
    axis: int
    since_trigger_ms: int
    planned_ms: int


class FakeArduPlane:
    """The script running on the stand-in bindings; set the vehicle state, then :meth:`tick` at a time."""

    def __init__(self, script: str, params: dict[str, float] | None = None) -> None:
        try:
            import lupa.lua53 as lua
        except ImportError as err:  # pragma: no cover - lupa is a test dependency
            raise LuaScriptError("lupa (Lua 5.3 for Python) is not installed: pip install lupa") from err
        self.rt = lua.LuaRuntime(unpack_returned_tuples=True)
        self.m = self.rt.execute(FAKE_API)
        for k, v in {**DEFAULT_PARAMS, **(params or {})}.items():
            self.m.params[k] = v
        for fn, ch in SERVO_CHANNEL.items():
            self.m.channel_of[fn] = ch
            self.m.servo[fn] = SERVO_TRIM_US[fn]
        res = self.rt.globals().load(script)
        chunk, err = res if isinstance(res, tuple) else (res, None)
        if chunk is None:
            raise LuaScriptError(f"the script does not compile: {err}")
        self.update, self.period_ms = self._call(chunk)

    def _call(self, fn: Any) -> Any:
        try:
            return fn()
        except Exception as err:  # lupa.LuaError and the stand-in's assertions
            raise LuaScriptError(f"the script failed at t = {self.m.now} ms: {err}") from None

    def set(self, **state: Any) -> None:
        """Vehicle state: roll, pitch [rad], airspeed [m/s], height [m], armed, switch_us (trigger channel)."""
        for k, v in state.items():
            if k == "height":
                self.m.down = -float(v)
            elif k == "switch_us":
                self.m.pwm[SWITCH_CHANNEL] = int(v)
            else:
                setattr(self.m, k, v)

    def tick(self, t_ms: float) -> None:
        self.m.now = round(t_ms)
        self._call(self.update)

    @property
    def mode(self) -> int:
        return int(self.m.mode)

    @property
    def marks(self) -> list[Mark]:
        rows = [self.m.logs[i + 1] for i in range(len(self.m.logs))]
        return [Mark(float(r[1]), int(r[3]), int(r[4]), int(r[5]), int(r[6]), int(r[7])) for r in rows]

    @property
    def texts(self) -> list[str]:
        return [str(self.m.texts[i + 1]) for i in range(len(self.m.texts))]

    @property
    def outputs(self) -> dict[int, int]:
        return {int(k): int(v) for k, v in self.m.outputs.items()}


@dataclass
class DryRun:
    """What the dry run saw; ``ok`` when every check held. ``lines`` say it in words."""

    ok: bool
    lines: list[str] = field(default_factory=list)
    max_mark_delay_ms: float = float("nan")
    marks: list[Mark] = field(default_factory=list)


def expected_marks(plan: ExcitationPlan) -> list[tuple[int, int, int]]:
    """(block, phase, planned ms) of every mark a whole sequence writes, in order."""
    out = [(0, 0, 0)]
    for b in plan.blocks:
        out += [(b.index, 1, round(1000 * b.start_s)), (b.index, 2, round(1000 * b.excitation_start_s)),
                (b.index, 3, round(1000 * b.end_s))]
    return [*out, (0, 4, round(1000 * plan.duration_s))]


def dry_run(plan: ExcitationPlan, script: str, out: OutputOptions | None = None,
            attitude: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None, jitter_ms: int = 8,
            seed: int = 0) -> DryRun:
    """Run ``script`` (the plan's Lua script) through the scenario of the module docstring. ``attitude`` =
    (plan times [s], roll [rad], pitch [rad]) of a closed-loop flight of the plan; ``jitter_ms``: the most a
    scheduler tick is late [ms]."""
    out = out or OutputOptions()
    lim = limits(plan, out)
    rng = np.random.default_rng(seed)
    flying = {"armed": True, "airspeed": plan.linear.va_m_s, "height": max(100.0, 2 * lim.min_height_m),
              "roll": 0.0, "pitch": float(plan.linear.x_trim[4])}
    recovery = ARDUPLANE_MODES[out.recovery_mode]
    lines: list[str] = []
    ok = True

    def check(cond: bool, text: str) -> None:
        nonlocal ok
        ok &= cond
        lines.append(f"{'ok' if cond else 'FAILED'}: {text}")

    # a trigger channel that is also the flight-mode channel is refused
    clash = FakeArduPlane(script, {"RC8_OPTION": out.trigger_option})
    clash.set(**flying, switch_us=LOW_US)
    clash.tick(0)
    clash.m.pwm[8] = HIGH_US
    clash.tick(1000)
    check(not clash.marks and any("FLTMODE_CH" in t for t in clash.texts),
          "trigger on the flight-mode channel (RC8 = FLTMODE_CH) refused")
    ap = FakeArduPlane(script, {f"RC{SWITCH_CHANNEL}_OPTION": out.trigger_option})
    period = int(ap.period_ms)
    # switch high when the script loads (e.g. left high before arming): waits for low first
    ap.set(**flying, switch_us=HIGH_US)
    ap.tick(0)
    ap.tick(period)
    check(not ap.marks, "switch high at load: no start until it has been low")
    # on the runway: armed, switch flicked high -> refused, says why
    ap.set(switch_us=LOW_US, armed=True, airspeed=0.4, height=0.0)
    ap.tick(2 * period)
    ap.set(switch_us=HIGH_US)
    ap.tick(3 * period)
    check(not ap.marks and any("not flying" in t for t in ap.texts), "switch high on the runway (armed, 0.4 m/s, "
          "0 m): not started, the reason sent to the GCS")
    ap.set(airspeed=flying["airspeed"], height=flying["height"])  # climbed out, switch still high: no start
    ap.tick(4 * period)
    check(not ap.marks, "still high after the refusal: no start until low, then high again")
    ap.set(switch_us=LOW_US)
    ap.tick(5 * period)
    t0 = 6 * period
    ap.set(switch_us=HIGH_US)
    ap.tick(t0)
    t = float(t0)
    end = t0 + 1000 * plan.duration_s + 3 * period
    while t < end:
        t += period + int(rng.integers(0, jitter_ms + 1))
        if attitude is not None:
            ts, roll, pitch = attitude
            k = min(int(np.searchsorted(ts, (t - t0) / 1000.0)), len(ts) - 1)
            ap.set(roll=float(roll[k]), pitch=float(pitch[k]))
        ap.tick(t)
    marks = ap.marks
    got = [(m.block, m.phase, m.planned_ms) for m in marks]
    want = expected_marks(plan)
    check(got == want, f"{len(want)} marks in order (start, per block hand-over, input, recovery; done)"
          + ("" if got == want else f": got {got[:6]}..., want {want[:6]}..."))
    delays = [m.since_trigger_ms - m.planned_ms for m in marks]
    gap = period + jitter_ms
    max_delay = float(max(delays)) if delays else float("nan")
    check(bool(delays) and min(delays) >= 0 and max_delay <= gap,
          f"each mark at the first tick at or after its planned time (delay 0..{max_delay:.0f} ms, ticks "
          f"{period}..{gap} ms apart)")
    check(all(abs((m.t_ms - t0) - m.since_trigger_ms) <= 1 for m in marks), "marks carry the actual time")
    check(ap.mode == recovery, "recovery mode after the sequence")
    # second run: abort on roll inside block 1's input
    ap.set(switch_us=LOW_US)
    t += period
    ap.tick(t)
    ap.set(switch_us=HIGH_US, roll=0.0)
    t += period
    t1 = t
    ap.tick(t1)
    b = plan.blocks[0]
    n_before = len(ap.marks)
    while t < t1 + 1000 * (b.excitation_start_s + 0.1):
        t += period
        ap.tick(t)
    ap.set(roll=np.radians(lim.roll_deg + 1.0))
    t += period
    ap.tick(t)
    frozen = dict(ap.outputs)
    for _ in range(5):
        t += period
        ap.tick(t)
    new = ap.marks[n_before:]
    check(bool(new) and new[-1].phase == 5 and ap.mode == recovery and ap.outputs == frozen,
          f"roll beyond {lim.roll_deg:g} deg in block {b.index}: abort mark, recovery mode, overrides stop")
    return DryRun(ok, lines, max_delay, marks)


__all__ = ["FAKE_API", "DryRun", "FakeArduPlane", "LuaScriptError", "Mark", "dry_run", "expected_marks"]

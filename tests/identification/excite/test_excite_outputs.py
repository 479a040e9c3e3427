"""What ``uavfmu excite`` writes: the timeline (read back by identification.logs.timeline), the RC-override steps,
and the ArduPilot Lua script (compiled by a real Lua 5.3, then run against a stand-in of the ArduPilot scripting
API whose bindings are the ones of ArduPilot's libraries/AP_Scripting/docs/docs.lua)."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fmu_models.signals.pwm_mapping import default_mapping
from identification.excite.design import ExciteOptions
from identification.excite.workflow import excite, write_files
from identification.excite.writers import servo_offset_us
from identification.logs.timeline import load_timeline

OPT = ExciteOptions(settle_s=1.0, tail_s=2.0, recovery_s=3.0)


@pytest.fixture(scope="module")
def result():  # type: ignore[no-untyped-def]
    return excite(None, OPT)


def test_files_are_written_and_the_timeline_reads_back(result, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    paths = write_files(result, tmp_path / "exc")
    assert sorted(p.name for p in paths) == sorted(["exc.lua", "exc.timeline.json", "exc.rc_override.json",
                                                    "exc.rc_override.csv", "exc.plan.json"])
    tl = load_timeline(tmp_path / "exc.timeline.json")
    assert "start of the planned sequence" in tl.time_base
    assert len(tl.blocks) == len(result.plan.blocks)
    for got, b in zip(tl.blocks, result.plan.blocks, strict=True):
        assert (got.axis, got.start_s, got.excitation_start_s, got.end_s) == (
            b.axis, pytest.approx(b.start_s), pytest.approx(b.excitation_start_s), pytest.approx(b.end_s))
    multi = tl.blocks[-1]
    assert multi.axis == "multi" and set(multi.excited_axes) == {"aileron", "elevator", "rudder"}
    assert {b.index for b in tl.blocks_for("rudder")} == {b.index for b in result.plan.blocks if "rudder" in b.signals}


def test_servo_offsets_follow_the_identify_mapping() -> None:
    m = default_mapping("fixed_wing")
    # +0.35 rad = full throw: aileron above trim (roll right), elevator below (uavbook nose down), rudder below
    assert servo_offset_us(m, "aileron", 0.35) == pytest.approx(400.0)
    assert servo_offset_us(m, "elevator", 0.35) == pytest.approx(-400.0)
    assert servo_offset_us(m, "rudder", 0.1) == pytest.approx(-400.0 * 0.1 / 0.35)
    # and the mapping reads them back as the planned deflection
    for name, target in (("aileron", "aileron_rad"), ("elevator", "elevator_rad"), ("rudder", "rudder_rad")):
        ch = next(c for c in m.channels if c.target == target)
        assert ch.to_input(ch.trim_us + servo_offset_us(m, name, 0.123)) == pytest.approx(0.123)


def test_rc_override_rows_carry_the_plan(result) -> None:  # type: ignore[no-untyped-def]
    plan = result.plan
    rc = json.loads(result.files[".rc_override.json"])
    rows = rc["rows"]
    dt = 1.0 / rc["rate_hz"]
    assert np.allclose(np.diff([r["t_s"] for r in rows]), dt, atol=1e-3)
    assert rows[-1]["t_s"] < plan.duration_s
    mapping = default_mapping("fixed_wing")
    for r in rows:
        blk = plan.active_block(r["t_s"])
        assert r["phase"] == ("excite" if blk else "recover") and r["block"] == (blk.index if blk else 0)
        du = plan.deflection(np.array([r["t_s"]]))[0]
        for surface, k in (("aileron", 0), ("elevator", 1), ("rudder", 2)):
            want = servo_offset_us(mapping, surface, du[k]) * 500.0 / 400.0  # full stick = full servo throw
            assert r["offset_us"][str(rc["channels"][surface])] == pytest.approx(want, abs=0.06)
        assert r["offset_us"]["3"] == 0.0  # throttle held where it was
    # inside the first 3-2-1-1 the aileron stick really moves by the planned amount
    b = plan.blocks[0]
    inside = [r for r in rows if b.excitation_start_s <= r["t_s"] < b.excitation_start_s + 0.3]
    amp_us = servo_offset_us(mapping, "aileron", b.signals["aileron"].peak_rad()) * 500 / 400
    assert inside and all(r["offset_us"]["1"] == pytest.approx(amp_us, abs=0.06) for r in inside)
    assert rc["modes"]["ardupilot"] == {"excite": "MANUAL", "recover": "FBWA"}
    assert rc["modes"]["px4"]["recover"] == "STABILIZED"
    lim = rc["limits"]
    assert lim["roll_deg"] == OPT.roll_limit_deg and lim["min_airspeed_m_s"] == pytest.approx(0.7 * 25.0, rel=1e-3)
    table = list(csv.reader(io.StringIO(result.files[".rc_override.csv"])))
    assert table[0] == ["t_s", "phase", "block", "ch1_offset_us", "ch2_offset_us", "ch3_offset_us", "ch4_offset_us"]
    assert len(table) == len(rows) + 1


# ------------------------------------------------------------------ Lua
lupa = pytest.importorskip("lupa.lua53", reason="lupa (Lua 5.3 for Python) not installed: pip install lupa")

#: the ArduPilot scripting bindings the script may use (names and argument order as in docs.lua); anything else
#: is nil here and the script fails
MOCK = """
local M = {now = 0, pwm = {}, roll = 0, pitch = 0.05, airspeed = 25, down = -100, mode = 5, modes = {},
           outputs = {}, texts = {}, logs = {}, armed = true,
           servo = {[4] = 1500, [19] = 1520, [21] = 1490, [70] = 1600},
           channel_of = {[4] = 0, [19] = 1, [21] = 3, [70] = 2}}
local U = {}
U.__index = U
U.__sub = function(a, b) return setmetatable({v = a.v - b.v}, U) end
function U:tofloat() return self.v end
function millis() return setmetatable({v = M.now}, U) end
rc = {}
function rc:get_pwm(chan) return M.pwm[chan] end
ahrs = {}
function ahrs:get_roll() return M.roll end
function ahrs:get_pitch() return M.pitch end
function ahrs:airspeed_estimate() return M.airspeed end
function ahrs:get_relative_position_D_home() return M.down end
vehicle = {}
function vehicle:set_mode(m) M.mode = m; table.insert(M.modes, m); return true end
function vehicle:get_mode() return M.mode end
arming = {}
function arming:is_armed() return M.armed end
gcs = {}
function gcs:send_text(sev, text) table.insert(M.texts, text) end
logger = {}
function logger:write(name, labels, fmt, a, b) table.insert(M.logs, {a, b}) end
SRV_Channels = {}
function SRV_Channels:find_channel(fn) return M.channel_of[fn] end
function SRV_Channels:get_output_pwm(fn) return M.servo[fn] end
function SRV_Channels:set_output_pwm_chan_timeout(chan, pwm, timeout_ms)
  assert(math.type(pwm) == "integer" and timeout_ms > 0)
  M.outputs[chan] = pwm
end
return M
"""


def _load(rt, text: str):  # type: ignore[no-untyped-def]
    """Lua's ``load``: (chunk, None) or (None, message)."""
    res = rt.globals().load(text)
    return res if isinstance(res, tuple) else (res, None)


def _runtime(script: str):  # type: ignore[no-untyped-def]
    rt = lupa.LuaRuntime(unpack_returned_tuples=True)
    mock = rt.execute(MOCK)
    chunk, err = _load(rt, script)
    assert chunk is not None, err
    update, period = chunk()
    return rt, mock, update, period


def test_lua_script_compiles_and_syntax_errors_are_caught(result) -> None:  # type: ignore[no-untyped-def]
    rt = lupa.LuaRuntime(unpack_returned_tuples=True)
    chunk, err = _load(rt, result.files[".lua"])
    assert chunk is not None, err
    broken, err = _load(rt, result.files[".lua"].replace("  return u\nend\n", "  return u\n", 1))
    assert broken is None and "expected" in err


def _step(mock, update, t_ms: float) -> None:  # type: ignore[no-untyped-def]
    mock.now = t_ms
    update()


def test_lua_runs_the_plan_and_aborts_on_the_roll_limit(result) -> None:  # type: ignore[no-untyped-def]
    plan = result.plan
    _rt, mock, update, period = _runtime(result.files[".lua"])
    assert period == round(1000 / plan.options.rate_hz)
    _step(mock, update, 1000)  # switch low: nothing happens
    assert len(mock.modes) == 0 and len(mock.outputs) == 0
    mock.pwm[8] = 1900
    _step(mock, update, 2000)  # trigger: t0 = 2000 ms
    b = plan.blocks[0]
    _step(mock, update, 2000 + 1)  # block 1 hand-over: trims captured, MANUAL
    assert mock.mode == 0
    t_in = b.excitation_start_s + 0.05  # inside the first "3" pulse
    _step(mock, update, 2000 + 1000 * t_in)
    mapping = default_mapping("fixed_wing")
    want = 1500 + servo_offset_us(mapping, "aileron", b.signals["aileron"].peak_rad())
    assert mock.outputs[0] == round(want)  # aileron = captured trim + planned offset
    assert mock.outputs[1] == 1520 and mock.outputs[3] == 1490 and mock.outputs[2] == 1600  # others held
    # the multisine block: the Lua sum of cosines equals the planned signal
    m = plan.blocks[-1]
    for t in (0.37, 2.11, 5.5):
        _step(mock, update, 2000 + 1000 * (m.excitation_start_s + t))
        du = m.deflection(np.array([m.excitation_start_s + t]))[0]
        assert mock.outputs[1] == round(1520 + servo_offset_us(mapping, "elevator", du[1]))
        assert mock.outputs[3] == round(1490 + servo_offset_us(mapping, "rudder", du[2]))
    # between blocks: recovery mode
    _step(mock, update, 2000 + 1000 * (plan.blocks[1].start_s - 0.5))
    assert mock.mode == 5
    # roll beyond the limit inside a block aborts to FBWA and stops overriding
    _step(mock, update, 2000 + 1000 * (plan.blocks[1].excitation_start_s + 0.1))
    assert mock.mode == 0
    mock.roll = math.radians(OPT.roll_limit_deg + 1)
    _step(mock, update, 2000 + 1000 * (plan.blocks[1].excitation_start_s + 0.12))
    assert mock.mode == 5 and any("abort, roll" in str(t) for t in mock.texts.values())
    n_out = dict(mock.outputs)
    _step(mock, update, 2000 + 1000 * (plan.blocks[2].excitation_start_s + 0.1))
    assert dict(mock.outputs) == n_out and mock.mode == 5  # aborted: no more blocks until re-armed


def test_lua_aborts_when_the_switch_goes_low_and_on_low_airspeed(result) -> None:  # type: ignore[no-untyped-def]
    plan = result.plan
    _rt, mock, update, _ = _runtime(result.files[".lua"])
    mock.pwm[8] = 1900
    _step(mock, update, 0)
    _step(mock, update, 1000 * (plan.blocks[0].excitation_start_s + 0.05))
    assert mock.mode == 0
    mock.pwm[8] = 1000
    _step(mock, update, 1000 * (plan.blocks[0].excitation_start_s + 0.1))
    assert mock.mode == 5 and any("switch low" in str(t) for t in mock.texts.values())
    _step(mock, update, 90000)  # still low: ready again
    mock.pwm[8] = 1900  # re-arm (low, then high): starts over
    _step(mock, update, 100000)
    _step(mock, update, 100001)
    assert mock.mode == 0
    mock.airspeed = 10.0
    _step(mock, update, 100000 + 1000 * (plan.blocks[0].excitation_start_s + 0.05))
    assert mock.mode == 5 and any("airspeed" in str(t) for t in mock.texts.values())


# ------------------------------------------------------------------ ground-station example (docs/examples)
def _example():  # type: ignore[no-untyped-def]
    import importlib.util

    path = Path(__file__).resolve().parents[3] / "docs" / "examples" / "excite_rc_override.py"
    spec = importlib.util.spec_from_file_location("excite_rc_override", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Msg:
    def __init__(self, kind: str, **fields: float) -> None:
        self.kind = kind
        self.__dict__.update(fields)

    def get_type(self) -> str:
        return self.kind


class _FakeMaster:
    """Records what the example sends; answers RC_CHANNELS once, then ATTITUDE from ``roll_of(t)``."""

    def __init__(self, clock, roll_of) -> None:  # type: ignore[no-untyped-def]
        self.target_system, self.target_component = 1, 1
        self.clock, self.roll_of = clock, roll_of
        self.sent: list[tuple[float, tuple[int, ...]]] = []
        self.modes: list[tuple[float, str]] = []
        self.mav = self
        self.last_att = -1.0

    def rc_channels_override_send(self, sysid, compid, *ch) -> None:  # type: ignore[no-untyped-def]
        self.sent.append((self.clock(), ch))

    def set_mode(self, mode: str) -> None:
        self.modes.append((self.clock(), mode))

    def recv_match(self, type, blocking=False, timeout=None):  # type: ignore[no-untyped-def]
        if type == "RC_CHANNELS":
            return _Msg("RC_CHANNELS", chan1_raw=1500, chan2_raw=1600, chan3_raw=1650, chan4_raw=1480,
                        chan5_raw=1000, chan6_raw=1000, chan7_raw=1000, chan8_raw=1000)
        t = self.clock()
        if t - self.last_att >= 0.1:
            self.last_att = t
            return _Msg("ATTITUDE", roll=self.roll_of(t), pitch=0.05)
        return None


def _fake_time():  # type: ignore[no-untyped-def]
    now = [0.0]
    return (lambda: now[0]), (lambda dt: now.__setitem__(0, now[0] + dt))


def test_ground_station_example_sends_the_rows_and_aborts_on_roll(result) -> None:  # type: ignore[no-untyped-def]
    ex = _example()
    plan = json.loads(result.files[".rc_override.json"])
    short = dict(plan, rows=plan["rows"][:200])
    clock, sleep = _fake_time()
    master = _FakeMaster(clock, lambda t: 0.0)
    assert ex.run(master, short, "ardupilot", clock, sleep) == "done"
    assert len(master.sent) == 200 + 1 and master.sent[-1][1] == (0,) * 8  # released at the end
    assert master.modes[0][1] == "MANUAL" and master.modes[-1][1] == "FBWA"
    for (t, ch), row in zip(master.sent, short["rows"], strict=False):
        assert t == pytest.approx(row["t_s"], abs=0.01)
        assert ch[0] == 1500 + round(row["offset_us"]["1"]) and ch[1] == 1600 + round(row["offset_us"]["2"])
        assert ch[2] == 1650 and ch[3] == 1480 + round(row["offset_us"]["4"]) and ch[4:] == (0, 0, 0, 0)
    # roll beyond the limit during an excite phase: recovery mode and release
    clock, sleep = _fake_time()
    master = _FakeMaster(clock, lambda t: math.radians(60.0) if t > 2.5 else 0.0)
    out = ex.run(master, plan, "px4", clock, sleep)
    assert out.startswith("abort: roll 60")
    assert master.modes[-1][1] == "STABILIZED" and master.sent[-1][1] == (0,) * 8
    assert master.sent[-1][0] < 3.0

"""What ``uavfmu excite`` writes: the timeline (read back by identification.logs.timeline), the RC-override steps,
and the ArduPilot Lua script (compiled by a real Lua 5.3, then run against the stand-in of the ArduPilot scripting
API in identification.excite.dry_run, whose bindings are the ones of ArduPilot's
libraries/AP_Scripting/docs/docs.lua): trigger refusals, marks at the first tick after their time, aborts."""

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
    multi = next(b for b in tl.blocks if b.axis == "multi")
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
        want_phase = "recover" if blk is None else "hold" if blk.axis == "throttle" else "excite"
        assert r["phase"] == want_phase and r["block"] == (blk.index if blk else 0)
        du = plan.deflection(np.array([r["t_s"]]))[0]
        for surface, k in (("aileron", 0), ("elevator", 1), ("rudder", 2)):
            want = servo_offset_us(mapping, surface, du[k]) * 500.0 / 400.0  # full stick = full servo throw
            assert r["offset_us"][str(rc["channels"][surface])] == pytest.approx(want, abs=0.06)
        thr = servo_offset_us(mapping, "throttle", du[3]) * 1000.0 / 1000.0  # one-sided: full stick = full range
        assert r["offset_us"]["3"] == pytest.approx(thr, abs=0.06)  # zero outside the throttle blocks
    # inside the first 3-2-1-1 the aileron stick really moves by the planned amount
    b = plan.blocks[0]
    inside = [r for r in rows if b.excitation_start_s <= r["t_s"] < b.excitation_start_s + 0.3]
    amp_us = servo_offset_us(mapping, "aileron", b.signals["aileron"].peak_rad()) * 500 / 400
    assert inside and all(r["offset_us"]["1"] == pytest.approx(amp_us, abs=0.06) for r in inside)
    assert rc["modes"]["ardupilot"] == {"excite": "MANUAL", "hold": "FBWA", "recover": "FBWA"}
    thr_rows = [r for r in rows if r["phase"] == "hold"]
    assert thr_rows and max(abs(r["offset_us"]["3"]) for r in thr_rows) > 50.0  # the throttle really moves
    assert rc["modes"]["px4"]["recover"] == "STABILIZED"
    lim = rc["limits"]
    assert lim["roll_deg"] == OPT.roll_limit_deg and lim["min_airspeed_m_s"] == pytest.approx(0.7 * 25.0, rel=1e-3)
    table = list(csv.reader(io.StringIO(result.files[".rc_override.csv"])))
    assert table[0] == ["t_s", "phase", "block", "ch1_offset_us", "ch2_offset_us", "ch3_offset_us", "ch4_offset_us"]
    assert len(table) == len(rows) + 1


# ------------------------------------------------------------------ Lua
lupa = pytest.importorskip("lupa.lua53", reason="lupa (Lua 5.3 for Python) not installed: pip install lupa")

from identification.excite.dry_run import (  # noqa: E402 - only with lupa
    HIGH_US,
    LOW_US,
    SWITCH_CHANNEL,
    FakeArduPlane,
    LuaScriptError,
    dry_run,
    expected_marks,
)


def test_lua_script_compiles_and_syntax_errors_are_caught(result) -> None:  # type: ignore[no-untyped-def]
    FakeArduPlane(result.files[".lua"])
    with pytest.raises(LuaScriptError, match="does not compile"):
        FakeArduPlane(result.files[".lua"].replace("  return u\nend\n", "  return u\n", 1))


def test_a_binding_ardupilot_does_not_have_fails_the_script(result) -> None:  # type: ignore[no-untyped-def]
    """The stand-in knows only docs.lua's bindings: a misspelt one is an error, not a silent nil."""
    bad = result.files[".lua"].replace("rc:find_channel_for_option(", "rc:find_channel_for_aux(", 1)
    ap = FakeArduPlane(bad, {f"RC{SWITCH_CHANNEL}_OPTION": 300})
    with pytest.raises(LuaScriptError, match="find_channel_for_aux"):
        ap.tick(0)


def test_dry_run_trigger_marks_and_abort(result) -> None:  # type: ignore[no-untyped-def]
    run = dry_run(result.plan, result.files[".lua"], jitter_ms=8, seed=3)
    assert run.ok, run.lines
    assert [(m.block, m.phase, m.planned_ms) for m in run.marks] == expected_marks(result.plan)
    delays = [m.since_trigger_ms - m.planned_ms for m in run.marks]
    assert min(delays) >= 0 and max(delays) <= 20 + 8
    assert {m.axis for m in run.marks if m.phase == 1} == {0, 1, 2, 3, 4}  # aileron .. throttle, multi


def test_dry_run_catches_a_mark_lost_to_a_late_tick(result) -> None:  # type: ignore[no-untyped-def]
    """Negative control: the old rule (input mark only if a tick falls within one period after the planned time)
    loses marks when ticks run late; the dry run must say so."""
    old = result.files[".lua"].replace(
        "if not input_marked and t_ms >= current.excite_ms then",
        "if t_ms >= current.excite_ms and t_ms - PERIOD_MS < current.excite_ms and not input_marked then")
    assert old != result.files[".lua"]
    run = dry_run(result.plan, old, jitter_ms=15, seed=1)
    assert not run.ok and any(line.startswith("FAILED") and "marks in order" in line for line in run.lines)


@pytest.mark.parametrize("params, word", [({"RC8_OPTION": 300}, "FLTMODE_CH"), ({"RC1_OPTION": 300}, "RCMAP_ROLL"),
                                          ({}, "no RC channel has RCx_OPTION 300")])
def test_a_trigger_that_could_surprise_is_refused(result, params, word) -> None:  # type: ignore[no-untyped-def]
    ap = FakeArduPlane(result.files[".lua"], params)
    ap.set(armed=True, airspeed=25.0, height=100.0, switch_us=LOW_US)
    ap.m.pwm[8] = ap.m.pwm[1] = LOW_US
    ap.tick(0)
    ap.m.pwm[8] = ap.m.pwm[1] = HIGH_US
    ap.set(switch_us=HIGH_US)
    ap.tick(1000)
    assert not ap.marks and ap.mode == 5 and any(word in t for t in ap.texts), ap.texts


def _flying(script: str) -> FakeArduPlane:
    ap = FakeArduPlane(script, {f"RC{SWITCH_CHANNEL}_OPTION": 300})
    ap.set(armed=True, airspeed=25.0, height=100.0, pitch=0.05, switch_us=LOW_US)
    ap.tick(0)
    return ap


def test_lua_outputs_are_the_captured_trim_plus_the_planned_offsets(result) -> None:  # type: ignore[no-untyped-def]
    plan = result.plan
    ap = _flying(result.files[".lua"])
    assert ap.period_ms == round(1000 / plan.options.rate_hz)
    ap.set(switch_us=HIGH_US)
    ap.tick(2000)  # trigger: t0 = 2000 ms
    b = plan.blocks[0]
    ap.tick(2000 + 1)  # block 1 hand-over: trims captured, MANUAL
    assert ap.mode == 0
    ap.tick(2000 + 1000 * (b.excitation_start_s + 0.05))  # inside the first "3" pulse
    mapping = default_mapping("fixed_wing")
    want = 1500 + servo_offset_us(mapping, "aileron", b.signals["aileron"].peak_rad())
    out = ap.outputs
    assert out[0] == round(want)  # aileron = captured trim + planned offset
    assert out[1] == 1520 and out[3] == 1490 and out[2] == 1600  # others held
    m = next(b for b in plan.blocks if b.axis == "multi")  # the Lua sum of cosines equals the planned multisine
    for t in (0.37, 2.11, 5.5):
        ap.tick(2000 + 1000 * (m.excitation_start_s + t))
        du = m.deflection(np.array([m.excitation_start_s + t]))[0]
        assert ap.outputs[1] == round(1520 + servo_offset_us(mapping, "elevator", du[1]))
        assert ap.outputs[3] == round(1490 + servo_offset_us(mapping, "rudder", du[2]))
    th = next(b for b in plan.blocks if b.axis == "throttle")  # throttle doublet at attitude hold (FBWA)
    ap.tick(2000 + 1000 * th.start_s + 1)
    ap.tick(2000 + 1000 * (th.excitation_start_s + 0.5))
    du = th.deflection(np.array([th.excitation_start_s + 0.5]))[0]
    assert ap.mode == 5 and du[3] != 0 and ap.outputs[2] == round(1600 + servo_offset_us(mapping, "throttle", du[3]))


def test_lua_aborts_when_the_switch_leaves_high_and_on_low_airspeed(result) -> None:  # type: ignore[no-untyped-def]
    plan = result.plan
    ap = _flying(result.files[".lua"])
    ap.set(switch_us=HIGH_US)
    ap.tick(20)
    ap.tick(20 + 1000 * (plan.blocks[0].excitation_start_s + 0.05))
    assert ap.mode == 0
    ap.set(switch_us=1500)  # middle position: not high any more
    ap.tick(20 + 1000 * (plan.blocks[0].excitation_start_s + 0.1))
    assert ap.mode == 5 and any("switch left high" in t for t in ap.texts) and ap.marks[-1].phase == 5
    ap.set(switch_us=LOW_US)
    ap.tick(90000)
    ap.set(switch_us=HIGH_US)  # re-armed (low, then high): starts over
    ap.tick(100000)
    ap.tick(100001)
    assert ap.mode == 0
    ap.set(airspeed=10.0)
    ap.tick(100000 + 1000 * (plan.blocks[0].excitation_start_s + 0.05))
    assert ap.mode == 5 and any("airspeed" in t for t in ap.texts) and ap.marks[-1].phase == 5


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


def test_check_dry_runs_the_script_and_a_failed_dry_run_fails_the_check(monkeypatch) -> None:
    import identification.excite.workflow as wf

    res = excite(None, OPT, check=True)
    assert res.dry_run is not None and res.dry_run.ok and res.check_passed is True
    assert "dry run of the Lua script" in res.summary() and "FAILED" not in res.summary()
    broken = wf.lua_script  # a script whose input mark never comes: the check must fail
    monkeypatch.setattr(wf, "lua_script", lambda *a, **k: broken(*a, **k).replace(
        "t_ms >= current.excite_ms then", "t_ms >= current.excite_ms + END_MS then"))
    bad = wf.excite(None, OPT, check=True)
    assert bad.dry_run is not None and not bad.dry_run.ok and bad.check_passed is False

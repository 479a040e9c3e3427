"""Flown blocks of PX4 flights from their mode spans (``vehicle_status.nav_state``) and sticks
(``manual_control_setpoint``), like ArduPlane's MODE spans: a synthetic MANUAL flight with PX4 1.14 stick names,
and the shared PX4 SITL quadrotor flight (PX4 1.13 names), whose ALTCTL spans hold the blocks of its
``.blocks.json``."""

from __future__ import annotations

import json

import numpy as np

from identification.logs.flightlog import FlightLog, Signal
from identification.logs.flown_blocks import flown_timeline, px4_mode_blocks
from identification.logs.readers import read_log
from tests.conftest import shared_data


def _sig(name: str, t: np.ndarray, v: np.ndarray) -> Signal:
    return Signal(name, t, v, "")


def test_manual_spans_and_the_stick_that_moves() -> None:
    t = np.arange(0.0, 60.0, 0.02)
    nav_t = np.arange(0.0, 60.0, 0.5)  # vehicle_status is logged again and again, not only at changes
    nav = np.where((nav_t >= 10) & (nav_t < 20), 0, np.where((nav_t >= 30) & (nav_t < 31), 0, 15)).astype(float)
    roll = np.where((t >= 12) & (t < 12.4), 0.3, 0.0) - np.where((t >= 12.4) & (t < 12.8), 0.3, 0.0)
    pitch = np.where((t >= 30.2) & (t < 30.6), 0.3, 0.0)
    log = FlightLog("x.ulg", "ulog", {
        "vehicle_status.nav_state": _sig("vehicle_status.nav_state", nav_t, nav),
        "manual_control_setpoint.roll": _sig("manual_control_setpoint.roll", t, roll),
        "manual_control_setpoint.pitch": _sig("manual_control_setpoint.pitch", t, pitch),
        "manual_control_setpoint.throttle": _sig("manual_control_setpoint.throttle", t, 0.6 + 0 * t)}, {})
    blocks = px4_mode_blocks(log)
    assert len(blocks) == 1  # the second MANUAL span lasts 1 s: a mode flick, no block
    b = blocks[0]
    assert (b.axis, b.start_s, b.end_s) == ("aileron", 10.0, 20.0)
    assert abs(b.excitation_start_s - 12.0) < 0.03 and "manual_control_setpoint.roll" in b.source
    assert flown_timeline(blocks, "PX4 MANUAL nav_state spans").blocks[0].axis == "aileron"
    assert px4_mode_blocks(FlightLog("y.ulg", "ulog", {}, {})) == []


def test_altctl_spans_of_the_shared_px4_flight_hold_its_blocks() -> None:
    path = shared_data("quadrotor_px4_sitl", "px4_sitl_fmu_sysid.ulg")
    log = read_log(path)
    assert px4_mode_blocks(log) == []  # no MANUAL in this flight
    blocks = px4_mode_blocks(log, nav_state=1)
    truth = [b for b in json.loads(path.with_suffix(".blocks.json").read_text()) if b["block"] != "posctl_settle"]
    starts = np.array([b["start_s"] for b in truth]) - log.boot_s
    for b in truth:  # every excitation block lies inside one ALTCTL block
        s0, s1 = b["start_s"] - log.boot_s, b["end_s"] - log.boot_s
        assert any(f.start_s <= s0 and s1 <= f.end_s for f in blocks), b
    single = [f for f in blocks if f.axis != "multi"]
    assert len(single) >= 4
    for f in single:  # the input starts where the block's stick starts moving
        assert np.min(np.abs(starts - f.excitation_start_s)) < 0.5, f.line()

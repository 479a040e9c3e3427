"""Robustness, HIL family: hypothesis-generated malformed packets for every interface that
receives packets. A malformed packet is counted and dropped with no side effect: no step, no restart, no FMU
input change, no other counter moved (in particular no dropped-frame leap); a good packet afterwards is served
as usual. NMEA is output only (GPS sentences out), so it has no packets to fuzz. At least 1000 examples per
interface; the counts are printed."""

from __future__ import annotations

import math
import os
import struct
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from hil_adapter.ardupilot_json import FRAME_RATE_HZ, MAX_FRAME_GAP, ArduPilotJsonServer
from hil_adapter.core import Plant
from hil_adapter.mavlink_bridge import MavlinkBridge
from hil_adapter.packets import SERVO16, SERVO16_MAGIC, SERVO32, SERVO32_MAGIC
from hil_adapter.px4 import Px4Server
from hil_adapter.sensors import SensorConfig, SensorSuite

#: ``UAVFMU_FUZZ_SCALE`` (0..1, default 1) shrinks the example count for `make mutation` only
EXAMPLES = max(10, round(1000 * min(1.0, max(0.01, float(os.environ.get("UAVFMU_FUZZ_SCALE", "1"))))))
COUNTS: Counter[str] = Counter()
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def plant(quadrotor_fmu: Path):
    p = Plant(quadrotor_fmu)
    yield p
    p.close()
    print("\nHIL packet robustness examples: " + ", ".join(f"{k} {v}" for k, v in sorted(COUNTS.items())))


def _snapshot(plant: Plant, stats: Any, extra: tuple = ()) -> tuple:
    s = stats
    return (plant.t_s, plant.fmu_t_s, dict(plant.inputs), plant.fmu_errors, s.steps, s.dropped, s.resends,
            s.out_of_order, s.restarts, *extra)


# ---------------------------------------------------------------------------------------- ArduPilot JSON
BAD_PWM = st.one_of(st.just(0), st.integers(1, 499), st.integers(2501, 65535))


@st.composite
def bad_servo_packets(draw: Any) -> bytes:
    """Malformed in exactly one way: bytes, length, magic, frame rate, a mapped PWM, or a frame_count leap."""
    kind = draw(st.sampled_from(["bytes", "length", "magic", "rate", "pwm", "leap"]))
    wide = draw(st.booleans())
    layout, magic, n = (SERVO32, SERVO32_MAGIC, 32) if wide else (SERVO16, SERVO16_MAGIC, 16)
    pwm = draw(st.lists(st.integers(1000, 2000), min_size=n, max_size=n))
    rate = draw(st.integers(FRAME_RATE_HZ[0], FRAME_RATE_HZ[1]))
    count = draw(st.integers(1, MAX_FRAME_GAP))  # relative to the last count (set to 1 by the fixture)
    if kind == "bytes":
        data = draw(st.binary(max_size=80))
        if len(data) in (SERVO16.size, SERVO32.size) and data[:2] in (b"\x1a\x48", b"\x81\x73"):
            data = data[:-1]
        return data
    if kind == "length":
        good = layout.pack(magic, rate, count, *pwm)
        cut = draw(st.integers(0, len(good) + 8).filter(lambda k: k != len(good)))
        return (good + bytes(8))[:cut]
    if kind == "magic":
        magic = draw(st.integers(0, 65535).filter(lambda m: m not in (SERVO16_MAGIC, SERVO32_MAGIC)))
    elif kind == "rate":
        rate = draw(st.one_of(st.just(0), st.integers(1, FRAME_RATE_HZ[0] - 1),
                              st.integers(FRAME_RATE_HZ[1] + 1, 65535)))
    elif kind == "pwm":
        pwm[draw(st.integers(0, 3))] = draw(BAD_PWM)  # channels 1-4 drive the quadrotor's motors
    else:
        count = draw(st.integers(1 + MAX_FRAME_GAP + 1, 2**32 - 1))
    return layout.pack(magic, rate, count, *pwm)


def test_malformed_servo_packets_have_no_side_effect(plant: Plant) -> None:
    _counted(_servo_packet_fuzz, "ardupilot-json", plant)


@FUZZ
@given(data=bad_servo_packets())
def _servo_packet_fuzz(plant: Plant, data: bytes) -> None:
    srv = ArduPilotJsonServer(plant, transport=None)  # type: ignore[arg-type]  (handle() only)
    assert srv.handle(SERVO16.pack(SERVO16_MAGIC, 400, 1, *([1000] * 16))) is not None
    before = _snapshot(plant, srv.stats, (srv.last_count, srv.last_reply))
    assert srv.handle(data) is None
    assert srv.stats.malformed == 1 and _snapshot(plant, srv.stats, (srv.last_count, srv.last_reply)) == before
    assert srv.handle(SERVO16.pack(SERVO16_MAGIC, 400, 2, *([1000] * 16))) is not None  # still served
    assert srv.stats.steps == 2 and srv.stats.dropped == 0 and srv.stats.restarts == 0
    COUNTS["ardupilot-json"] += 1


# ---------------------------------------------------------------------------------------- PX4
@st.composite
def bad_actuator_bytes(draw: Any) -> bytes:
    """Garbage, or a CRC-valid HIL_ACTUATOR_CONTROLS with a used control non-finite or beyond +-1."""
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    if draw(st.booleans()):
        data = draw(st.binary(max_size=120))
        return b"\x00" + data  # never starts a whole valid frame by chance
    controls = draw(st.lists(st.floats(-1.0, 1.0, width=32), min_size=16, max_size=16))
    bad = draw(st.one_of(st.sampled_from([math.nan, math.inf, -math.inf]),
                         st.floats(1.5, 2.0**100, width=32), st.floats(-(2.0**100), -1.5, width=32)))
    controls[draw(st.integers(0, 3))] = bad
    return mav.hil_actuator_controls_encode(1, controls, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, 1).pack(mav)


@pytest.fixture(scope="module")
def px4(plant: Plant):
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0)
    yield srv
    srv.close()


def test_malformed_px4_actuator_messages_have_no_side_effect(px4: Px4Server) -> None:
    _counted(_px4_fuzz, "px4", px4)


@FUZZ
@given(data=bad_actuator_bytes())
def _px4_fuzz(px4: Px4Server, data: bytes) -> None:
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    good = mav.hil_actuator_controls_encode(1, [0.25] * 16, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, 1).pack(mav)
    assert _resync(px4, good) == 1  # after a good message the next one is taken at once
    pwm, armed, malformed = dict(px4.pwm), px4.armed, px4.stats.malformed
    before = _snapshot(px4.plant, px4.stats)
    assert px4._absorb(data) is False
    assert px4.pwm == pwm and px4.armed == armed and px4.stats.malformed > malformed
    assert _snapshot(px4.plant, px4.stats) == before
    # a stream parser: garbage ending in a frame header swallows up to one frame (<= 280 bytes) of what follows
    assert _resync(px4, good) <= 4
    COUNTS["px4"] += 1


def _resync(px4: Px4Server, good: bytes) -> int:
    """How many good actuator messages it takes until one is taken (at most 5 tried)."""
    for k in range(1, 6):
        if px4._absorb(good):
            return k
    return 99


# ---------------------------------------------------------------------------------------- generic MAVLink
class ScriptedConnection:
    """A pymavlink-like connection handing out given messages, recording what is written back."""

    def __init__(self) -> None:
        self.mav = mavlink2.MAVLink(self, srcSystem=1, srcComponent=51)
        self.inbox: list[Any] = []
        self.sent = 0

    def recv_match(self, type: Any = None, blocking: bool = False, timeout: float | None = None) -> Any:
        return self.inbox.pop(0) if self.inbox else None

    def write(self, buf: bytes) -> None:
        self.sent += len(buf)

    def close(self) -> None:
        pass


def _servo_raw(pwm: list[int]) -> Any:
    return mavlink2.MAVLink_servo_output_raw_message(0, 0, *pwm[:8], *([0] * 8))


def test_malformed_servo_output_raw_has_no_side_effect(plant: Plant) -> None:
    _counted(_servo_raw_fuzz, "mavlink", plant)


@FUZZ
@given(pwm=st.lists(st.integers(1000, 2000), min_size=8, max_size=8), where=st.integers(0, 3), bad=BAD_PWM,
       garbage=st.booleans())
def _servo_raw_fuzz(plant: Plant, pwm: list[int], where: int, bad: int, garbage: bool) -> None:
    conn = ScriptedConnection()
    bridge = MavlinkBridge(plant, SensorSuite(SensorConfig.noise_free()), conn, dt_s=0.004)  # type: ignore[arg-type]
    conn.inbox.append(_servo_raw([1000] * 8))
    bridge._receive()
    inputs, last_pwm = dict(plant.inputs), dict(bridge.pwm)
    before = _snapshot(plant, bridge.stats)
    pwm[where] = bad
    conn.inbox.append(mavlink2.MAVLink_bad_data(b"\xfe\x05junk", "junk") if garbage else _servo_raw(pwm))
    bridge._receive()
    assert bridge.stats.malformed == 1 and plant.inputs == inputs and bridge.pwm == last_pwm
    assert _snapshot(plant, bridge.stats) == before
    COUNTS["mavlink"] += 1


def _counted(fuzz: Callable[..., None], key: str, *args: Any) -> None:
    """Run a property test and check, in the same test (whatever ran before), that all its examples ran
    (hypothesis may stop early only when it has exhausted a strategy, which none of these can)."""
    before = COUNTS[key]
    fuzz(*args)
    assert COUNTS[key] - before >= EXAMPLES, f"{key}: {COUNTS[key] - before} of {EXAMPLES} examples ran"


def test_struct_layouts_are_what_sitl_sends() -> None:
    assert (SERVO16.size, SERVO32.size) == (40, 72) and struct.calcsize("<HHI") == 8

"""The ArduPilot SITL JSON codec's refusals and exact output, by hand (each message names what is wrong)."""

from __future__ import annotations

import json
import math
import re

import pytest

from hil_adapter.packets import (
    SERVO16,
    SERVO16_MAGIC,
    SERVO32_MAGIC,
    PacketError,
    ServoPacket,
    json_state,
    parse_json_state,
)

STATE = dict(timestamp_s=1.5, gyro_body_rad_s=(0.1, -0.2, 0.3), accel_body_m_s2=(0.0, 0.0, -9.81),
             position_ned_m=(1.0, 2.0, -3.0), velocity_ned_m_s=(0.5, 0.0, 0.0), quaternion=(1.0, 0.0, 0.0, 0.0))


def test_servo_packet_refusals_name_length_magic_and_rate() -> None:
    with pytest.raises(PacketError, match=r"^servo packet needs 16 or 32 PWM values, got 8$"):
        ServoPacket(400, 1, (1000,) * 8).pack()
    for data in (b"", b"\x1a"):
        with pytest.raises(PacketError, match=rf"^servo packet of {len(data)} bytes is too short for its magic$"):
            ServoPacket.unpack(data)
    with pytest.raises(PacketError, match=rf"^servo packet magic 1 is neither {SERVO16_MAGIC} \(16 ch\) nor "
                                          rf"{SERVO32_MAGIC} \(32 ch\)$"):
        ServoPacket.unpack(b"\x01\x00")
    with pytest.raises(PacketError, match=r"^servo packet frame_rate is 0 Hz$"):
        ServoPacket.unpack(SERVO16.pack(SERVO16_MAGIC, 0, 7, *([1500] * 16)))
    got = ServoPacket.unpack(SERVO16.pack(SERVO16_MAGIC, 1, 0, *range(1000, 1016)))  # 1 Hz, frame 0: both valid
    assert got == ServoPacket(1, 0, tuple(range(1000, 1016)))
    with pytest.raises(PacketError, match=r"must be 40 bytes, got 2$"):
        ServoPacket.unpack(SERVO16.pack(SERVO16_MAGIC, 400, 1, *([1500] * 16))[:2])


def test_json_state_exact_text_extras_and_refusals() -> None:
    text = json_state(**STATE, airspeed_m_s=12.5, extra={"rng": 3.25, "tag": "a"}).decode()
    assert text.startswith("\n{") and text.endswith(',"airspeed":12.5,"rng":3.25,"tag":"a"}\n')
    obj = parse_json_state(text.encode())
    assert obj["timestamp"] == 1.5 and obj["position"] == [1.0, 2.0, -3.0] and obj["rng"] == 3.25
    assert obj["imu"]["accel_body"] == [0.0, 0.0, pytest.approx(-9.81, rel=1e-7)]
    far = json_state(**{**STATE, "position_ned_m": (1e308, 1e308, 0.0)})  # finite values whose sum overflows
    assert parse_json_state(far)["position"][:2] == [1e308, 1e308]
    with pytest.raises(PacketError, match=r"^JSON state has a non-finite value: timestamp 1.5, gyro"):
        json_state(**{**STATE, "gyro_body_rad_s": (math.nan, 0.0, 0.0)})
    for bad in (math.inf, 1e39):
        with pytest.raises(PacketError, match=rf"^JSON state airspeed {re.escape(str(bad))} is not a finite float32$"):
            json_state(**STATE, airspeed_m_s=bad)
    with pytest.raises(PacketError, match=r"^JSON state needs 3-vectors and a 4-quaternion \("):
        json_state(**{**STATE, "quaternion": (1.0, 0.0)})
    with pytest.raises(PacketError, match=r"^JSON state value beyond float32 range"):
        json_state(**{**STATE, "accel_body_m_s2": (1e39, 0.0, 0.0)})


def test_parse_json_state_refusals() -> None:
    with pytest.raises(PacketError, match=r"^JSON state does not parse: "):
        parse_json_state(b"{nope")
    with pytest.raises(PacketError, match=r"^JSON state is not an object$"):
        parse_json_state(json.dumps([1, 2]).encode())

"""Wire formats of the simulator interfaces, declared once with pack/unpack.

ArduPilot SITL JSON backend (``libraries/SITL/examples/JSON/readme.md``): SITL sends binary servo packets
``uint16 magic, uint16 frame_rate, uint32 frame_count, uint16 pwm[16|32]`` over UDP; the physics backend
replies with one JSON object per frame, preceded and terminated by a newline. No library implements this
backend side in Python, so the struct layouts are written here. MAVLink (PX4 and generic) goes through
pymavlink.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

#: ArduPilot servo packet with 16 channels: magic, frame_rate [Hz], frame_count, pwm[16] [us]
SERVO16 = struct.Struct("<HHI16H")
SERVO16_MAGIC = 18458
#: with SERVO_32_ENABLE = 1: 32 channels
SERVO32 = struct.Struct("<HHI32H")
SERVO32_MAGIC = 29569
MAGIC_TO_STRUCT = {SERVO16_MAGIC: SERVO16, SERVO32_MAGIC: SERVO32}


class PacketError(ValueError):
    """A malformed packet; the message says what is wrong with it."""


@dataclass(frozen=True)
class ServoPacket:
    """One ArduPilot SITL output frame."""

    frame_rate_hz: int
    frame_count: int
    pwm_us: tuple[int, ...]

    def pack(self) -> bytes:
        layout, magic = (SERVO16, SERVO16_MAGIC) if len(self.pwm_us) == 16 else (SERVO32, SERVO32_MAGIC)
        if len(self.pwm_us) not in (16, 32):
            raise PacketError(f"servo packet needs 16 or 32 PWM values, got {len(self.pwm_us)}")
        return layout.pack(magic, self.frame_rate_hz, self.frame_count, *self.pwm_us)

    @classmethod
    def unpack(cls, data: bytes) -> ServoPacket:
        """Parse a datagram; ``PacketError`` names the length or magic that does not fit."""
        if len(data) < 2:
            raise PacketError(f"servo packet of {len(data)} bytes is too short for its magic")
        (magic,) = struct.unpack_from("<H", data)
        layout = MAGIC_TO_STRUCT.get(magic)
        if layout is None:
            raise PacketError(f"servo packet magic {magic} is neither {SERVO16_MAGIC} (16 ch) nor {SERVO32_MAGIC} "
                              "(32 ch)")
        if len(data) != layout.size:
            raise PacketError(f"servo packet with magic {magic} must be {layout.size} bytes, got {len(data)}")
        _, rate, count, *pwm = layout.unpack(data)
        if rate == 0:
            raise PacketError("servo packet frame_rate is 0 Hz")
        return cls(rate, count, tuple(pwm))


def _vec(values: Sequence[float], name: str) -> list[float]:
    out = [float(v) for v in values]
    if not all(math.isfinite(v) for v in out):
        raise PacketError(f"JSON state field {name} is not finite: {out}")
    return out


def json_state(timestamp_s: float, gyro_body_rad_s: Sequence[float], accel_body_m_s2: Sequence[float],
               position_ned_m: Sequence[float], velocity_ned_m_s: Sequence[float], quaternion: Sequence[float],
               airspeed_m_s: float | None = None, extra: Mapping[str, object] | None = None) -> bytes:
    """The physics backend's reply: a JSON object framed by newlines (quaternion w, x, y, z body->NED)."""
    obj: dict[str, object] = {
        "timestamp": float(timestamp_s),
        "imu": {"gyro": _vec(gyro_body_rad_s, "imu.gyro"), "accel_body": _vec(accel_body_m_s2, "imu.accel_body")},
        "position": _vec(position_ned_m, "position"),
        "velocity": _vec(velocity_ned_m_s, "velocity"),
        "quaternion": _vec(quaternion, "quaternion"),
    }
    if airspeed_m_s is not None:
        obj["airspeed"] = float(airspeed_m_s)
    if extra:
        obj.update(extra)
    return ("\n" + json.dumps(obj, separators=(",", ":")) + "\n").encode()


def parse_json_state(data: bytes) -> dict[str, object]:
    """Inverse of :func:`json_state` (what SITL parses), for tests and recorders."""
    try:
        obj = json.loads(data.decode().strip())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise PacketError(f"JSON state does not parse: {err}") from err
    if not isinstance(obj, dict):
        raise PacketError("JSON state is not an object")
    return obj

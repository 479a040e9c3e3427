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
from typing import NamedTuple

#: ArduPilot servo packet with 16 channels: magic, frame_rate [Hz], frame_count, pwm[16] [us]
SERVO16 = struct.Struct("<HHI16H")
SERVO16_MAGIC = 18458
#: with SERVO_32_ENABLE = 1: 32 channels
SERVO32 = struct.Struct("<HHI32H")
SERVO32_MAGIC = 29569
MAGIC_TO_STRUCT = {SERVO16_MAGIC: SERVO16, SERVO32_MAGIC: SERVO32}


class PacketError(ValueError):
    """A malformed packet; the message says what is wrong with it."""


class ServoPacket(NamedTuple):
    """One ArduPilot SITL output frame (a named tuple: one is unpacked per lockstep frame)."""

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
        magic = data[0] | data[1] << 8  # little-endian uint16
        layout = MAGIC_TO_STRUCT.get(magic)
        if layout is None:
            raise PacketError(f"servo packet magic {magic} is neither {SERVO16_MAGIC} (16 ch) nor {SERVO32_MAGIC} "
                              "(32 ch)")
        if len(data) != layout.size:
            raise PacketError(f"servo packet with magic {magic} must be {layout.size} bytes, got {len(data)}")
        fields = layout.unpack(data)
        if fields[1] == 0:
            raise PacketError("servo packet frame_rate is 0 Hz")
        return cls(fields[1], fields[2], fields[3:])


#: SITL reads the timestamp and position as doubles (17 significant digits give every double back exactly, and
#: format in about half the time of the shortest repr) and the IMU, velocity and quaternion as floats: those are
#: rounded to float32 first, and 9 significant digits give every float32 back exactly
_STATE_FORMAT = ('\n{"timestamp":%.17g,"imu":{"gyro":[%.9g,%.9g,%.9g],"accel_body":[%.9g,%.9g,%.9g]},'
                 '"position":[%.17g,%.17g,%.17g],"velocity":[%.9g,%.9g,%.9g],"quaternion":[%.9g,%.9g,%.9g,%.9g]')
_FLOAT32_FIELDS = struct.Struct("<13f")  #: gyro, accel, velocity, quaternion as SITL stores them
_FLOAT32 = struct.Struct("<f")


def json_state(timestamp_s: float, gyro_body_rad_s: Sequence[float], accel_body_m_s2: Sequence[float],
               position_ned_m: Sequence[float], velocity_ned_m_s: Sequence[float], quaternion: Sequence[float],
               airspeed_m_s: float | None = None, extra: Mapping[str, object] | None = None) -> bytes:
    """The physics backend's reply: a JSON object framed by newlines (quaternion w, x, y, z body->NED).

    Formatted with a fixed template (finite floats format as valid JSON): ``json.dumps`` of the nested dict
    costs several times more, once per lockstep frame. ``PacketError`` for a non-finite value or one beyond
    float32's range in a float field.
    """
    try:
        pn, pe, pd = position_ned_m
        singles = _FLOAT32_FIELDS.unpack(_FLOAT32_FIELDS.pack(*gyro_body_rad_s, *accel_body_m_s2, *velocity_ned_m_s,
                                                              *quaternion))
    except OverflowError as err:
        raise PacketError(f"JSON state value beyond float32 range ({err}): gyro {gyro_body_rad_s}, accel "
                          f"{accel_body_m_s2}, velocity {velocity_ned_m_s}, quaternion {quaternion}") from None
    except (ValueError, struct.error) as err:
        raise PacketError(f"JSON state needs 3-vectors and a 4-quaternion ({err})") from None
    values = (float(timestamp_s), *singles[:6], float(pn), float(pe), float(pd), *singles[6:])
    # one sum instead of 17 tests in the common case; a sum that overflows is checked value by value
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
        raise PacketError(f"JSON state has a non-finite value: timestamp {timestamp_s}, gyro {gyro_body_rad_s}, "
                          f"accel {accel_body_m_s2}, position {position_ned_m}, velocity {velocity_ned_m_s}, "
                          f"quaternion {quaternion}")
    text = _STATE_FORMAT % values
    if airspeed_m_s is not None:
        try:
            (airspeed,) = _FLOAT32.unpack(_FLOAT32.pack(airspeed_m_s))
        except OverflowError:
            airspeed = math.inf
        if not math.isfinite(airspeed):
            raise PacketError(f"JSON state airspeed {airspeed_m_s} is not a finite float32")
        text += f',"airspeed":{airspeed:.9g}'
    if extra:
        text += "," + json.dumps(dict(extra), separators=(",", ":"))[1:-1]
    return (text + "}\n").encode()


def parse_json_state(data: bytes) -> dict[str, object]:
    """Inverse of :func:`json_state` (what SITL parses), for tests and recorders."""
    try:
        obj = json.loads(data.decode().strip())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise PacketError(f"JSON state does not parse: {err}") from err
    if not isinstance(obj, dict):
        raise PacketError("JSON state is not an object")
    return obj

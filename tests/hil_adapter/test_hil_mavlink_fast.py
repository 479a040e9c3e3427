"""The per-step MAVLink framing against pymavlink: the same bytes out, the same fields in, and pymavlink
taking over for anything the fast path does not cover."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from hil_adapter.mavlink_fast import FastMavlink
from hil_adapter.px4 import HilMessages
from hil_adapter.sensors import SensorSuite

F32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
I32 = st.integers(-(2**31), 2**31 - 1)
I16 = st.integers(-(2**15), 2**15 - 1)
U16 = st.integers(0, 2**16 - 1)
U64 = st.integers(0, 2**64 - 1)


def _reference(mav: mavlink2.MAVLink, msg: mavlink2.MAVLink_message) -> bytes:
    """What pymavlink sends for ``msg`` (``MAVLink.send`` packs, then advances the sequence number)."""
    buf = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return buf


@settings(max_examples=150, deadline=None)
@given(t=U64, imu=st.lists(F32, min_size=13, max_size=13), fields=st.integers(0, 2**32 - 1),
       seq=st.integers(0, 255))
def test_hil_sensor_bytes_equal_pymavlink(t: int, imu: list[float], fields: int, seq: int) -> None:
    ours, ref = mavlink2.MAVLink(None, 1, 51), mavlink2.MAVLink(None, 1, 51)
    ours.seq = ref.seq = seq
    args = (t, *imu, fields)
    assert FastMavlink(ours).pack(mavlink2.MAVLink_hil_sensor_message, *args) == _reference(
        ref, mavlink2.MAVLink_hil_sensor_message(*args))
    assert ours.seq == ref.seq == (seq + 1) % 256


@settings(max_examples=150, deadline=None)
@given(t=U64, q=st.lists(F32, min_size=4, max_size=4), rates=st.lists(F32, min_size=3, max_size=3),
       pos=st.lists(I32, min_size=3, max_size=3), vel=st.lists(I16, min_size=3, max_size=3),
       air=st.lists(U16, min_size=2, max_size=2), acc=st.lists(I16, min_size=3, max_size=3))
def test_hil_state_quaternion_bytes_equal_pymavlink(t, q, rates, pos, vel, air, acc) -> None:
    """Array fields (the quaternion) and zero tails (MAVLink 2 trims trailing zero bytes) included."""
    ours, ref = mavlink2.MAVLink(None, 1, 51), mavlink2.MAVLink(None, 1, 51)
    args = (t, q, *rates, *pos, *vel, *air, *acc)
    assert FastMavlink(ours).pack(mavlink2.MAVLink_hil_state_quaternion_message, *args) == _reference(
        ref, mavlink2.MAVLink_hil_state_quaternion_message(*args))


def test_every_hil_message_equals_pymavlink_and_parses_back() -> None:
    """The builders the PX4 server and the MAVLink bridge use, one step with GPS, heartbeat and RC."""
    suite = SensorSuite(seed=3)
    state = {"accel_body_x_m_s2": 0.1, "accel_body_y_m_s2": -0.2, "accel_body_z_m_s2": -9.8, "rate_body_x_rad_s": 0.01,
             "rate_body_y_rad_s": -0.02, "rate_body_z_rad_s": 0.03, "quat_w": 1.0, "quat_x": 0.0, "quat_y": 0.0,
             "quat_z": 0.0, "roll_rad": 0.0, "pitch_rad": 0.0, "yaw_rad": 0.0, "pos_north_m": 1.0,
             "pos_east_m": 2.0, "pos_down_m": -3.0, "vel_north_m_s": 0.5, "vel_east_m_s": -0.5,
             "vel_down_m_s": 0.1, "lat_deg": 47.397742, "lon_deg": 8.545594, "height_m": 491.0, "altitude_m": 3.0}
    frame = suite.sample(0.0, state)
    assert frame.gps is not None
    mav = mavlink2.MAVLink(None, 1, 51)
    msgs = HilMessages(mav, "quadrotor")
    out = [msgs.sensor(10, frame), msgs.state(10, state), msgs.gps(10, frame.gps), msgs.heartbeat(),
           msgs.rc(0, [1500, 1500, 1000, 1500])]
    parser = mavlink2.MAVLink(None, 255, 0)
    parsed = parser.parse_buffer(b"".join(out))
    assert [m.get_type() for m in parsed] == ["HIL_SENSOR", "HIL_STATE_QUATERNION", "HIL_GPS", "HEARTBEAT",
                                              "RC_CHANNELS"]
    assert [m.get_seq() for m in parsed] == [0, 1, 2, 3, 4]
    assert parsed[0].zacc == pytest.approx(frame.accel_body_m_s2[2], rel=1e-6)
    assert parsed[1].lat == round(47.397742e7)
    assert parsed[3].type == mavlink2.MAV_TYPE_QUADROTOR and parsed[3].mavlink_version == 3
    assert parsed[4].chan3_raw == 1000 and parsed[4].chan5_raw == 65535 and parsed[4].chancount == 4
    # the same bytes as pymavlink's own encoders
    ref = mavlink2.MAVLink(None, 1, 51)
    ref.seq = 3
    assert out[3] == ref.heartbeat_encode(mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0,
                                          mavlink2.MAV_STATE_ACTIVE).pack(ref)
    ref.seq = 2
    fix = frame.gps
    assert out[2] == ref.hil_gps_encode(
        10, int(fix.fix_type), round(fix.lat_deg * 1e7), round(fix.lon_deg * 1e7), round(fix.alt_msl_m * 1e3),
        min(round(fix.eph_m * 100), 65535), min(round(fix.epv_m * 100), 65535),
        min(round(fix.ground_speed_m_s * 100), 65535), round(fix.vel_ned_m_s[0] * 100),
        round(fix.vel_ned_m_s[1] * 100), round(fix.vel_ned_m_s[2] * 100), round(fix.course_deg * 100) % 36000,
        int(fix.satellites)).pack(ref)


def test_signed_links_are_signed_by_pymavlink() -> None:
    mav = mavlink2.MAVLink(None, 1, 51)
    mav.signing.secret_key = bytes(range(32))
    mav.signing.sign_outgoing = True
    buf = FastMavlink(mav).pack(mavlink2.MAVLink_heartbeat_message, 2, 8, 0, 0, 4, 3)
    assert buf[2] & mavlink2.MAVLINK_IFLAG_SIGNED and len(buf) == 12 + 9 + 13
    assert mav.seq == 1


def _actuator_frame(controls: list[float], mode: int, flags: int, t_us: int = 7) -> bytes:
    px4 = mavlink2.MAVLink(None, 1, 1)
    return px4.hil_actuator_controls_encode(t_us, controls, mode, flags).pack(px4)


@settings(max_examples=150, deadline=None)
@given(controls=st.lists(F32, min_size=16, max_size=16), mode=st.integers(0, 255), flags=U64,
       tail=st.binary(max_size=40))
def test_actuator_controls_parse_like_pymavlink(controls: list[float], mode: int, flags: int, tail: bytes) -> None:
    """Zero controls are trimmed off the wire by MAVLink 2; whatever follows the frame is handed back."""
    frame = _actuator_frame(controls, mode, flags)
    got = FastMavlink(mavlink2.MAVLink(None, 1, 51)).actuator_controls(frame + tail)
    assert got is not None
    ref = mavlink2.MAVLink(None, 1, 51).parse_buffer(frame)[0]
    assert list(got[0]) == list(ref.controls) and got[1] == ref.mode == mode and got[2] == ref.flags == flags
    assert got[3] == tail


def test_actuator_fast_path_declines_what_pymavlink_must_parse() -> None:
    fast = FastMavlink(mavlink2.MAVLink(None, 1, 51))
    frame = _actuator_frame([0.5] * 4 + [0.0] * 12, 128, 1)
    assert fast.actuator_controls(frame[:-1]) is None  # split across reads
    bad = bytearray(frame)
    bad[-1] ^= 0xFF
    assert fast.actuator_controls(bytes(bad)) is None  # CRC: pymavlink counts the bad data
    hb = mavlink2.MAVLink(None, 1, 1)
    assert fast.actuator_controls(hb.heartbeat_encode(2, 12, 0, 0, 4).pack(hb) + frame) is None  # other message
    assert fast.actuator_controls(b"\x00" + frame) is None  # garbage first
    fast.mav.parse_buffer(frame[:5])  # pymavlink holds a partial frame: its bytes come first
    assert fast.actuator_controls(frame) is None
    signer = mavlink2.MAVLink(None, 1, 1)
    signer.signing.secret_key, signer.signing.sign_outgoing = bytes(32), True
    signed = signer.hil_actuator_controls_encode(0, [0.5] * 16, 128, 1).pack(signer)
    assert FastMavlink(mavlink2.MAVLink(None, 1, 51)).actuator_controls(signed) is None


def test_all_zero_payload_keeps_one_byte() -> None:
    """MAVLink 2 trims trailing zeros but keeps at least one payload byte (as pymavlink does)."""
    ours, ref = mavlink2.MAVLink(None, 1, 51), mavlink2.MAVLink(None, 1, 51)
    buf = FastMavlink(ours).pack(mavlink2.MAVLink_hil_actuator_controls_message, 0, [0.0] * 16, 0, 0)
    assert buf[1] == 1 and buf == mavlink2.MAVLink_hil_actuator_controls_message(0, [0.0] * 16, 0, 0).pack(ref)
    got = FastMavlink(mavlink2.MAVLink(None, 1, 51)).actuator_controls(buf)
    assert got is not None and all(c == 0.0 and not math.copysign(1, c) < 0 for c in got[0])


def test_checksum_without_fastcrc_matches(monkeypatch: pytest.MonkeyPatch) -> None:
    """pymavlink falls back to its pure-Python CRC without fastcrc; so do we, with the same bytes."""
    import hil_adapter.mavlink_fast as fast_module

    args = (5, 0.1, 0.2, -9.8, 0.0, 0.0, 0.0, 0.2, 0.0, 0.4, 1013.0, 0.0, 100.0, 15.0, 8191)
    with_fastcrc = FastMavlink(mavlink2.MAVLink(None, 1, 51)).pack(mavlink2.MAVLink_hil_sensor_message, *args)
    monkeypatch.setattr(fast_module, "_MCRF4XX", None)
    monkeypatch.setattr(mavlink2, "x25crc", mavlink2._x25crc_slow)
    assert FastMavlink(mavlink2.MAVLink(None, 1, 51)).pack(mavlink2.MAVLink_hil_sensor_message, *args) == with_fastcrc


def test_ground_truth_saturates_int16_fields_instead_of_failing() -> None:
    """A crash landing can exceed 32 g, a runaway model 327 m/s: the int16 fields saturate."""
    state = {"quat_w": 1.0, "quat_x": 0.0, "quat_y": 0.0, "quat_z": 0.0, "rate_body_x_rad_s": 0.0,
             "rate_body_y_rad_s": 0.0, "rate_body_z_rad_s": 0.0, "lat_deg": 47.0, "lon_deg": 8.0, "height_m": 500.0,
             "vel_north_m_s": 400.0, "vel_east_m_s": -400.0, "vel_down_m_s": 1.0, "accel_body_x_m_s2": 50 * 9.80665,
             "accel_body_y_m_s2": 0.0, "accel_body_z_m_s2": -50 * 9.80665}
    msg = mavlink2.MAVLink(None, 255, 0).parse_buffer(HilMessages(mavlink2.MAVLink(None, 1, 51), "quadrotor")
                                                      .state(0, state))[0]
    assert (msg.vx, msg.vy, msg.vz) == (32767, -32768, 100)
    assert (msg.xacc, msg.zacc) == (32767, -32768)


def test_sequence_wraps_and_only_zero_bytes_are_trimmed() -> None:
    """The sequence number after 255 is 0; a payload ending in a non-zero byte (0x58, 'X') keeps it."""
    ours, ref = mavlink2.MAVLink(None, 1, 51), mavlink2.MAVLink(None, 1, 51)
    ours.seq = ref.seq = 255
    args = (1, *([0.5] * 13), 0x58000000)  # fields_updated little-endian: its last byte is 0x58
    fast = FastMavlink(ours).pack(mavlink2.MAVLink_hil_sensor_message, *args)
    assert fast == _reference(ref, mavlink2.MAVLink_hil_sensor_message(*args))
    assert ours.seq == 0 and fast[-3] == 0x58  # ... then the two CRC bytes


def test_actuator_fast_path_checks_all_three_message_id_bytes() -> None:
    """A frame whose 24-bit message id only shares its low byte with HIL_ACTUATOR_CONTROLS (93) is not taken,
    even with a checksum made for it; nor is a buffer too short for a header."""
    from hil_adapter.mavlink_fast import CRC, HEADER_LEN, _crc16

    fast = FastMavlink(mavlink2.MAVLink(None, 1, 51))
    frame = _actuator_frame([0.5] * 4 + [0.0] * 12, 128, 1)
    extra = bytes((mavlink2.MAVLink_hil_actuator_controls_message.crc_extra,))
    assert fast.actuator_controls(frame) is not None
    for at in (8, 9):  # id bytes 2 and 3
        other = bytearray(frame)
        other[at] = 1
        other[-2:] = CRC.pack(_crc16(bytes(other[1:-2]) + extra))
        assert len(other) > HEADER_LEN + 2 and fast.actuator_controls(bytes(other)) is None, at
    for short in (b"", b"\xfd", frame[:HEADER_LEN + 1]):
        assert fast.actuator_controls(short) is None


def test_ground_truth_indicated_airspeed_is_the_equivalent_one() -> None:
    """HIL_STATE_QUATERNION: ``true_airspeed`` the FMU's, ``ind_airspeed`` what a pitot reads (the equivalent
    airspeed, 3.2 % lower at 651 m AMSL); no airspeed output: both 0."""
    from fmu_models.common.atmosphere import eas_to_tas

    state = {"quat_w": 1.0, "quat_x": 0.0, "quat_y": 0.0, "quat_z": 0.0, "rate_body_x_rad_s": 0.0,
             "rate_body_y_rad_s": 0.0, "rate_body_z_rad_s": 0.0, "lat_deg": -35.0, "lon_deg": 149.0, "height_m": 651.0,
             "vel_north_m_s": 27.0, "vel_east_m_s": 0.0, "vel_down_m_s": 0.0, "accel_body_x_m_s2": 0.0,
             "accel_body_y_m_s2": 0.0, "accel_body_z_m_s2": -9.80665}

    def parsed(s: dict[str, float]) -> object:
        return mavlink2.MAVLink(None, 255, 0).parse_buffer(HilMessages(mavlink2.MAVLink(None, 1, 51), "fixed_wing")
                                                           .state(0, s))[0]

    msg = parsed({**state, "airspeed_m_s": 27.0})
    assert msg.true_airspeed == 2700
    assert msg.ind_airspeed == round(2700 / eas_to_tas(651.0)) == 2616
    msg = parsed(state)
    assert (msg.ind_airspeed, msg.true_airspeed) == (0, 0)

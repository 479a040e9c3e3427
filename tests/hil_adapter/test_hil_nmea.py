"""NMEA GPS output: sentences parsed back with pynmea2, hemispheres, bad inputs, and the writer over a real
pseudo-terminal pair, pyserial's ``loop://`` and a port that fails."""

from __future__ import annotations

import errno
import math
import os
import select
import time
from collections.abc import Iterator
from datetime import UTC, date, datetime, timedelta, timezone
from datetime import time as dtime

import pynmea2
import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from hil_adapter.nmea import KMH_PER_M_S, KNOTS_PER_M_S, NmeaError, NmeaGpsWriter, nmea_sentences, open_serial

UTC0 = datetime(2024, 6, 21, 13, 45, 7, 250000, tzinfo=UTC)


def parse_all(lines: list[str]) -> list[pynmea2.NMEASentence]:
    """Each line must be a full ``$...*hh\\r\\n`` line with a valid checksum."""
    out = []
    for line in lines:
        assert line.startswith("$") and line.endswith("\r\n") and line.count("\r\n") == 1, repr(line)
        assert len(line) <= 82, f"NMEA 0183 limit is 82 characters: {line!r}"
        out.append(pynmea2.parse(line.strip(), check=True))
    return out


def split_lines(data: bytes) -> list[str]:
    text = data.decode("ascii")
    assert text.endswith("\r\n"), repr(text[-20:])
    return [line + "\r\n" for line in text.split("\r\n")[:-1]]


# --------------------------------------------------------------------------------------------- sentences


def test_sentences_round_trip_through_pynmea2() -> None:
    lines = nmea_sentences(UTC0, 47.3977419, 8.5455938, 488.25, 12.5, 123.45, 1, 10, 0.8, geoid_sep_m=47.6)
    gga, rmc, vtg = parse_all(lines)
    assert isinstance(gga, pynmea2.GGA) and isinstance(rmc, pynmea2.RMC) and isinstance(vtg, pynmea2.VTG)
    assert [m.talker for m in (gga, rmc, vtg)] == ["GP"] * 3
    for m in (gga, rmc):
        assert m.latitude == pytest.approx(47.3977419, abs=1e-6)
        assert m.longitude == pytest.approx(8.5455938, abs=1e-6)
        assert m.lat_dir == "N" and m.lon_dir == "E"
        assert m.timestamp == dtime(13, 45, 7, 250000, tzinfo=UTC)
    assert lines[0].split(",")[1] == "134507.25" and lines[0].split(",")[2] == "4723.86451"
    assert lines[0].split(",")[4] == "00832.73563"
    assert gga.gps_qual == 1 and int(gga.num_sats) == 10 and float(gga.horizontal_dil) == pytest.approx(0.8)
    assert gga.altitude == pytest.approx(488.25) and gga.altitude_units == "M"
    assert float(gga.geo_sep) == pytest.approx(47.6) and gga.geo_sep_units == "M"
    assert rmc.status == "A" and rmc.datestamp == date(2024, 6, 21) and rmc.mode_indicator == "A"
    assert rmc.spd_over_grnd == pytest.approx(12.5 * KNOTS_PER_M_S, abs=1e-3)
    assert rmc.spd_over_grnd == pytest.approx(24.298, abs=1e-3)  # 12.5 m/s in knots, by hand
    assert rmc.true_course == pytest.approx(123.45)
    assert float(vtg.true_track) == pytest.approx(123.45) and vtg.true_track_sym == "T"
    assert float(vtg.spd_over_grnd_kts) == pytest.approx(12.5 * KNOTS_PER_M_S, abs=1e-3)
    assert float(vtg.spd_over_grnd_kmph) == pytest.approx(45.0, abs=1e-3) and vtg.spd_over_grnd_kmph_sym == "K"
    assert 12.5 * KMH_PER_M_S == pytest.approx(45.0)
    assert rmc.datetime == datetime(2024, 6, 21, 13, 45, 7, 250000, tzinfo=UTC)


def test_southern_and_western_hemispheres() -> None:
    gga, rmc, _ = parse_all(nmea_sentences(UTC0, -33.8567844, -151.2152967, 5.0, 0.0, 0.0, 1, 8, 1.1))
    for m in (gga, rmc):
        assert m.lat_dir == "S" and m.lon_dir == "W"
        assert m.latitude == pytest.approx(-33.8567844, abs=1e-6)
        assert m.longitude == pytest.approx(-151.2152967, abs=1e-6)
    # the poles and the antimeridian keep their widths; a tiny negative that rounds to zero is not "S"
    gga, _, _ = parse_all(nmea_sentences(UTC0, -90.0, 180.0, 0.0, 0.0, 0.0, 1, 8, 1.0))
    assert gga.lat == "9000.00000" and gga.lat_dir == "S" and gga.lon == "18000.00000" and gga.lon_dir == "E"
    gga, _, _ = parse_all(nmea_sentences(UTC0, -1e-12, -1e-12, 0.0, 0.0, 0.0, 1, 8, 1.0))
    assert (gga.lat, gga.lat_dir, gga.lon, gga.lon_dir) == ("0000.00000", "N", "00000.00000", "E")


def test_minutes_round_up_into_the_next_degree() -> None:
    gga, _, _ = parse_all(nmea_sentences(UTC0, 12.9999999999, -45.9999999999, 0.0, 0.0, 0.0, 1, 8, 1.0))
    assert gga.lat == "1300.00000" and gga.lon == "04600.00000" and gga.lon_dir == "W"


@settings(max_examples=200, deadline=None)
@given(lat=st.floats(-90, 90), lon=st.floats(-180, 180))
def test_any_position_round_trips_to_1e_6_deg(lat: float, lon: float) -> None:
    gga, rmc, _ = parse_all(nmea_sentences(UTC0, lat, lon, 0.0, 0.0, 0.0, 1, 8, 1.0))
    for m in (gga, rmc):
        assert m.latitude == pytest.approx(lat, abs=1e-6) and m.longitude == pytest.approx(lon, abs=1e-6)


def test_no_fix_is_status_v_and_other_fix_types() -> None:
    gga, rmc, vtg = parse_all(nmea_sentences(UTC0, 1.0, 2.0, 3.0, 0.0, 0.0, 0, 0, 99.99))
    assert gga.gps_qual == 0 and gga.num_sats == "00" and rmc.status == "V"
    assert rmc.mode_indicator == "N" and vtg.faa_mode == "N"
    gga, rmc, vtg = parse_all(nmea_sentences(UTC0, 1.0, 2.0, 3.0, 0.0, 0.0, 2, 14, 0.6))
    assert gga.gps_qual == 2 and rmc.status == "A" and rmc.mode_indicator == "D" and vtg.faa_mode == "D"


def test_time_rounding_carries_into_the_date_and_timezones_convert() -> None:
    _, rmc, _ = parse_all(nmea_sentences(datetime(2023, 12, 31, 23, 59, 59, 996000, tzinfo=UTC),
                                         0.0, 0.0, 0.0, 0.0, 0.0, 1, 8, 1.0))
    assert rmc.datetime == datetime(2024, 1, 1, tzinfo=UTC)
    cest = timezone(timedelta(hours=2))
    _, rmc, _ = parse_all(nmea_sentences(datetime(2024, 6, 22, 1, 30, tzinfo=cest), 0, 0, 0, 0, 0, 1, 8, 1.0))
    assert rmc.datetime == datetime(2024, 6, 21, 23, 30, tzinfo=UTC)
    _, rmc, _ = parse_all(nmea_sentences(datetime(2024, 6, 21, 23, 30), 0, 0, 0, 0, 0, 1, 8, 1.0))  # naive = UTC
    assert rmc.datetime == datetime(2024, 6, 21, 23, 30, tzinfo=UTC)


def test_course_near_360_is_sent_as_zero() -> None:
    _, rmc, vtg = parse_all(nmea_sentences(UTC0, 0, 0, 0, 5.0, 359.999, 1, 8, 1.0))
    assert rmc.true_course == 0.0 and float(vtg.true_track) == 0.0
    _, rmc, _ = parse_all(nmea_sentences(UTC0, 0, 0, 0, 5.0, 360.0, 1, 8, 1.0))
    assert rmc.true_course == 0.0


def test_longest_sentences_fit_the_nmea_limit() -> None:
    for alt in (-1000.0, 50_000.0):
        parse_all(nmea_sentences(UTC0, -89.99, -179.99, alt, 10_000.0, 359.0, 8, 99, 99.99, -199.99))


@pytest.mark.parametrize(
    ("field", "kwargs"),
    [
        ("lat_deg", {"lat_deg": 90.5}),
        ("lat_deg", {"lat_deg": math.nan}),
        ("lon_deg", {"lon_deg": -180.01}),
        ("lon_deg", {"lon_deg": math.inf}),
        ("alt_msl_m", {"alt_msl_m": -math.inf}),
        ("ground_speed_m_s", {"ground_speed_m_s": -0.1}),
        ("course_deg", {"course_deg": 361.0}),
        ("course_deg", {"course_deg": -1.0}),
        ("fix_quality", {"fix_quality": 9}),
        ("fix_quality", {"fix_quality": 1.0}),
        ("fix_quality", {"fix_quality": True}),
        ("satellites", {"satellites": -1}),
        ("satellites", {"satellites": 100}),
        ("hdop", {"hdop": -0.5}),
        ("hdop", {"hdop": "0.8"}),
        ("geoid_sep_m", {"geoid_sep_m": math.nan}),
        ("utc", {"utc": "2024-06-21T13:45:07Z"}),
    ],
)
def test_invalid_inputs_name_the_field_value_and_range(field: str, kwargs: dict) -> None:
    args = {"utc": UTC0, "lat_deg": 10.0, "lon_deg": 20.0, "alt_msl_m": 30.0, "ground_speed_m_s": 1.0,
            "course_deg": 90.0, "fix_quality": 1, "satellites": 8, "hdop": 1.0, "geoid_sep_m": 0.0}
    args.update(kwargs)
    with pytest.raises(NmeaError, match=f"^{field}=") as info:
        nmea_sentences(**args)
    assert isinstance(info.value, ValueError)
    assert repr(kwargs[field]) in str(info.value)
    if field != "utc":
        assert "allowed range [" in str(info.value)


# --------------------------------------------------------------------------------------------- writer


class RecordingPort:
    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.chunks.append(bytes(data))
        return len(data)


def drive(writer: NmeaGpsWriter, steps: int = 100, dt: float = 0.01, **state: float) -> list[int]:
    """``steps`` simulation steps of ``dt`` from t = 0 (1 s at 100 Hz by default); the bytes of every poll."""
    out = []
    for i in range(steps):
        t = i * dt
        writer.update(t, 47.0 + 1e-6 * i, 8.0, 500.0, state.get("vn", 3.0), state.get("ve", 4.0), 0.5)
        out.append(writer.poll(t))
    return out


def test_writer_schedule_speed_course_and_utc() -> None:
    port = RecordingPort()
    start = datetime(2024, 6, 21, 12, 0, tzinfo=UTC)
    writer = NmeaGpsWriter(port, rate_hz=5.0, start_utc=start)
    assert writer.poll(0.0) == 0 and writer.sent == 0  # nothing before the first update
    written = drive(writer)
    assert [i for i, n in enumerate(written) if n] == [0, 20, 40, 60, 80]
    assert len(port.chunks) == 5 and writer.sent == 15 and writer.errors == 0 and writer.last_error is None
    assert sum(written) == writer.bytes_written == sum(map(len, port.chunks))
    msgs = parse_all(split_lines(b"".join(port.chunks)))
    assert [type(m).__name__ for m in msgs] == ["GGA", "RMC", "VTG"] * 5
    rmcs = [m for m in msgs if isinstance(m, pynmea2.RMC)]
    assert [m.datetime for m in rmcs] == [start + timedelta(seconds=0.2 * k) for k in range(5)]
    for m in rmcs:
        assert m.spd_over_grnd == pytest.approx(5.0 * KNOTS_PER_M_S, abs=1e-3)  # hypot(3, 4) m/s
        assert m.true_course == pytest.approx(math.degrees(math.atan2(4.0, 3.0)), abs=0.01)
    assert msgs[-3].latitude == pytest.approx(47.0 + 80e-6, abs=1e-6)  # the latest state at t = 0.8 s


def test_writer_keeps_course_when_still_skips_missed_epochs_and_restarts_on_reset() -> None:
    port = RecordingPort()
    writer = NmeaGpsWriter(port, rate_hz=5.0, start_utc=UTC0)
    writer.update(0.0, 1.0, 2.0, 3.0, 0.0, -2.0, 0.0)  # heading west
    assert writer.poll(0.0) > 0
    writer.update(0.1, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0)  # stopped: course stays 270
    assert writer.poll(0.1) == 0 and writer.poll(0.2) > 0
    assert parse_all(split_lines(port.chunks[-1]))[1].true_course == pytest.approx(270.0)
    assert writer.state_time_s == 0.1
    assert writer.poll(1.05) > 0 and writer.poll(1.1) == 0 and writer.poll(1.2) > 0  # one late epoch, no burst
    assert writer.poll(0.0) > 0 and writer.poll(0.1) == 0  # time went back: schedule restarts
    assert writer.sent == 5 * 3


def test_writer_rejects_bad_state_and_rate() -> None:
    writer = NmeaGpsWriter(RecordingPort())
    with pytest.raises(NmeaError, match=r"^lat_deg=91"):
        writer.update(0.0, 91.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(NmeaError, match=r"^vel_down_m_s=nan"):
        writer.update(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, math.nan)
    with pytest.raises(NmeaError, match=r"^satellites=-3"):
        writer.update(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, satellites=-3)
    with pytest.raises(NmeaError, match=r"^t_s=nan"):
        writer.poll(math.nan)
    for bad in (0.0, -5.0, math.nan, 1000.0):
        with pytest.raises(NmeaError, match=r"^rate_hz="):
            NmeaGpsWriter(RecordingPort(), rate_hz=bad)
    assert writer.poll(0.0) == 0 and writer.sent == 0  # the rejected states were not stored


class BrokenPort:
    def __init__(self) -> None:
        self.calls = 0

    def write(self, data: bytes) -> int:
        self.calls += 1
        raise OSError(errno.EIO, "Input/output error")


def test_write_errors_are_counted_not_raised() -> None:
    port = BrokenPort()
    writer = NmeaGpsWriter(port, start_utc=UTC0)
    assert sum(drive(writer)) == 0
    assert port.calls == 5 and writer.errors == 5 and writer.sent == 0
    assert isinstance(writer.last_error, OSError) and writer.last_error.errno == errno.EIO


def test_short_writes_are_errors() -> None:
    class HalfPort:
        def write(self, data: bytes) -> int:
            return len(data) // 2

    writer = NmeaGpsWriter(HalfPort(), start_utc=UTC0)
    written = drive(writer, steps=1)
    assert written[0] > 0 and writer.errors == 1 and writer.sent == 0 and "short write" in str(writer.last_error)


# --------------------------------------------------------------------------------------------- real ports


def read_fd_until(fd: int, n_lines: int, timeout_s: float = 5.0) -> bytes:
    """Read from ``fd`` until ``n_lines`` CRLFs arrived or the deadline passed, then a short quiet wait."""
    buf = b""
    deadline = time.monotonic() + timeout_s
    while buf.count(b"\r\n") < n_lines and (left := deadline - time.monotonic()) > 0:
        if select.select([fd], [], [], min(left, 0.5))[0]:
            buf += os.read(fd, 4096)
    while select.select([fd], [], [], 0.2)[0]:  # nothing more may arrive
        chunk = os.read(fd, 4096)
        if not chunk:
            break
        buf += chunk
    return buf


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, int]]:
    master, slave = os.openpty()
    try:
        yield master, slave
    finally:
        for fd in (master, slave):
            try:
                os.close(fd)
            except OSError:
                pass


def test_writer_over_pty_via_pyserial_slave(pty_pair: tuple[int, int]) -> None:
    """The bench opens the pty slave like a GPS's serial device; the autopilot end reads the master."""
    master, slave = pty_pair
    ser = open_serial(os.ttyname(slave), 38400)
    try:
        writer = NmeaGpsWriter(ser, rate_hz=5.0, start_utc=UTC0)
        drive(writer)
        ser.flush()
        data = read_fd_until(master, 15)
    finally:
        ser.close()
    assert writer.sent == 15 and writer.errors == 0
    msgs = parse_all(split_lines(data))
    assert len(msgs) == 15 and [type(m).__name__ for m in msgs] == ["GGA", "RMC", "VTG"] * 5
    assert all(m.latitude == pytest.approx(47.0, abs=1e-4) for m in msgs if isinstance(m, pynmea2.GGA))


def test_writer_over_pty_master_read_with_pyserial(pty_pair: tuple[int, int]) -> None:
    """The bench writes the master; the other side reads the slave with pyserial, like an autopilot."""
    master, slave = pty_pair
    reader = serial.Serial(os.ttyname(slave), 9600, timeout=0.2)
    try:
        with os.fdopen(os.dup(master), "wb", buffering=0) as port:
            writer = NmeaGpsWriter(port, rate_hz=5.0, start_utc=UTC0)
            drive(writer)
        lines: list[bytes] = []
        deadline = time.monotonic() + 5.0
        while len(lines) < 16 and time.monotonic() < deadline:
            line = reader.readline()  # bounded by the 0.2 s timeout
            if not line and len(lines) >= 15:
                break
            if line:
                lines.append(line)
    finally:
        reader.close()
    assert writer.sent == 15 and writer.errors == 0
    msgs = parse_all([line.decode("ascii") for line in lines])
    assert len(msgs) == 15 and [type(m).__name__ for m in msgs] == ["GGA", "RMC", "VTG"] * 5


def test_loop_url_echoes_and_a_closed_port_is_counted() -> None:
    ser = open_serial("loop://", 115200, timeout=0.5)
    try:
        writer = NmeaGpsWriter(ser, rate_hz=5.0, start_utc=UTC0)
        written = drive(writer)
        data = ser.read(sum(written))
        assert len(data) == sum(written) and ser.in_waiting == 0
        msgs = parse_all(split_lines(data))
        assert len(msgs) == 15
    finally:
        ser.close()
    assert writer.poll(1.0) == 0  # the port went away: counted, not raised
    assert writer.errors == 1 and isinstance(writer.last_error, serial.SerialException)
    assert isinstance(writer.last_error, OSError) and writer.sent == 15

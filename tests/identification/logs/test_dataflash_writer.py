"""DataFlash .bin writer: round trips through pymavlink's DFReader and the project's read_log, time order,
definition and value errors, truncated files."""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink import DFReader

from identification.logs.dataflash_writer import (
    ATT,
    CTUN,
    FIRST_TYPE_ID,
    FMT_TYPE_ID,
    GPS,
    IMU,
    LAST_TYPE_ID,
    RCOU,
    STANDARD_LAYOUTS,
    DataFlashFormatError,
    DataFlashWriter,
    MessageLayout,
    define_standard,
    write_log,
)
from identification.logs.readers import read_log

DEG = math.pi / 180.0


def read_all(path: Path) -> list[Any]:
    """Every message of ``path`` as pymavlink's DFReader_binary parses it, in file order."""
    reader = DFReader.DFReader_binary(str(path))
    out = []
    while (msg := reader.recv_msg()) is not None:
        out.append(msg)
    return out


def f32(x: float) -> float:
    return float(np.float32(x))


def test_fmt_definitions_are_what_dfreader_parses(tmp_path: Path) -> None:
    path = tmp_path / "fmt.bin"
    with DataFlashWriter(path) as w:
        define_standard(w)
        w.define("XYZ", "QbhiIdnNZ", "TimeUS,A,B,C,D,E,F,G,H")
        assert [w.type_id(n) for n in w.layouts] == list(range(FIRST_TYPE_ID, FIRST_TYPE_ID + len(w.layouts)))
    raw = path.read_bytes()
    # the FMT of FMT comes first: header, Type 128, Length 89, "FMT"
    assert raw[:6] == bytes((0xA3, 0x95, FMT_TYPE_ID, FMT_TYPE_ID, 89)) + b"F"
    reader = DFReader.DFReader_binary(str(path))
    by_name = {f.name: f for f in reader.formats.values()}
    assert by_name["FMT"].type == FMT_TYPE_ID
    expected = {**STANDARD_LAYOUTS, "XYZ": MessageLayout("XYZ", "QbhiIdnNZ", ("TimeUS", *"ABCDEFGH"))}
    for name, layout in expected.items():
        fmt = by_name[name]
        assert (fmt.format, fmt.columns) == (layout.fmt, list(layout.columns)), name
        assert fmt.len == 3 + struct.calcsize(fmt.msg_struct), name
    assert by_name["XYZ"].len == 3 + 8 + 1 + 2 + 4 + 4 + 8 + 4 + 16 + 64
    assert by_name["IMU"].len == 3 + 8 + 1 + 6 * 4
    assert len(raw) == 89 * (1 + len(expected))  # nothing but FMTs, 89 bytes each


def test_every_format_character_round_trips_through_dfreader(tmp_path: Path) -> None:
    path = tmp_path / "all.bin"
    vals: dict[str, Any] = {
        "TimeUS": 2**64 - 1,
        "Q2": -(2**63),
        "b": -128,
        "B": 255,
        "h": -32768,
        "H": 65535,
        "i": -(2**31),
        "I": 2**32 - 1,
        "f": 0.1,
        "d": 0.1,
        "g": 0.333,
        "n": "ABCD",
        "N": "SERVO1_FUNCTION",
        "Z": "z" * 64,
        "c": -123.456,
        "C": 655.35,
        "e": -21474836.47,
        "E": 42949672.95,
        "L": -122.0841234567,
        "M": 5,
        "a": [1, -2, 3],
    }
    with DataFlashWriter(path) as w:
        w.define("INT", "QqbBhHiIfdg", "TimeUS,Q2,b,B,h,H,i,I,f,d,g")
        w.define("SCA", "QnNZcCeELMa", "TimeUS,n,N,Z,c,C,e,E,L,M,a")
        for name, layout in w.layouts.items():
            w.write(name, **{k: v for k, v in vals.items() if k in layout.columns})
    msgs = {m.get_type(): m for m in read_all(path)}
    assert msgs["INT"].TimeUS == msgs["SCA"].TimeUS == vals["TimeUS"]
    msg = type("Both", (), {**msgs["INT"].to_dict(), **msgs["SCA"].to_dict()})
    for k in ("TimeUS", "Q2", "b", "B", "h", "H", "i", "I", "M", "n", "N", "Z", "d"):
        assert getattr(msg, k) == vals[k], k
    assert msg.f == f32(0.1) and msg.f != 0.1  # float32, not float64
    assert msg.g == float(np.float16(0.333))
    assert msg.c == pytest.approx(-123.46, abs=1e-9)  # stored as round(value * 100)
    assert msg.C == pytest.approx(655.35, abs=1e-9)
    assert msg.e == pytest.approx(-21474836.47, abs=1e-6)
    assert msg.E == pytest.approx(42949672.95, abs=1e-6)
    assert msg.L == pytest.approx(-122.0841235, abs=1e-12)  # degE7
    assert list(msg.a) == [1, -2, 3] + [0] * 29


@settings(max_examples=40, deadline=None)
@given(
    c=st.lists(st.floats(-327.68, 327.67), min_size=1, max_size=20),
    e=st.floats(-2e7, 2e7),
    lat=st.floats(-90.0, 90.0),
    lon=st.floats(-180.0, 180.0),
)
def test_scaled_columns_round_trip_within_half_a_step(
    tmp_path_factory: pytest.TempPathFactory, c: list[float], e: float, lat: float, lon: float
) -> None:
    path = tmp_path_factory.mktemp("scaled") / "s.bin"
    with DataFlashWriter(path) as w:
        w.define("SCL", "QceLL", "TimeUS,C,E,Lat,Lng")
        for k, cv in enumerate(c):
            w.write("SCL", TimeUS=k, C=cv, E=e, Lat=lat, Lng=lon)
    msgs = [m for m in read_all(path) if m.get_type() == "SCL"]
    assert [m.TimeUS for m in msgs] == list(range(len(c)))
    for m, cv in zip(msgs, c, strict=True):
        assert abs(m.C - cv) <= 0.005 + 1e-9
        assert abs(m.E - e) <= 0.005 + 1e-6
        assert abs(m.Lat - lat) <= 0.5e-7 + 1e-12
        assert abs(m.Lng - lon) <= 0.5e-7 + 1e-12


def test_standard_messages_round_trip_through_dfreader(tmp_path: Path) -> None:
    path = tmp_path / "std.bin"
    with DataFlashWriter(path) as w:  # standard layouts are defined on first write
        w.param(0, "SERVO1_FUNCTION", 33)
        w.write("IMU", TimeUS=1000, I=1, GyrX=0.01, GyrY=-0.02, GyrZ=0.03, AccX=0.1, AccY=-0.2, AccZ=-9.81)
        w.write("ATT", TimeUS=2000, DesRoll=1.0, Roll=1.5, DesPitch=-2.0, Pitch=-2.5, DesYaw=359.0, Yaw=358.5)
        w.write("RCOU", TimeUS=3000, C1=1100, C4=1900, C14=2000)
        w.write(
            "GPS",
            TimeUS=4000,
            Status=3,
            GMS=123456789,
            GWk=2300,
            NSats=14,
            HDop=0.7,
            Lat=47.3977419,
            Lng=8.5455938,
            Alt=488.12,
            Spd=12.5,
            GCrs=271.0,
            VZ=-0.4,
            Yaw=0.0,
            U=1,
        )
        w.write("CTUN", TimeUS=5000, ThO=0.45, DAlt=10.0, Alt=9.87, BAlt=9.91, DCRt=50, CRt=-73)
        w.write("ARSP", TimeUS=6000, Airspeed=17.5, DiffPress=187.6, Temp=-12.34, H=1)
        w.write("BARO", TimeUS=7000, Alt=9.9, Press=101325.0, Temp=25.0)
        w.write("EV", TimeUS=8000, Id=10)
        assert list(w.layouts) == ["PARM", "IMU", "ATT", "RCOU", "GPS", "CTUN", "ARSP", "BARO", "EV"]
    msgs = {m.get_type(): m for m in read_all(path)}
    assert (msgs["PARM"].Name, msgs["PARM"].Value) == ("SERVO1_FUNCTION", 33.0)
    imu = msgs["IMU"]
    assert (imu.TimeUS, imu.I, imu.AccZ, imu.GyrY) == (1000, 1, f32(-9.81), f32(-0.02))
    assert (msgs["ATT"].Roll, msgs["ATT"].Yaw) == (1.5, 358.5)
    rcou = msgs["RCOU"]
    assert [getattr(rcou, f"C{n}") for n in range(1, 15)] == [1100, 0, 0, 1900] + [0] * 9 + [2000]
    gps = msgs["GPS"]
    assert (gps.Status, gps.GMS, gps.GWk, gps.NSats, gps.U) == (3, 123456789, 2300, 14, 1)
    assert gps.Lat == pytest.approx(47.3977419, abs=1e-12) and gps.Lng == pytest.approx(8.5455938, abs=1e-12)
    assert gps.Alt == pytest.approx(488.12, abs=1e-9) and gps.HDop == pytest.approx(0.7, abs=1e-9)
    ctun = msgs["CTUN"]
    assert (ctun.Alt, ctun.BAlt, ctun.CRt, ctun.DCRt, ctun.ThI) == (f32(9.87), pytest.approx(9.91), -73, 50, 0.0)
    arsp = msgs["ARSP"]
    assert (arsp.Airspeed, arsp.Temp, arsp.H) == (17.5, pytest.approx(-12.34), 1)
    assert (msgs["BARO"].Press, msgs["EV"].Id) == (101325.0, 10)


def quad_streams(t0: float = 0.5, duration: float = 10.0) -> tuple[dict, dict[str, float]]:
    """A synthetic quadrotor flight: IMU 100 Hz, ATT 50 Hz, RCOU 25 Hz, CTUN 10 Hz, GPS 5 Hz, EV arm/disarm."""
    t_imu = t0 + np.arange(0.0, duration, 0.01)
    t_att = t0 + np.arange(0.0, duration, 0.02)
    t_rc = t0 + np.arange(0.0, duration, 0.04)
    t_ct = t0 + np.arange(0.0, duration, 0.1)
    t_gps = t0 + np.arange(0.0, duration, 0.2)
    pwm = {f"C{n}": np.round(1500 + 100 * n + 50 * np.sin(t_rc + n)) for n in range(1, 5)}
    streams = {
        "IMU": (t_imu, {"AccZ": -9.81 + 0.5 * np.sin(t_imu), "GyrX": 0.1 * np.cos(t_imu), "I": 0}),
        "ATT": (t_att, {"Roll": 20.0 * np.sin(t_att), "Pitch": -5.0 + 0 * t_att, "Yaw": 90.0 + 0 * t_att}),
        "RCOU": (t_rc, pwm),
        "CTUN": (t_ct, {"Alt": 2.0 * t_ct, "CRt": np.round(200 * np.cos(t_ct)), "DAlt": 2.0 * t_ct}),
        "GPS": (
            t_gps,
            {"Lat": 47.3977419 + 1e-5 * t_gps, "Lng": 8.5455938 - 2e-5 * t_gps, "Alt": 488.0 + t_gps, "Status": 3},
        ),
        "EV": (t0 + np.array([1.0, 9.0]), {"Id": [10, 11]}),
    }
    # outputs 3 and 4 drive motors 4 and 3: read_log must follow SERVOn_FUNCTION, not the output number
    params = {"SERVO1_FUNCTION": 33, "SERVO2_FUNCTION": 34, "SERVO3_FUNCTION": 36, "SERVO4_FUNCTION": 35}
    return streams, {**params, "ATC_RAT_RLL_P": 0.135}


def test_read_log_gives_canonical_signals(tmp_path: Path) -> None:
    streams, params = quad_streams(t0=0.5)
    path = write_log(tmp_path / "quad.bin", streams, params)
    log = read_log(path)
    assert log.warnings == [] and log.fmt == "dataflash" and log.vehicle == "quadrotor"
    assert log.params == pytest.approx(params)
    t_imu, imu = streams["IMU"]
    acc = log.signal("accel_body_z_m_s2")
    np.testing.assert_allclose(acc.t_s, t_imu - 0.5, atol=1e-6)  # read_log starts time at the first message
    np.testing.assert_allclose(acc.values, imu["AccZ"], rtol=1e-6)
    np.testing.assert_allclose(log.signal("gyro_body_x_rad_s").values, imu["GyrX"], rtol=1e-6, atol=1e-9)
    t_att, att = streams["ATT"]
    np.testing.assert_allclose(log.signal("roll_rad").values, att["Roll"] * DEG, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(log.signal("yaw_rad").values, np.pi / 2, rtol=1e-6)
    np.testing.assert_allclose(log.signal("roll_rad").t_s, t_att - 0.5, atol=1e-6)
    _, pwm = streams["RCOU"]
    for n in range(1, 5):
        np.testing.assert_array_equal(log.signal(f"servo_{n}_pwm_us").values, pwm[f"C{n}"])
    for motor, output in ((1, 1), (2, 2), (3, 4), (4, 3)):
        np.testing.assert_array_equal(log.signal(f"motor_{motor}_pwm_us").values, pwm[f"C{output}"])
    _, ctun = streams["CTUN"]
    np.testing.assert_allclose(log.signal("altitude_m").values, ctun["Alt"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(log.signal("climb_rate_m_s").values, ctun["CRt"] / 100.0)  # stored in cm/s
    _, gps = streams["GPS"]
    np.testing.assert_allclose(log.signal("lat_deg").values, gps["Lat"], rtol=0, atol=0.6e-7)
    np.testing.assert_allclose(log.signal("lon_deg").values, gps["Lng"], rtol=0, atol=0.6e-7)
    np.testing.assert_allclose(log.signal("height_m").values, gps["Alt"], rtol=0, atol=0.006)
    armed = log.signal("armed")
    assert armed.values.tolist() == [0.0, 1.0, 0.0]
    np.testing.assert_allclose(armed.t_s, [0.0, 1.0, 9.0], atol=1e-6)


def test_write_log_interleaves_messages_in_time_order(tmp_path: Path) -> None:
    streams, params = quad_streams(t0=0.0, duration=3.0)
    # a stream given out of order is written sorted
    t_baro = np.array([2.0, 0.0, 1.0, 0.04])
    streams["BARO"] = (t_baro, {"Alt": t_baro * 10})
    path = write_log(tmp_path / "order.bin", streams, params)
    msgs = read_all(path)
    kinds = [m.get_type() for m in msgs]
    n_fmt = 1 + len(streams) + 1  # FMT of FMT, one per stream, PARM
    assert kinds[:n_fmt] == ["FMT"] * n_fmt
    assert kinds[n_fmt : n_fmt + len(params)] == ["PARM"] * len(params)
    assert all(m.TimeUS == 0 for m in msgs[n_fmt : n_fmt + len(params)])
    data = msgs[n_fmt + len(params) :]
    times = [m.TimeUS for m in data]
    assert times == sorted(times)
    for name, (t, _) in streams.items():
        got = [m.TimeUS for m in data if m.get_type() == name]
        assert got == sorted(round(x * 1e6) for x in t), name
    assert [m.Alt for m in data if m.get_type() == "BARO"] == [0.0, f32(0.4), 10.0, 20.0]
    # equal times keep the order of ``streams``: at t = 0 IMU, ATT, RCOU, CTUN, GPS, BARO
    assert [m.get_type() for m in data if m.TimeUS == 0] == ["IMU", "ATT", "RCOU", "CTUN", "GPS", "BARO"]
    assert len(data) == sum(len(t) for t, _ in streams.values())


@pytest.mark.parametrize(
    ("name", "fmt", "columns", "needles"),
    [
        ("TOOLONG", "Qf", "TimeUS,X", ("'TOOLONG'", "'name'", "at most 4")),
        ("LONG", "Q" * 17, ",".join(f"A{k}" for k in range(17)), ("'LONG'", "'format'", "'" + "Q" * 17 + "'")),
        ("BAD", "Qx", "TimeUS,Foo", ("'BAD'", "'Foo'", "'x'")),
        ("CNT", "Qff", "TimeUS,X", ("'CNT'", "'columns'", "'TimeUS,X'", "'Qff'")),
        ("DUP", "Qff", "TimeUS,X,X", ("'DUP'", "'X'", "twice")),
        ("WIDE", "Qff", "TimeUS," + "A" * 30 + "," + "B" * 30, ("'WIDE'", "'columns'", "at most 64")),
    ],
)
def test_bad_definitions_raise_naming_message_field_and_value(
    tmp_path: Path, name: str, fmt: str, columns: str, needles: tuple[str, ...]
) -> None:
    path = tmp_path / "bad.bin"
    with DataFlashWriter(path) as w:
        with pytest.raises(DataFlashFormatError) as err:
            w.define(name, fmt, columns)
        assert isinstance(err.value, ValueError)
        for needle in needles:
            assert needle in str(err.value), (needle, str(err.value))
        assert w.layouts == {}
        w.write("EV", TimeUS=1, Id=10)
    assert [m.get_type() for m in read_all(path)] == ["FMT", "FMT", "EV"]  # nothing of the failed define


@pytest.mark.parametrize(
    ("message", "fields", "needles"),
    [
        ("GPS", {"TimeUS": 1, "Lat": 300.0}, ("'GPS'", "'Lat'", "300.0")),  # 3e9 does not fit int32
        ("RCOU", {"TimeUS": 1, "C3": -1}, ("'RCOU'", "'C3'", "-1")),
        ("RCOU", {"TimeUS": 1, "C2": float("nan")}, ("'RCOU'", "'C2'", "nan")),
        ("IMU", {"TimeUS": 1, "AccX": 1e39}, ("'IMU'", "'AccX'", "1e+39")),  # float32 overflow
        ("IMU", {"TimeUS": 1, "Foo": 2.0}, ("'IMU'", "'Foo'", "2.0")),
        ("IMU", {"TimeUS": 1, "AccX": "fast"}, ("'IMU'", "'AccX'", "'fast'")),
        ("PARM", {"TimeUS": 1, "Name": "A_VERY_LONG_PARAM_NAME"}, ("'PARM'", "'Name'", "'A_VERY_LONG_PARAM_NAME'")),
        ("NOPE", {"TimeUS": 1}, ("'NOPE'", "not defined")),
    ],
)
def test_bad_values_raise_and_write_nothing(
    tmp_path: Path, message: str, fields: dict[str, Any], needles: tuple[str, ...]
) -> None:
    path = tmp_path / "bad.bin"
    with DataFlashWriter(path) as w:
        with pytest.raises(DataFlashFormatError) as err:
            w.write(message, **fields)
        for needle in needles:
            assert needle in str(err.value), (needle, str(err.value))
        w.write("EV", TimeUS=2, Id=11)
    assert [m.get_type() for m in read_all(path) if m.get_type() != "FMT"] == ["EV"]


def test_redefinition_type_id_limit_and_closed_writer(tmp_path: Path) -> None:
    with DataFlashWriter(tmp_path / "ids.bin") as w:
        w.define("ABC", "Qf", "TimeUS,X")
        w.define("ABC", "Qf", ["TimeUS", "X"])  # same layout again: no-op
        with pytest.raises(DataFlashFormatError, match=r"'ABC'.*already defined"):
            w.define("ABC", "Qd", "TimeUS,X")
        for k in range(FIRST_TYPE_ID + 1, LAST_TYPE_ID + 1):
            w.define(f"M{k}", "Q", "TimeUS")
        assert w.type_id("ABC") == FIRST_TYPE_ID and w.type_id(f"M{LAST_TYPE_ID}") == LAST_TYPE_ID
        with pytest.raises(DataFlashFormatError, match=r"'LAST'.*no type id left"):
            w.define("LAST", "Q", "TimeUS")
    with pytest.raises(ValueError, match="closed"):
        w.write("ABC", TimeUS=1, X=1.0)
    assert len(read_all(tmp_path / "ids.bin")) == 1 + LAST_TYPE_ID - FIRST_TYPE_ID + 1


def test_write_log_rejects_bad_streams_and_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "w.bin"
    t = np.arange(5) * 0.1
    cases = [
        ({"IMU": (t, {"AccZ": np.zeros(4)})}, ("'IMU'", "'AccZ'", "4 values")),
        ({"IMU": (t, {"Acc": np.zeros(5)})}, ("'IMU'", "'Acc'", "not a column")),
        ({"IMU": (t - 1.0, {"AccZ": np.zeros(5)})}, ("'IMU'", "'t_s'", "-1.0")),
        ({"XYZ": (t, {"A": t})}, ("'XYZ'", "not a standard layout")),
        ({"RCOU": (t, {"C1": [1500, 1500, 70000, 1500, 1500]})}, ("'RCOU'", "'C1'", "70000")),
    ]
    for streams, needles in cases:
        with pytest.raises(DataFlashFormatError) as err:
            write_log(path, streams)
        for needle in needles:
            assert needle in str(err.value), (needle, str(err.value))
        assert not path.exists()
    # a custom message goes through ``layouts``
    xyz = MessageLayout("XYZ", "Qh", ("TimeUS", "A"))
    write_log(path, {"XYZ": (t, {"A": [1, 2, 3, 4, 5]})}, layouts=[xyz])
    assert [m.A for m in read_all(path) if m.get_type() == "XYZ"] == [1, 2, 3, 4, 5]


def _cut_log(tmp_path: Path) -> tuple[Path, bytes, int, dict]:
    """A written log cut in the middle of its last-but-ten IMU message: (cut file, full bytes, offset of the cut
    message, {message: number of messages before the cut})."""
    streams, params = quad_streams(t0=0.0, duration=5.0)
    full = write_log(tmp_path / "full.bin", streams, params)
    raw = full.read_bytes()
    reader = DFReader.DFReader_binary(str(full))
    imu_type = reader.name_to_id["IMU"]
    cut_at = reader.offsets[imu_type][-10] + IMU.length // 2
    intact = {
        name: sum(
            ofs + reader.formats[reader.name_to_id[name]].len <= cut_at
            for ofs in reader.offsets[reader.name_to_id[name]]
        )
        for name in streams
    }
    cut = tmp_path / "cut.bin"
    cut.write_bytes(raw[:cut_at])
    return cut, raw, reader.offsets[imu_type][-10], intact


def test_truncated_file_reads_back_the_intact_part(tmp_path: Path) -> None:
    cut, _, _, intact = _cut_log(tmp_path)
    assert intact["IMU"] == 500 - 10 and intact["GPS"] == 25 and 0 < intact["RCOU"] < 125
    log = read_log(cut)
    for name, n in intact.items():
        assert len(log.signals[f"{name}.TimeUS"].t_s) == n, name
    streams, _ = quad_streams(t0=0.0, duration=5.0)
    np.testing.assert_allclose(
        log.signal("accel_body_z_m_s2").values, streams["IMU"][1]["AccZ"][: intact["IMU"]], rtol=1e-6
    )
    assert log.signal("motor_3_pwm_us").values.tolist() == streams["RCOU"][1]["C4"][: intact["RCOU"]].tolist()


def test_truncated_file_followed_by_junk_warns(tmp_path: Path) -> None:
    cut, raw, last_ofs, intact = _cut_log(tmp_path)
    # cut between two messages and followed by junk, e.g. a flash page not erased after a power cut. (Junk right
    # after a half message would complete it into one bogus sample: DataFlash messages carry no checksum.)
    cut.write_bytes(raw[:last_ofs] + bytes(range(256)) * 8)
    log = read_log(cut)
    assert len(log.signal("accel_body_z_m_s2").t_s) == intact["IMU"]
    assert any("could not be parsed" in w for w in log.warnings), log.warnings


def test_truncated_file_warns(tmp_path: Path) -> None:
    cut, _, _, _ = _cut_log(tmp_path)
    assert read_log(cut).warnings != []


def test_layout_constants_match_the_brief() -> None:
    assert (ATT.fmt, ATT.units[2]) == ("Qffffff", "deg")
    assert RCOU.columns[-1] == "C14" and len(RCOU.columns) == 15
    assert GPS.fmt == "QBBIHBcLLeffffB" and GPS.length == 3 + 48
    assert {"Alt", "CRt"} <= set(CTUN.columns) and CTUN.units[CTUN.columns.index("CRt")] == "cm/s"

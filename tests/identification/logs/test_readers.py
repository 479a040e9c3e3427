"""DataFlash reader: canonical signals from the shared logs, bad files give clear errors, damaged tails."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from identification.logs.flightlog import DataQuality, FlightLog, LogError, MissingSignalError, check_quality
from identification.logs.readers import read_log
from tests.conftest import shared_data


def test_old_format_copter_log_canonical_signals() -> None:
    log = read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"))
    assert log.vehicle == "quadrotor" and log.warnings == []
    assert log.duration_s == pytest.approx(335.0, abs=1.0)  # data README: 335 s
    acc = log.signal("accel_body_z_m_s2").values
    assert np.mean(acc) == pytest.approx(-9.99, abs=0.05)  # data README: AccZ averages about -9.99
    assert log.signals["BARO.Alt"].values.max() == pytest.approx(14.6, abs=0.1)  # data README: up to 14.6 m
    assert 10.0 < log.signal("altitude_m").values.max() < 15.0  # CTUN.Alt, the autopilot's altitude
    for k in range(1, 5):
        assert log.signal(f"motor_{k}_pwm_us").unit == "us"
    assert "FRAME" in log.params
    assert log.signal("lat_deg").t_s[0] < 335.0  # GPS time of week is not mistaken for boot time


def test_plane_log_maps_surfaces_from_servo_functions() -> None:
    log = read_log(shared_data("fixed_wing", "arduplane_sitl_takeoff_00000012.BIN"))
    assert log.vehicle == "fixed_wing"
    for name in ("aileron_pwm_us", "elevator_pwm_us", "throttle_pwm_us", "rudder_pwm_us", "airspeed_m_s"):
        assert log.has(name), name
    assert log.duration_s == pytest.approx(44.0, abs=3.0)


def test_truncated_log_returns_the_intact_part_with_a_warning(tmp_path: Path) -> None:
    src = shared_data("quadrotor", "arducopter_x_quad_real_218.BIN").read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(src[: len(src) // 2] + bytes(range(256)) * 20)
    log = read_log(cut)
    assert 100.0 < log.duration_s < 300.0
    assert any("could not be parsed" in w or "damaged" in w for w in log.warnings), log.warnings


def test_empty_missing_and_garbage_files_are_clear_errors(tmp_path: Path) -> None:
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    with pytest.raises(LogError, match="empty"):
        read_log(empty)
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "nope.bin")
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8)))
    with pytest.raises(LogError, match=r"junk\.bin"):
        read_log(junk)
    with pytest.raises(LogError, match="unsupported log format"):
        read_log(tmp_path.joinpath("x.xyz").resolve() if (tmp_path / "x.xyz").write_text("a") else None)


def test_missing_signal_names_file_and_what_is_there() -> None:
    log = read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"))
    with pytest.raises(MissingSignalError) as err:
        log.signal("airspeed_m_s")
    assert "arducopter_x_quad_real_218.BIN" in str(err.value) and "accel_body_z_m_s2" in str(err.value)


def test_px4_ulog_canonical_signals() -> None:
    log = read_log(shared_data("quadrotor", "px4_sitl_quad_takeoff.ulg"))
    assert log.vehicle == "quadrotor" and log.duration_s == pytest.approx(31.0, abs=1.0)
    pwm = log.signal("motor_1_pwm_us").values
    assert 850 <= pwm.min() and pwm.max() <= 1560  # data README: PWM 900-1556
    assert log.signal("altitude_m").values.max() == pytest.approx(2.0, abs=0.5)  # takeoff to ~2 m
    assert np.mean(log.signal("accel_body_z_m_s2").values) == pytest.approx(-9.8, abs=0.2)
    assert log.signal("armed").values.max() == 1.0
    # velocity from the estimator (vehicle_local_position, NED, the altitude's source), not the receiver's
    vel = log.signal("vel_down_m_s")
    assert vel.t_s.size == log.signal("vehicle_local_position.vz").t_s.size != log.signal(
        "vehicle_gps_position.vel_d_m_s").t_s.size
    np.testing.assert_array_equal(vel.values, -log.signal("climb_rate_m_s").values)


def test_csv_with_column_map_and_truncated_last_line(tmp_path: Path) -> None:
    f = tmp_path / "flight.csv"
    f.write_text("time_s,az,pwm1\n0.0,-9.8,1500\n0.1,-9.7,1510\n0.2,-9.")
    log = read_log(f, channel_map={"accel_body_z_m_s2": "az", "motor_1_pwm_us": "pwm1"})
    np.testing.assert_array_equal(log.signal("accel_body_z_m_s2").values, [-9.8, -9.7])
    assert log.signal("motor_1_pwm_us").t_s.tolist() == [0.0, 0.1]
    assert "1 incomplete line(s) at the end were dropped" in log.warnings[0]
    with pytest.raises(LogError, match="mapped column"):
        read_log(f, channel_map={"airspeed_m_s": "ias"})


def test_corrupt_ulog_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"not a ulog at all" * 10)
    with pytest.raises(LogError, match=r"bad\.ulg"):
        read_log(bad)


def test_channel_map_file_overrides_the_log_mapping(tmp_path: Path) -> None:
    cfg = tmp_path / "map.toml"
    cfg.write_text("[channels]\nmotor_1_pwm_us = 3\n")
    log = read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"), channel_map=cfg)
    np.testing.assert_array_equal(log.signal("motor_1_pwm_us").values, log.signal("servo_3_pwm_us").values)
    cfg.write_text("[channels]\nmotor_1_pwm_us = 99\n")
    with pytest.raises(LogError, match=r"channels\.motor_1_pwm_us = 99"):
        read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"), channel_map=cfg)


def test_tlog_round_trip_written_with_pymavlink(tmp_path: Path) -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mav

    f = tmp_path / "flight.tlog"
    link = mav.MAVLink(None, srcSystem=1)
    with f.open("wb") as fh:
        for k in range(5):
            t_us = int((1_700_000_000 + 0.1 * k) * 1e6)
            for msg in (mav.MAVLink_attitude_message(100 * k, 0.1 * k, 0.0, 0.0, 0.0, 0.0, 0.0),
                        mav.MAVLink_servo_output_raw_message(100 * k, 0, 1500 + k, 1500, 1500, 1500, 0, 0, 0, 0),
                        mav.MAVLink_heartbeat_message(2, 3, 128, 0, 4, 3)):
                fh.write(t_us.to_bytes(8, "big") + msg.pack(link))
    log = read_log(f)
    np.testing.assert_allclose(log.signal("roll_rad").values, [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-6)
    np.testing.assert_array_equal(log.signal("servo_1_pwm_us").values, [1500, 1501, 1502, 1503, 1504])
    assert log.signal("armed").values.min() == 1.0


def test_identify_thrust_reports_a_corrupt_log_without_traceback(tmp_path: Path, capsys) -> None:
    from uavfmu.cli import main

    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\x00" * 100)
    rc = main(["identify", "thrust", str(bad), "--mass", "1.14", "--out", str(tmp_path / "p.json")])
    err = capsys.readouterr().err
    assert rc != 0 and "bad.bin" in err and "Traceback" not in err


def test_text_dataflash_log(tmp_path: Path) -> None:
    f = tmp_path / "flight.log"
    f.write_text(
        "FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns\n"
        "FMT, 129, 31, IMU, Qffffff, TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ\n"
        "FMT, 130, 40, PARM, QNf, TimeUS,Name,Value\n"
        "PARM, 1000, FRAME, 1\n"
        "IMU, 1000000, 0.01, 0.02, 0.03, 0.1, 0.2, -9.8\n"
        "IMU, 1020000, 0.01, 0.02, 0.03, 0.1, 0.2, -9.7\n"
    )
    log = read_log(f)
    np.testing.assert_allclose(log.signal("accel_body_z_m_s2").values, [-9.8, -9.7])
    np.testing.assert_allclose(log.signal("accel_body_z_m_s2").t_s, [0.0, 0.02])
    assert log.params == {"FRAME": 1.0} and log.fmt == "dataflash"


def test_battery_from_new_bat_and_old_curr_dataflash(tmp_path: Path) -> None:
    from identification.logs.dataflash_writer import MessageLayout, write_log

    t = np.arange(5) * 0.5
    bat = MessageLayout("BAT", "QBff", "TimeUS,Inst,Volt,Curr")
    new = write_log(tmp_path / "new.bin", {"BAT": (t, {"Inst": 0, "Volt": 12.0 - 0.1 * t, "Curr": 10.0})},
                    layouts=[bat])
    log = read_log(new)
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, 12.0 - 0.1 * t, rtol=1e-6)
    np.testing.assert_allclose(log.signal("battery_current_a").values, 10.0)
    assert log.signal("battery_voltage_v").unit == "V" and log.signal("battery_current_a").unit == "A"
    curr = MessageLayout("CURR", "Qhhh", "TimeUS,Volt,Curr,Vcc")  # old ArduCopter: cV, cA, mV
    old = write_log(tmp_path / "old.bin", {"CURR": (t, {"Volt": 1110, "Curr": 1550, "Vcc": 5000})},
                    layouts=[curr])
    log = read_log(old)
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, 11.1)
    np.testing.assert_allclose(log.signal("battery_current_a").values, 15.5)
    none = write_log(tmp_path / "none.bin", {"CURR": (t, {"Volt": 0, "Curr": 0, "Vcc": 0})}, layouts=[curr])
    assert not read_log(none).has("battery_voltage_v")  # no monitor fitted: 0 V is not a measurement


def test_battery_from_tlog_sys_status_and_battery_status(tmp_path: Path) -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mav

    link = mav.MAVLink(None, srcSystem=1)

    def write(name: str, msgs: list) -> Path:
        f = tmp_path / name
        with f.open("wb") as fh:
            for k, msg in enumerate(msgs):
                fh.write(int((1_700_000_000 + 0.1 * k) * 1e6).to_bytes(8, "big") + msg.pack(link))
        return f

    sys_status = [mav.MAVLink_sys_status_message(0, 0, 0, 500, v, c, 50, 0, 0, 0, 0, 0, 0)
                  for v, c in ((12600, 1234), (65535, -1), (12500, 1300))]
    log = read_log(write("sys.tlog", sys_status))
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, [12.6, 12.5])
    np.testing.assert_allclose(log.signal("battery_current_a").values, [12.34, 13.0])
    cells = [4100, 4100, 4000] + [65535] * 7
    batt = [mav.MAVLink_battery_status_message(0, 0, 0, 2500, cells, 800, 100, 200, 80)]
    log = read_log(write("batt.tlog", batt))
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, [12.2])
    np.testing.assert_allclose(log.signal("battery_current_a").values, [8.0])


def test_battery_from_ulog_and_csv(tmp_path: Path) -> None:
    log = read_log(shared_data("quadrotor", "px4_sitl_quad_takeoff.ulg"))
    v = log.signal("battery_voltage_v").values
    assert 15.0 < v.min() <= v.max() <= 16.8  # 4S SITL battery
    assert not log.has("battery_current_a")  # PX4 SITL logs current_a = -1 (unknown)
    f = tmp_path / "b.csv"
    f.write_text("time_s,vbat,ibat\n0.0,12.5,3.0\n0.1,0,3.1\n0.2,12.4,nan\n")
    log = read_log(f, channel_map={"battery_voltage_v": "vbat", "battery_current_a": "ibat"})
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, [12.5, 12.4])
    np.testing.assert_allclose(log.signal("battery_current_a").t_s, [0.0, 0.1])


def _flip(src: bytes, offset: int, bit: int) -> bytes:
    b = bytearray(src)
    b[offset] ^= 1 << bit
    return bytes(b)


# (2, 0) turns RCOU (type 134) into IMU2 (135, same length): structurally valid, so not detectable without a
# checksum; (3, 1) is a payload bit; the others break the header and must be skipped and reported.
@pytest.mark.parametrize("byte, bit, detectable", [(0, 0, True), (1, 5, True), (2, 7, True), (2, 3, True),
                                                   (2, 0, False), (3, 1, False)])
def test_one_flipped_bit_keeps_the_flight_and_says_what_was_lost(tmp_path: Path, byte: int, bit: int,
                                                                 detectable: bool) -> None:
    """One flipped bit 10 % into the Erle log once kept 33 of 335 s; now >= 95 % and the damage is named."""
    path = shared_data("quadrotor", "arducopter_x_quad_real_218.BIN")
    src = path.read_bytes()
    clean = read_log(path)
    assert clean.quality.ok and clean.quality.lines() == []
    header = src.find(b"\xa3\x95", len(src) // 10)  # sync bytes, type byte and first payload byte of a message
    bad = tmp_path / "flipped.BIN"
    bad.write_bytes(_flip(src, header + byte, bit))
    log = read_log(bad)
    q = log.quality
    assert q.time_kept_s >= 0.95 * clean.quality.time_kept_s
    assert log.duration_s == pytest.approx(clean.duration_s, abs=1.0)
    assert len(log.signal("accel_body_z_m_s2").t_s) >= 0.99 * len(clean.signal("accel_body_z_m_s2").t_s)
    if detectable:
        assert 0 < q.bytes_skipped < 200 and q.messages_skipped >= 1
        assert any("flipped.BIN" in line and "skipped" in line for line in q.lines())
        assert q.damage_fraction < 0.01


def test_time_jump_is_split_off_not_gridded(tmp_path: Path) -> None:
    """A +1e6 s time jump 80 % into a log: the far part is dropped and reported, the duration stays 8 s."""
    from identification.logs.dataflash_writer import write_log

    t = np.arange(1000) * 0.01
    t_jump = np.where(t >= 8.0, t + 1e6, t)
    f = write_log(tmp_path / "jump.bin", {"IMU": (t_jump, {"AccZ": -9.8, "GyrX": 0.1}),
                                         "ATT": (t_jump[::10], {"Roll": 1.0})})
    log = read_log(f)
    q = log.quality
    assert log.duration_s == pytest.approx(7.99, abs=0.02)
    assert q.jumps and q.jumps[0][1] == pytest.approx(1e6, rel=1e-3)
    assert q.samples_beyond_jumps == 200 + 20 and q.dropped_segments[0][0] == pytest.approx(1.99, abs=0.02)
    assert q.time_kept_s == pytest.approx(7.99, abs=0.02) and q.time_total_s == pytest.approx(7.99 + 1.99, abs=0.05)
    assert q.damage_fraction == pytest.approx(0.2, abs=0.01)
    assert any("time jump" in line and "jump.bin" in line for line in q.lines())


def test_single_corrupt_timestamps_and_backward_time_in_csv(tmp_path: Path) -> None:
    t = np.arange(200) * 0.1
    t_bad = t.copy()
    t_bad[50] = 5e7            # one corrupt stamp far away: a one-sample segment, dropped
    t_bad[100] = 3.0           # one corrupt stamp inside the log: an isolated outlier, dropped
    t_bad[[150, 151]] = t_bad[[151, 150]]  # two rows swapped: put back in order
    rows = "\n".join(f"{float(a)!r},{-9.8 + 0.001 * k!r}" for k, a in enumerate(t_bad))
    f = tmp_path / "t.csv"
    f.write_text("time_s,az\n" + rows + "\n")
    log = read_log(f, channel_map={"accel_body_z_m_s2": "az"})
    s, q = log.signal("accel_body_z_m_s2"), log.quality
    assert np.all(np.diff(s.t_s) > 0) and s.t_s.size == 198
    assert q.samples_beyond_jumps == 1 and q.time_outliers == 1 and q.backward_steps == 1
    assert q.samples_reordered == 2 and log.duration_s == pytest.approx(19.9)
    assert len(q.lines()) >= 3 and all("t.csv" in line for line in q.lines())


def test_gaps_non_finite_and_duplicates_are_counted(tmp_path: Path) -> None:
    t = np.r_[np.arange(100) * 0.1, 20.0 + np.arange(100) * 0.1]  # a 10.1 s pause without data
    vals = np.full(t.size, -9.8)
    vals[[3, 7]] = np.nan
    lines = [f"{float(a)!r},{float(v)!r}" for a, v in zip(t, vals, strict=True)]
    lines.insert(20, lines[19])  # a duplicated row
    f = tmp_path / "g.csv"
    f.write_text("time_s,az\n" + "\n".join(lines) + "\n")
    log = read_log(f, channel_map={"accel_body_z_m_s2": "az"})
    q = log.quality
    assert q.gap_count == 1 and q.gaps[0] == pytest.approx((9.9, 10.1))
    assert q.time_kept_s == pytest.approx(29.9 - 10.1) and q.time_total_s == pytest.approx(29.9)
    assert q.non_finite_samples == 2 and np.isfinite(log.signal("accel_body_z_m_s2").values).all()
    assert q.duplicate_samples == 1 and not q.ok


def test_check_quality_refuses_damaged_logs_unless_forced(tmp_path: Path) -> None:
    import json

    from identification.logs.flightlog import check_quality

    t = np.arange(100) * 0.1
    t[60:] += 1e6  # 40 % beyond a time jump
    f = tmp_path / "d.csv"
    f.write_text("time_s,az\n" + "\n".join(f"{float(a)!r},-9.8" for a in t) + "\n")
    log = read_log(f, channel_map={"accel_body_z_m_s2": "az"})
    with pytest.raises(LogError, match=r"d\.csv: 40\.0 % of the log is damaged.*--force"):
        check_quality(log, force=False, max_damage=0.05)
    check_quality(log, force=True)
    check_quality(log, max_damage=0.5)
    d = log.quality.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False))["samples_beyond_jumps"] == 40 and d["ok"] is False
    clean = read_log(f.with_name("c.csv") if f.with_name("c.csv").write_text("time_s,az\n0,1\n0.1,2\n") else f)
    assert clean.quality.ok and clean.quality.damage_fraction == 0.0 and clean.quality.lines() == []
    check_quality(clean)


def test_channel_map_schema_errors_name_file_field_value_and_range(tmp_path: Path) -> None:
    from fmu_models.config import ConfigError

    cfg = tmp_path / "map.toml"
    cfg.write_text("[channels]\nmotor_1_pwm_us = true\nmotor_2_pwm_us = 0\nmotor_3_pwm_us = 2.5\n")
    with pytest.raises(ConfigError) as err:
        read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"), channel_map=cfg)
    text = str(err.value)
    assert isinstance(err.value, LogError) and "map.toml" in text and len(err.value.problems) == 3
    assert "channels.motor_1_pwm_us = True" in text and "channels.motor_2_pwm_us = 0" in text
    assert "allowed: 1..32" in text and "channels.motor_3_pwm_us = 2.5" in text
    cfg.write_text("[channels]\nmotor_1_pwm_us = 'C3'\n")
    with pytest.raises(LogError, match="name CSV columns"):
        read_log(shared_data("quadrotor", "arducopter_x_quad_real_218.BIN"), channel_map=cfg)
    with pytest.raises(ConfigError, match=r"(?s)channel_map argument.*channels\.x = -1"):
        read_log(tmp_path / "nope.csv", channel_map={"x": -1})


def test_standard_bat_layout_gives_battery_signals(tmp_path: Path) -> None:
    from identification.logs.dataflash_writer import write_log

    t = np.arange(10) * 0.1
    f = write_log(tmp_path / "bat.bin", {"BAT": (t, {"Inst": 0, "Volt": 16.0 - t, "Curr": 20.0 + t, "Temp": 25.0})})
    log = read_log(f)
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, 16.0 - t, rtol=1e-6)
    np.testing.assert_allclose(log.signal("battery_current_a").values, 20.0 + t, rtol=1e-6)
    np.testing.assert_allclose(log.signals["BAT.Temp"].values, 25.0)


# ------------------------------------------------------------------ refusing a damaged log
def _damaged(bytes_skipped: int) -> FlightLog:
    q = DataQuality("f.bin", bytes_total=1000, bytes_skipped=bytes_skipped, messages_total=100,
                    messages_skipped=1, damaged_regions=[(40, bytes_skipped)], jumps=[(12.0, 3600.0)],
                    samples_beyond_jumps=7, dropped_segments=[(2.0, 7)], duplicate_samples=3, gap_count=1,
                    gaps=[(5.0, 0.8)], gap_total_s=0.8, time_total_s=10.0, time_kept_s=10.0)
    return FlightLog("f.bin", "dataflash", {}, {}, quality=q)


def test_check_quality_refuses_above_the_limit_and_says_what_was_lost() -> None:
    check_quality(_damaged(50))  # exactly the 5 % limit: kept
    check_quality(_damaged(300), force=True)  # --force: the caller takes what is left
    check_quality(_damaged(300), max_damage=0.3)
    with pytest.raises(LogError) as err:
        check_quality(_damaged(60))
    msg = str(err.value)
    assert msg.startswith("f.bin: 6.0 % of the log is damaged or lost (limit 5.0 %): 60 of 1000 bytes could not be")
    # the first three findings without their file prefix, the jump's own ": " kept
    assert "time jump(s) +3.6e+03 s at t=12.0 s: the log was split there and 2.0 s (7 samples)" in msg
    assert "; 3 duplicated sample(s) dropped. Repair or re-download the log, or pass --force to use what is left" \
        in msg
    assert "gap(s)" not in msg and msg.count("f.bin") == 1
    with pytest.raises(LogError, match=r"\(limit 2\.0 %\)"):
        check_quality(_damaged(50), max_damage=0.02)


def test_missing_signal_error_reads_plainly() -> None:
    assert str(MissingSignalError("f.bin: no airspeed_m_s")) == "f.bin: no airspeed_m_s"  # not KeyError's quotes


def test_quality_report_lines_and_json_by_hand() -> None:
    """Every finding in words with its numbers, and the JSON summary a metrics file carries."""
    q = DataQuality("f.bin", bytes_total=1000, bytes_skipped=60, messages_total=100, messages_skipped=2,
                    damaged_regions=[(40, 50), (900, 10)], samples_total=500, jumps=[(12.0, 3600.0)],
                    samples_beyond_jumps=7, dropped_segments=[(2.0, 7)], backward_steps=2, samples_reordered=3,
                    samples_backward_dropped=1, time_outliers=4, duplicate_samples=3, non_finite_times=1,
                    gap_count=2, gaps=[(5.0, 0.8), (9.0, 1.2)], gap_total_s=2.0, non_finite_samples=5,
                    canonical_samples=1000, clipped_samples=6, time_total_s=20.0, time_kept_s=18.0)
    # lost shares: bytes 0.06, messages 0.02, samples (7 + 1 + 4 + 1) / 500, values 0.005, time 1 - 18/20
    assert q.samples_dropped == 13 and q.damage_fraction == pytest.approx(0.1) and not q.ok
    lines = [
        "f.bin: 60 of 1000 bytes could not be decoded and were skipped (2 damaged message(s) in 2 region(s); "
        "first at byte 40)",
        "f.bin: time jump(s) +3.6e+03 s at t=12.0 s: the log was split there and 2.0 s (7 samples) beyond the "
        "jump(s) dropped",
        "f.bin: 5 sample(s) with implausible or non-finite time stamps dropped",
        "f.bin: time went backwards 2 time(s): 3 sample(s) put back in order, 1 dropped (beyond the tolerance)",
        "f.bin: 3 duplicated sample(s) dropped",
        "f.bin: 2 gap(s) without data, 2.00 s in all (longest 1.20 s at t=9.0 s)",
        "f.bin: 5 non-finite (NaN/inf) value(s) removed from canonical signals",
        "f.bin: 6 clipped sensor sample(s) (at full scale)",
        "f.bin: kept 18.0 of 20.0 s of log; damage 10.0 %",
    ]
    assert q.lines() == lines
    assert q.to_dict() == {
        "source": "f.bin", "ok": False, "damage_fraction": pytest.approx(0.1), "bytes_total": 1000,
        "bytes_skipped": 60, "damaged_regions": [[40, 50], [900, 10]], "messages_total": 100, "messages_skipped": 2,
        "samples_total": 500, "samples_dropped": 13, "gap_count": 2, "gap_total_s": 2.0,
        "gaps": [[5.0, 0.8], [9.0, 1.2]], "jumps": [[12.0, 3600.0]], "dropped_segments": [[2.0, 7]],
        "samples_beyond_jumps": 7, "backward_steps": 2, "samples_reordered": 3, "samples_backward_dropped": 1,
        "time_outliers": 4, "duplicate_samples": 3, "non_finite_times": 1, "non_finite_samples": 5,
        "clipped_samples": 6, "time_total_s": 20.0, "time_kept_s": 18.0, "lines": lines}
    only_messages = DataQuality("g.bin", messages_total=10, messages_skipped=1)
    assert only_messages.lines() == ["g.bin: 1 of 10 message(s) damaged and skipped",
                                     "g.bin: kept 0.0 of 0.0 s of log; damage 10.0 %"]
    clean = DataQuality("h.bin")
    assert clean.ok and clean.lines() == [] and clean.damage_fraction == 0.0
    many = DataQuality("m.bin", bytes_total=10**6)
    for k in range(25):
        many.add_damage(100 * k, 10)
    assert many.bytes_skipped == 250 and many.messages_skipped == 25 and len(many.damaged_regions) == 20
    assert "25 damaged message(s) in 20+ region(s); first at byte 0" in many.lines()[0]


def test_add_battery_keeps_only_what_was_measured() -> None:
    from identification.logs.flightlog import BATTERY_CURRENT, BATTERY_VOLTAGE, BATTERY_VOLTAGE_LEGACY, add_battery

    t = np.array([0.0, 1.0, 2.0, np.nan, 4.0])
    sig: dict = {}
    add_battery(sig, t, np.array([12.0, 0.0, np.nan, 11.0, 11.5]), np.array([1.0, np.inf, 0.0, 2.0, 3.0]), "BAT")
    v, a = sig[BATTERY_VOLTAGE], sig[BATTERY_CURRENT]
    assert v.t_s.tolist() == [0.0, 4.0] and v.values.tolist() == [12.0, 11.5] and v.unit == "V"
    assert v.description == "battery voltage from BAT" and a.description == "battery current from BAT"
    assert sig[BATTERY_VOLTAGE_LEGACY].values.tolist() == [12.0, 11.5]
    assert sig[BATTERY_VOLTAGE_LEGACY].description == f"alias of {BATTERY_VOLTAGE}"
    assert a.t_s.tolist() == [0.0, 2.0, 4.0] and a.values.tolist() == [1.0, 0.0, 3.0] and a.unit == "A"
    earlier = {BATTERY_VOLTAGE: v}
    add_battery(earlier, t, np.full(5, 20.0), None, "other")  # an earlier, better source is kept
    assert earlier[BATTERY_VOLTAGE] is v and BATTERY_VOLTAGE_LEGACY not in earlier
    none: dict = {}
    add_battery(none, t, np.zeros(5), np.zeros(5), "BAT")  # no sensor: ArduPilot logs zeros
    assert none == {}
    current_only: dict = {}
    add_battery(current_only, t, None, np.array([0.0, 0.5, 0.0, 0.0, 0.0]), "BAT")  # not all zero: measured
    assert current_only[BATTERY_CURRENT].values.tolist() == [0.0, 0.5, 0.0, 0.0]


def test_sanitiser_counts_non_finite_and_clipped_canonical_samples() -> None:
    from identification.logs.flightlog import CLIP_LIMITS, Signal, sanitize_log

    t = np.arange(10) * 0.1
    az = np.full(10, -9.8)
    az[[2, 3]] = [np.nan, np.inf]
    az[7] = -CLIP_LIMITS["accel_body_"]  # at full scale
    gx = np.zeros(10)
    gx[5] = 1.01 * CLIP_LIMITS["gyro_body_"]
    log = FlightLog("c.bin", "csv", {
        "accel_body_z_m_s2": Signal("accel_body_z_m_s2", t, az, "m/s2"),
        "gyro_body_x_rad_s": Signal("gyro_body_x_rad_s", t, gx, "rad/s"),
        "IMU.AccZ": Signal("IMU.AccZ", t, az.copy(), "m/s2"),  # raw fields are not checked
        "VIBE.Clip0": Signal("VIBE.Clip0", t, np.arange(10.0), "1"),  # the IMU's own running clip count
        "mode": Signal("mode", t, np.array(["a"] * 10), ""),
    }, {})
    out = sanitize_log(log)
    q = out.quality
    assert q.non_finite_samples == 2 and q.canonical_samples == 20  # accel and gyro: raw fields and text skipped
    assert q.clipped_samples == 1 + 1 + 9
    kept = out.signal("accel_body_z_m_s2").values
    assert kept.size == 8 and np.isfinite(kept).all()
    assert out.signal("IMU.AccZ").values.size == 10


#: ArduCopter's RATE message (AC_AttitudeControl / AP_AHRS_View::Write_Rate, ArduCopter 4.x layout)
RATE_LAYOUT = ("RATE", "Qffffffffffff", "TimeUS,RDes,R,ROut,PDes,P,POut,YDes,Y,YOut,ADes,A,AOut")


def test_rate_controller_message_dataflash(tmp_path: Path) -> None:
    """RATE: targets and achieved rates [deg/s] -> rad/s, mixer inputs as logged, vertical accelerations
    [cm/s/s, up] -> m/s2; the achieved rates stand in for the gyro only where no IMU message is logged."""
    from identification.logs.dataflash_writer import MessageLayout, write_log

    t = np.arange(40) * 0.0025  # 400 Hz, ArduCopter's fast loop
    cols = {"RDes": 30.0 * np.sin(t), "R": 28.0 * np.sin(t), "ROut": 0.1, "PDes": -10.0, "P": -9.0, "POut": -0.05,
            "YDes": 5.0, "Y": 4.0, "YOut": 0.02, "ADes": 150.0, "A": 120.0, "AOut": 0.45}
    rate = MessageLayout(*RATE_LAYOUT)
    only = read_log(write_log(tmp_path / "rate.bin", {"RATE": (t, cols)}, layouts=[rate]))
    d2r = math.pi / 180.0
    np.testing.assert_allclose(only.signal("rate_target_body_x_rad_s").values, 30.0 * np.sin(t) * d2r, rtol=1e-6)
    np.testing.assert_allclose(only.signal("rate_achieved_body_y_rad_s").values, -9.0 * d2r, rtol=1e-6)
    np.testing.assert_allclose(only.signal("rate_target_body_z_rad_s").values, 5.0 * d2r, rtol=1e-6)
    np.testing.assert_allclose(only.signal("rate_out_roll").values, 0.1, rtol=1e-6)
    np.testing.assert_allclose(only.signal("throttle_out").values, 0.45, rtol=1e-6)
    np.testing.assert_allclose(only.signal("accel_target_up_m_s2").values, 1.5, rtol=1e-6)
    np.testing.assert_allclose(only.signal("accel_up_m_s2").values, 1.2, rtol=1e-6)
    np.testing.assert_allclose(only.signal("gyro_body_x_rad_s").values, 28.0 * np.sin(t) * d2r, rtol=1e-6, atol=1e-9)
    assert only.signal("gyro_body_z_rad_s").description == "from RATE.Y" and only.signal("rate_out_yaw").unit == "1"
    both = read_log(write_log(tmp_path / "both.bin", {"RATE": (t, cols), "IMU": (t[::8], {"I": 0, "GyrX": 0.7})},
                              layouts=[rate]))
    np.testing.assert_allclose(both.signal("gyro_body_x_rad_s").values, 0.7, rtol=1e-6)  # the IMU wins
    assert both.signal("gyro_body_x_rad_s").description == "from IMU.GyrX"

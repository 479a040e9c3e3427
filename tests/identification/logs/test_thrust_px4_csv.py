"""PX4 ulog2csv folder reader: canonical names, battery signals, armed, damaged rows kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from identification.logs.flightlog import LogError
from identification.logs.readers import read_log
from tests.conftest import shared_data


def _write(folder: Path, topic: str, header: str, rows: list[str]) -> None:
    folder.mkdir(exist_ok=True)
    (folder / f"fl_{topic}.csv").write_text(header + "\n" + "\n".join(rows) + "\n")


def test_small_folder_gives_canonical_signals(tmp_path: Path) -> None:
    d = tmp_path / "fl"
    _write(d, "actuator_outputs_0", "timestamp,noutputs,output[0],output[1],output[2],output[3]",
           ["1000000,4,900,900,900,900", "1100000,4,1500,1510,1490,1505", "1200000,4,1600,1600,1600,1600"])
    _write(d, "battery_status_0", "timestamp,voltage_v,voltage_filtered_v,current_a",
           ["1000000,11.0,0.0,1.0", "1500000,10.9,0.0,9.5", "broken,row", "2000000,10.8,0.0,9.0"])
    _write(d, "sensor_combined_0", "timestamp,gyro_rad[0],gyro_rad[1],gyro_rad[2],accelerometer_m_s2[0],"
           "accelerometer_m_s2[1],accelerometer_m_s2[2]", ["1000000,0,0,0.1,0,0,-9.8", "1004000,0,0,0.2,0,0,-9.9"])
    log = read_log(d)
    assert log.fmt == "px4_csv" and log.vehicle == "quadrotor"
    m1 = log.signal("motor_1_pwm_us")
    np.testing.assert_allclose(m1.t_s, [0.0, 0.1, 0.2])
    np.testing.assert_allclose(m1.values, [900, 1500, 1600])
    np.testing.assert_allclose(log.signal("armed").values, [0, 1, 1])
    # filtered voltage is all zero here: the raw voltage_v is used
    np.testing.assert_allclose(log.signal("battery_voltage_v").values, [11.0, 10.9, 10.8])
    np.testing.assert_allclose(log.signal("battery_current_a").values, [1.0, 9.5, 9.0])
    assert log.signal("gyro_body_z_rad_s").values[1] == pytest.approx(0.2)
    assert any("1 malformed row" in w for w in log.warnings)


def test_folder_without_csv_is_a_clear_error(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(LogError, match="no CSV files"):
        read_log(tmp_path / "empty")


def test_shared_px4_flight() -> None:
    log = read_log(shared_data("quadrotor_px4_csv", "drone1-8"))
    v = log.signal("battery_voltage_v")
    assert "voltage_filtered_v" in v.description
    # README of ../shared/data: filtered voltage 10.55 -> 10.12 V over the flight
    assert 9.5 < v.values.min() < v.values.max() < 12.7
    pwm = log.signal("motor_4_pwm_us").values
    assert pwm.min() == pytest.approx(900.0) and pwm.max() <= 2000.0
    assert log.duration_s == pytest.approx(94.4, abs=1.0)

"""The measurement chain read off a log: the shared ArduPlane SITL excitation log says a 20 Hz gyro and
accelerometer filter (INS_GYRO_FILTER, INS_ACCEL_FILTER), a 50 Hz main loop and servo outputs logged at 25 Hz."""

from __future__ import annotations

import pytest

from identification.logs.flightlog import FlightLog
from identification.logs.readers import read_log
from identification.logs.sensor_chain import sensor_chain
from tests.conftest import shared_data


def test_shared_sitl_log_chain() -> None:
    chain = sensor_chain(read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN")))
    assert (chain.gyro_cutoff_hz, chain.accel_cutoff_hz, chain.loop_rate_hz) == (20.0, 20.0, 50.0)
    assert chain.servo_log_rate_hz == pytest.approx(25.0, rel=0.05)
    assert chain.imu_log_rate_hz == pytest.approx(50.0, rel=0.05)
    assert chain.output_filters(("roll_rad", "rate_body_x_rad_s", "accel_body_z_m_s2")) == {
        "rate_body_x_rad_s": 20.0, "accel_body_z_m_s2": 20.0}
    text = "\n".join(chain.lines())
    assert "INS_GYRO_FILTER" in text and "below the loop rate" in text


def test_px4_names_and_a_filter_turned_off() -> None:
    px4 = sensor_chain(FlightLog("x.ulg", "ulog", {}, {"IMU_GYRO_CUTOFF": 40.0, "IMU_ACCEL_CUTOFF": 0.0}))
    assert (px4.gyro_cutoff_hz, px4.accel_cutoff_hz, px4.gyro_param) == (40.0, None, "IMU_GYRO_CUTOFF")
    assert px4.output_filters(["rate_body_y_rad_s", "accel_body_x_m_s2"]) == {"rate_body_y_rad_s": 40.0}
    assert "off (IMU_ACCEL_CUTOFF = 0)" in "\n".join(px4.lines())
    none = sensor_chain(FlightLog("x.csv", "csv", {}, {}))
    assert none.output_filters(["rate_body_x_rad_s"]) == {} and "no parameter in the log" in none.lines()[0]

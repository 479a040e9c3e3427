"""The measurement chain read off a log: the shared ArduPlane SITL excitation log says a 20 Hz gyro and
accelerometer filter (INS_GYRO_FILTER, INS_ACCEL_FILTER), a 50 Hz main loop and servo outputs logged at 25 Hz."""

from __future__ import annotations

import numpy as np
import pytest

from identification.logs.flightlog import FlightLog
from identification.logs.readers import read_log
from identification.logs.sensor_chain import LoopClock, loop_clock, sensor_chain
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


def test_loop_clock_of_the_shared_log_puts_every_servo_sample_on_an_even_tick() -> None:
    """ArduPlane logs RCOU every second 50 Hz loop, stamped in that loop: each sample is on a gyro tick."""
    log = read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN"))
    clock = loop_clock(log)
    assert clock is not None and clock.period_s == pytest.approx(0.020, abs=2e-6)
    t_servo = np.asarray(log.signal("aileron_pwm_us").t_s)
    on_tick = np.min(np.abs(clock.tick_s[None, :200] - t_servo[1:100, None]), axis=1)  # [0]: before the first IMU
    assert np.all(on_tick < 1e-6)
    assert clock.servo_every(sensor_chain(log).servo_log_rate_hz) == 2
    grid = clock.grid(61.919, 62.5)
    assert np.min(np.abs(clock.tick_s - grid[0])) < 1e-9 and grid[0] >= 61.919
    assert "ticks from the gyro's time stamps" in "\n".join(sensor_chain(log).lines(clock=clock))


def test_loop_commands_bracket_the_unlogged_loops() -> None:
    """Logged every second loop: a logged loop keeps its sample, an unlogged one lies between its neighbours
    (their mean as the expected value); a grid drifting by microseconds against the ticks reads the same loops."""
    ticks = np.arange(10) * 0.02
    clock = LoopClock(ticks, 0.02)
    t_log, pwm = ticks[::2], np.array([1500.0, 1500.0, 1600.0, 1600.0, 1400.0])
    assert np.allclose(clock.commands(t_log, pwm, ticks), [1500, 1500, 1500, 1550, 1600, 1600, 1600, 1500, 1400,
                                                            1400])
    before, after, share, logged = clock.bracket(t_log, pwm, ticks + 3e-6)
    assert list(logged) == [True, False] * 5
    assert before[3] == 1500 and after[3] == 1600 and share[3] == 0.5 and share[4] == 0
    assert clock.loop_index(np.array([0.0399, 0.0301]))[0] == 2 and clock.loop_index(np.array([0.0301]))[0] == 1
    hw = clock.commands(t_log + 4e-4, pwm, ticks)  # hardware stamps RCOU after the loop's IMU sample
    assert hw[4] == 1600 and hw[3] == 1550
    assert loop_clock(FlightLog("x.csv", "csv", {}, {})) is None

"""HIL plant, watchdog and generic MAVLink bridge: FMU errors restart the simulation, the failsafe applies when
input stops, SERVO_OUTPUT_RAW drives the FMU and HIL_* messages come back (pymavlink over loopback UDP)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from fmu_models.signals.pwm_mapping import MappingError, default_mapping
from hil_adapter.core import Plant, Stats, Watchdog
from hil_adapter.mavlink_bridge import MavlinkBridge
from hil_adapter.sensors import SensorConfig, SensorSuite


def test_fmu_error_restarts_instead_of_crashing(quadrotor_fmu: Path) -> None:
    plant = Plant(quadrotor_fmu)
    try:
        plant.apply({1: 1500, 2: 1500, 3: 1500, 4: 1500})
        for _ in range(10):
            plant.advance(0.01)
        assert plant.t_s == pytest.approx(0.1)
        plant.inputs = {**plant.inputs, "pwm_1_us": 3000.0}  # beyond the FMU's input range: fmi2Error
        state = plant.advance(0.01)
        assert plant.fmu_errors == 1 and "pwm_1_us" in plant.last_error
        # the clock goes on past the failed step (never backwards, never repeated), the FMU starts afresh on a new
        # instance (no fmi2Reset after an error)
        assert plant.t_s == pytest.approx(0.11) and plant.fmu_t_s == 0.0 and plant.reinstantiations == 1
        assert state["altitude_m"] == pytest.approx(0.0, abs=0.05)
        plant.apply({1: 1500, 2: 1500, 3: 1500, 4: 1500})
        plant.advance(0.01)  # the new instance steps on from its own time 0
        assert plant.t_s == pytest.approx(0.12) and plant.fmu_errors == 1
        with pytest.raises(MappingError, match="channel 2"):
            plant.apply({1: 1500, 3: 1500, 4: 1500})
    finally:
        plant.close()


def test_watchdog_throttle_off_and_hold(quadrotor_fmu: Path) -> None:
    plant = Plant(quadrotor_fmu)
    stats = Stats()
    try:
        plant.apply({k: 1700.0 for k in range(1, 5)})
        dog = Watchdog(timeout_s=0.05, mode="throttle_off")
        assert not dog.check(plant, stats)
        time.sleep(0.06)
        assert dog.check(plant, stats) and stats.failsafes == 1
        assert plant.inputs == {f"pwm_{k}_us": 1000.0 for k in range(1, 5)}
        dog.fed()
        assert not dog.check(plant, stats)
        plant.apply({k: 1700.0 for k in range(1, 5)})
        hold = Watchdog(timeout_s=0.01, mode="hold")
        time.sleep(0.02)
        assert hold.check(plant, stats) and plant.inputs["pwm_1_us"] == 1700.0
        with pytest.raises(ValueError, match="watchdog mode 'coast'"):
            Watchdog(mode="coast")
    finally:
        plant.close()


def test_default_fixed_wing_mapping_matches_arduplane() -> None:
    m = default_mapping("fixed_wing")
    # ArduPlane: PWM above trim = roll right, nose up, nose right; the FMU is uavbook (elevator + = nose down)
    assert m.apply({1: 1900, 2: 1100, 3: 1500, 4: 1900}) == pytest.approx(
        {"aileron_rad": 0.35, "elevator_rad": 0.35, "throttle": 0.5, "rudder_rad": -0.35})


def test_generic_mavlink_bridge_over_udp(fixed_wing_fmu: Path) -> None:
    plant = Plant(fixed_wing_fmu, start_values={"init_pos_down_m": -100.0, "init_vel_body_x_m_s": 25.0})
    adapter = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=1, dialect="common")
    port = adapter.port.getsockname()[1]
    autopilot = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=2, dialect="common")
    bridge = MavlinkBridge(plant, SensorSuite(SensorConfig.noise_free()), adapter, dt_s=0.01)
    try:
        autopilot.mav.servo_output_raw_send(0, 0, 1900, 1500, 1700, 1500, 0, 0, 0, 0)
        deadline = time.monotonic() + 3.0
        while not bridge.pwm and time.monotonic() < deadline:  # the first datagram also tells udpin the peer
            bridge.step()
        assert bridge.pwm[1] == 1900 and plant.inputs["aileron_rad"] == pytest.approx(0.35)
        for _ in range(50):
            bridge.step()
        sensor = autopilot.recv_match(type="HIL_SENSOR", blocking=True, timeout=2.0)
        state = autopilot.recv_match(type="HIL_STATE_QUATERNION", blocking=True, timeout=2.0)
        assert sensor is not None and state is not None
        assert state.rollspeed > 0.1  # full right aileron rolls right
        autopilot.write(b"\xfe\x05junkjunkjunk")
        time.sleep(0.05)
        bridge.step()
        assert bridge.stats.steps > 50
    finally:
        autopilot.close()
        adapter.close()
        plant.close()


def test_busy_poll_returns_when_data_waits_and_gives_up_after_its_time() -> None:
    import socket

    from hil_adapter.core import SocketSpinner

    a, b = socket.socketpair()
    try:
        assert SocketSpinner(a, 0.0).wait() is False  # off: the caller blocks at once
        spinner = SocketSpinner(a, 5.0 / 1000)
        t0 = time.perf_counter()
        assert spinner.wait() is False
        assert time.perf_counter() - t0 >= 0.005
        b.sendall(b"x")
        t0 = time.perf_counter()
        assert SocketSpinner(a, 0.1).wait(limit_s=5.0) is True
        assert time.perf_counter() - t0 < 1.0  # found the byte, did not spin for its whole time
        assert a.recv(1) == b"x"
    finally:
        a.close()
        b.close()


def test_busy_poll_setting_is_checked() -> None:
    from hil_adapter.ardupilot_json import UdpTransport

    with pytest.raises(ValueError, match=r"busy_poll_s = -0\.001; allowed 0\.\.0\.1 s"):
        UdpTransport("127.0.0.1", 0, busy_poll_s=-0.001)
    tr = UdpTransport("127.0.0.1", 0, busy_poll_s=0.0)
    try:
        assert tr.recv(0.01) is None  # no spin, a short blocking wait, nothing came
    finally:
        tr.close()


def test_out_of_band_only_above_idle_and_counted_per_step(quadrotor_fmu: Path, tmp_path: Path) -> None:
    """Disarmed motors (1000 us) and idle are not out of band; above idle but outside the trained band is,
    counted per step and recorded in the out_of_band column."""
    from hil_adapter.core import Recorder
    from identification.logs.readers import read_log

    plant = Plant(quadrotor_fmu)
    stats = Stats()
    rec = Recorder(tmp_path / "oob.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs)
    idle = plant.host.start_value("pwm_idle_us")
    top = plant.host.start_value("anfis_band_hi_us") / 4
    try:
        for pwm, expected in ((1000.0, False), (idle, False), (top + 100.0, True), (1000.0, False)):
            for _ in range(5):
                plant.apply(dict.fromkeys(range(1, 5), pwm))
                plant.advance(0.004)
                stats.step(plant.out_of_band)
                rec.write(plant.t_s, dict.fromkeys(range(1, 5), pwm), plant.inputs, plant.state,
                          out_of_band=plant.out_of_band)
                assert plant.out_of_band is expected, pwm
    finally:
        rec.close()
        plant.close()
    assert stats.out_of_band == 5 and stats.summary()["out_of_band_steps"] == 5
    assert read_log(rec.path).signal("out_of_band").values.tolist() == [0.0] * 10 + [1.0] * 5 + [0.0] * 5


def test_rates_count_stepping_time_only() -> None:
    """The summary rate leaves out waits (autopilot not yet connected, after it stopped); the live rate is over
    the last stretch of stepping and drops to 0 when stepping stops."""
    stats = Stats()
    time.sleep(0.3)  # waiting for the autopilot
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 0.2:
        stats.step()
        time.sleep(0.001)
    stepping = time.perf_counter() - t0
    time.sleep(0.3)  # the autopilot stopped
    expected = stats.steps / stepping
    assert stats.rate_hz == pytest.approx(expected, rel=0.15)
    assert stats.live_rate_hz() == pytest.approx(expected, rel=0.15)
    assert stats.live_rate_hz() == 0.0  # nothing stepped since the last call

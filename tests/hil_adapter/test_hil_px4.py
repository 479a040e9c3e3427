"""PX4 simulator interface over loopback TCP with a pymavlink fake PX4: sensors at rest, lockstep closed-loop
hover at 10 m, disconnect/reconnect, malformed bytes."""

from __future__ import annotations

import csv
import itertools
import math
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from hil_adapter.core import Plant, Watchdog
from hil_adapter.px4 import HilMessages, Px4Server, controls_to_pwm
from hil_adapter.sensors import (
    REQUIRED_OUTPUTS,
    UPDATED_BARO,
    UPDATED_DIFF_PRESSURE,
    UPDATED_IMU,
    UPDATED_MAG,
    SensorConfig,
    SensorSuite,
    interval_imu,
)
from tests.fakes.hil import controller_inputs, hold_10m_autopilot, serving

DT = 0.004  # PX4's usual 250 Hz


class FakePx4:
    """Connects like PX4 SITL: reads the HIL messages of a step, answers with HIL_ACTUATOR_CONTROLS."""

    def __init__(self, address: tuple[str, int] | None = None, sock: socket.socket | None = None) -> None:
        if sock is None:
            sock = socket.create_connection(address, timeout=5.0)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock = sock
        self.sock.settimeout(5.0)
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self.pending: list = []

    def read_step(self) -> dict[str, object]:
        """Messages up to and including the next HIL_STATE_QUATERNION, by type."""
        got: dict[str, object] = {}
        while True:
            while self.pending:
                m = self.pending.pop(0)
                got[m.get_type()] = m
                if m.get_type() == "HIL_STATE_QUATERNION":
                    return got
            data = self.sock.recv(65536)
            assert data, "adapter closed the connection"
            self.pending += self.mav.parse_buffer(data) or []

    def send_controls(self, t_us: int, pwm: list[float], armed: bool = True) -> None:
        controls = [(p - 1000.0) / 1000.0 for p in pwm] + [0.0] * (16 - len(pwm))
        mode = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0
        self.sock.sendall(self.mav.hil_actuator_controls_encode(t_us, controls, mode, 1).pack(self.mav))

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def server(quadrotor_fmu: Path):
    plant = Plant(quadrotor_fmu)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0, dt_s=DT,
                    watchdog=Watchdog(timeout_s=2.0))
    with serving(srv):
        yield srv
    srv.close()
    plant.close()


def test_controls_map_to_pwm() -> None:
    assert controls_to_pwm([0.5, 0.0, 1.0, 2.0] + [0] * 12, "quadrotor", True) == {1: 1500, 2: 1000, 3: 2000, 4: 2000}
    assert controls_to_pwm([0.5] * 16, "quadrotor", False) == {1: 1000, 2: 1000, 3: 1000, 4: 1000}
    wing = controls_to_pwm([-1.0, 0.5, 0.2, 0.7] + [0] * 12, "fixed_wing", True)
    assert wing == {1: 1000.0, 2: 1750.0, 3: 1700.0, 4: 1600.0}
    assert controls_to_pwm([float("nan")] * 16, "quadrotor", True)[1] == 1000.0
    swapped = controls_to_pwm([-1.0, 0.5, 0.2, 0.7] + [0] * 12, "fixed_wing", True, {1: 1, 2: 0, 3: 3, 4: 2})
    assert swapped == {1: 1750.0, 2: 1000.0, 3: 1700.0, 4: 1600.0}


def test_at_rest_sensors_read_gravity_and_home(server) -> None:
    px4 = FakePx4(server.address)
    try:
        updated, times = [], []
        for k in range(250):  # 1 s on the ground, motors idle
            got = px4.read_step()
            px4.send_controls(k, [1000.0] * 4)
            updated.append(got["HIL_SENSOR"].fields_updated)
        sensor, state = got["HIL_SENSOR"], got["HIL_STATE_QUATERNION"]
        assert sensor.zacc == pytest.approx(-9.81, abs=0.02) and abs(sensor.xacc) < 1e-3
        # the IMU every step, the magnetometer at 100 Hz and the barometer at 50 Hz (PX4's Gazebo plugins'
        # rates), no pitot on a quadrotor
        assert all(u & UPDATED_IMU == UPDATED_IMU and not u & UPDATED_DIFF_PRESSURE for u in updated)
        assert sum(u & UPDATED_MAG == UPDATED_MAG for u in updated) == pytest.approx(100, abs=2)
        assert sum(u & UPDATED_BARO == UPDATED_BARO for u in updated) == pytest.approx(50, abs=2)
        home = server.plant.host.start_value
        isa_hpa = 1013.25 * (1 - 2.25577e-5 * home("home_height_m")) ** 5.25588  # ISA at the home height
        assert sensor.abs_pressure == pytest.approx(isa_hpa, abs=0.5)
        assert state.lat == pytest.approx(home("home_lat_deg") * 1e7, abs=20)
        gps, heartbeats = None, 0
        for k in range(300):  # GPS comes at its own rate, the heartbeat at 1 Hz
            got = px4.read_step()
            px4.send_controls(250 + k, [1000.0] * 4)
            gps = got.get("HIL_GPS", gps)
            heartbeats += "HEARTBEAT" in got
            times.append(got["HIL_SENSOR"].time_usec)
        assert gps is not None and gps.fix_type == 3
        assert gps.lat == pytest.approx(home("home_lat_deg") * 1e7, abs=20)
        assert gps.lon == pytest.approx(home("home_lon_deg") * 1e7, abs=20)
        span_s = (times[-1] - times[0]) * 1e-6  # 1.2 s: one heartbeat per second of simulated time
        assert heartbeats in (math.floor(span_s), math.floor(span_s) + 1) and heartbeats >= 1
    finally:
        px4.close()


def test_lockstep_closed_loop_hover_at_10_m(server) -> None:
    px4 = FakePx4(server.address)
    ap = hold_10m_autopilot()
    alts = []
    try:
        for k in range(round(35.0 / DT)):
            s = px4.read_step()["HIL_STATE_QUATERNION"]
            q = tuple(s.attitude_quaternion)
            alt = server.plant.host.start_value("home_height_m")
            alt = s.alt / 1000.0 - alt
            v = (s.vx / 100.0, s.vy / 100.0, s.vz / 100.0)
            y = controller_inputs(q, (s.rollspeed, s.pitchspeed, s.yawspeed), alt, v)
            cmd = ap(k * DT, y)
            px4.send_controls(s.time_usec, [cmd[f"pwm_{i}_us"] for i in range(1, 5)])
            alts.append(alt)
    finally:
        px4.close()
    hold = np.array(alts[round(15.0 / DT):])  # the last 20 s of simulated time
    assert np.all(np.abs(hold - 10.0) < 0.5), (hold.min(), hold.max())
    assert server.stats.malformed == 0
    assert server.stats.percentile(99) < 0.05


def test_garbage_disconnect_and_reconnect(server) -> None:
    px4 = FakePx4(server.address)
    px4.read_step()
    px4.sock.sendall(b"\xfd\x09garbage-not-mavlink" * 5)
    px4.send_controls(0, [1200.0] * 4)
    # until its first actuator message the server free-runs at the wall-clock pace, so a state may arrive before
    # it has read our bytes; the state it sends after taking them comes after the garbage was counted
    last = px4.read_step()["HIL_STATE_QUATERNION"]
    for _ in range(2000):  # bounded: 8 s of free-run states at the test step
        if server.stats.malformed >= 1:
            break
        last = px4.read_step()["HIL_STATE_QUATERNION"]
    start_alt = round(server.plant.host.start_value("home_height_m") * 1e3)
    assert server.stats.malformed >= 1
    px4.close()  # PX4 goes away mid-run
    again = FakePx4(server.address)
    try:
        first = again.read_step()["HIL_STATE_QUATERNION"]
        # the FMU restarted for the new connection; its clock goes on (one continuous record, never backwards)
        assert first.time_usec > last.time_usec and first.alt == pytest.approx(start_alt, abs=20)
        assert server.stats.reconnects == 1
    finally:
        again.close()


@pytest.fixture
def realtime_server(quadrotor_fmu: Path, tmp_path: Path):
    from hil_adapter.core import Recorder

    plant = Plant(quadrotor_fmu)
    rec = Recorder(tmp_path / "rt.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs)
    srv = Px4Server(plant, SensorSuite(seed=5), port=0, lockstep=False, dt_s=0.004, recorder=rec,
                    watchdog=Watchdog(timeout_s=0.1, mode="throttle_off"), rc_channels=[1500, 1500, 1000, 1500])
    with serving(srv):
        yield srv
    rec.close()
    srv.close()
    plant.close()


@pytest.mark.realtime
def test_realtime_mode_paces_steps_and_watchdog_cuts_throttle(realtime_server) -> None:
    from identification.logs.readers import read_log

    px4 = FakePx4(realtime_server.address)
    seen: set[str] = set()
    try:
        for k in range(50):
            seen |= set(px4.read_step())
            px4.send_controls(k, [1600.0] * 4)
        assert "RC_CHANNELS" in seen and "HEARTBEAT" in seen
        steps0 = realtime_server.stats.steps
        t0 = time.monotonic()
        time.sleep(0.5)  # no more actuator messages: the watchdog trips after 0.1 s
        rate = (realtime_server.stats.steps - steps0) / (time.monotonic() - t0)
        assert 150 < rate < 300  # paced at 250 Hz by the wall clock, not as fast as possible
        assert realtime_server.stats.failsafes == 1
        assert realtime_server.plant.inputs == {f"pwm_{k}_us": 1000.0 for k in range(1, 5)}
    finally:
        px4.close()
    log = read_log(realtime_server.recorder.path)
    assert log.signal("failsafe").values.max() == 1.0
    sens = log.signal("sens_accel_z_m_s2").values
    assert np.nanstd(sens) > 0  # the recorded sensor readings carry the configured noise


@pytest.fixture(scope="module")
def absorb_server(quadrotor_fmu: Path):
    plant = Plant(quadrotor_fmu)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0)
    yield srv
    srv.close()
    plant.close()


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=300))
def test_fuzzed_mavlink_bytes_never_crash(absorb_server, data: bytes) -> None:
    """Random bytes, and random bytes spliced into a valid actuator message, never raise: a chunk either
    delivers an actuator message whose controls are the valid one's (0.5 -> 1500 us) or leaves the PWM as it
    was; and after the parser is cleared, the valid message alone is taken."""
    srv = absorb_server
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    good = mav.hil_actuator_controls_encode(1, [0.5] * 16, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, 1).pack(mav)
    cut = len(data) % (len(good) + 1)
    for chunk in (data, good[:cut] + data + good[cut:]):
        before = dict(srv.pwm)
        got = srv._absorb(chunk)
        if got:
            assert srv.pwm == dict.fromkeys(range(1, 5), 1500.0)
        else:
            assert srv.pwm == before
    srv.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=51)  # drop any partial frame the fuzz left
    srv.mav.robust_parsing = True
    srv.msgs = HilMessages(srv.mav, srv.plant.vehicle)
    srv.pwm = {}
    assert srv._absorb(good) is True and srv.pwm == dict.fromkeys(range(1, 5), 1500.0)


class PairListener:
    """An in-memory listener: each accept() hands the server one end of a fresh socketpair."""

    def __init__(self) -> None:
        self.peers: list[socket.socket] = []
        self.timeout: float | None = None
        self.ready = threading.Event()

    def accept(self) -> tuple[socket.socket, str]:
        if not self.ready.wait(self.timeout):
            raise TimeoutError
        self.ready.clear()
        ours, theirs = socket.socketpair()
        self.peers.append(theirs)
        return ours, "memory"

    def settimeout(self, timeout: float | None) -> None:
        self.timeout = timeout

    def getsockname(self) -> str:
        return "memory"

    def close(self) -> None:
        for s in self.peers:
            s.close()


def test_px4_over_an_in_memory_transport(quadrotor_fmu: Path, tmp_path: Path) -> None:
    """The same server on a socketpair instead of TCP: the HIL loop needs no network to be tested. Each log
    row holds the state and the (noise-free) sensor readings sent with it, at the same time."""
    from hil_adapter.core import Recorder

    plant = Plant(quadrotor_fmu)
    listener = PairListener()
    rec = Recorder(tmp_path / "px4.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), listener=listener, dt_s=DT, recorder=rec)
    try:
        with serving(srv):
            listener.ready.set()
            deadline = time.monotonic() + 5.0
            while not listener.peers and time.monotonic() < deadline:
                time.sleep(0.01)
            px4 = FakePx4(sock=listener.peers[0])
            for k in range(100):
                px4.read_step()
                px4.send_controls(k, [1000.0] * 4 if k < 50 else [1700.0] * 4)  # rest, then climb
            assert srv.stats.steps >= 99
    finally:
        srv.close()
        plant.close()
        rec.close()
    with (tmp_path / "px4.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    # the start state (at a positive time: PX4 takes 0 as no time), then one row per step
    assert len(rows) >= 100 and float(rows[0]["time_s"]) == DT
    accel_z = np.array([float(r["accel_body_z_m_s2"]) for r in rows[1:]])
    sensed_z = np.array([float(r["sens_accel_z_m_s2"]) for r in rows[1:]])
    assert accel_z[45] == pytest.approx(-9.81, abs=0.05)  # at rest on the ground
    assert np.all(np.abs(np.diff(accel_z[55:])) > 1e-6)  # climbing: drag changes the reading every step
    # the accelerometer sent with each state is the mean over the step that led to it (delta velocity), not the
    # instant at its end and not the last step's: recomputed here from the recorded states
    states = [{k: float(v) for k, v in r.items() if k in (*REQUIRED_OUTPUTS, "gravity_m_s2")} for r in rows]
    means_z = np.array([interval_imu(states[k - 1], states[k], DT)[0][2] for k in range(1, len(rows))])
    np.testing.assert_allclose(sensed_z, means_z, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sensed_z[:45], accel_z[:45], rtol=0, atol=1e-6)  # at rest the mean is the instant
    assert abs(sensed_z[50] - accel_z[50]) > 0.5  # the motors spinning up: the mean over the step differs
    assert all(float(r["servo_1_pwm_us"]) == pytest.approx(1700.0, abs=1e-3) for r in rows[60:])  # float32 controls


def test_outputs_no_message_holds_restart_the_simulation(absorb_server) -> None:
    """A sensor reading beyond float32 cannot be sent: handled like an FMU error, the step goes out from the
    restarted simulation instead of raising in the server loop."""
    srv = absorb_server
    a, b = socket.socketpair()
    try:
        srv.plant.advance(DT)
        srv.plant.state = {**srv.plant.state, "accel_body_x_m_s2": 1e39}
        srv.plant.imu = ((1e39, 0.0, 0.0), (0.0, 0.0, 0.0))  # the mean over the step, as sent
        errors = srv.plant.fmu_errors
        srv._send_step(a)
        assert srv.plant.fmu_errors == errors + 1 and "do not fit" in srv.plant.last_error
        b.settimeout(2.0)
        msgs = mavlink2.MAVLink(None, 255, 0).parse_buffer(b.recv(65536))
        assert [m.get_type() for m in msgs][:2] == ["HIL_SENSOR", "HIL_STATE_QUATERNION"]
        # the start state's reading (not 1e39) on a fresh instance, at the time the clock had reached
        assert msgs[0].time_usec == round(srv.plant.t_s * 1e6) > 0 and abs(msgs[0].xacc) < 1.0
        assert srv.plant.fmu_t_s == 0.0
        restart = srv.plant.restart

        def runaway_start() -> None:
            restart()
            srv.plant.state = {**srv.plant.state, "accel_body_x_m_s2": 1e39}

        srv.plant.restart = runaway_start  # type: ignore[method-assign]
        try:
            srv.plant.state = {**srv.plant.state, "accel_body_x_m_s2": 1e39}
            srv._send_step(a)  # not even the start state fits: logged, nothing sent, nothing raised
        finally:
            del srv.plant.restart
            srv.plant.restart()  # leave the shared server as it was
        assert srv.plant.fmu_errors == errors + 2
        b.settimeout(0.2)
        with pytest.raises(TimeoutError):
            b.recv(65536)
    finally:
        a.close()
        b.close()


def test_reconnect_is_fast_and_the_record_stays_continuous(quadrotor_fmu: Path, tmp_path: Path) -> None:
    """PX4 leaves and comes back 5 times: each new connection gets its first state in < 0.1 s (measured from
    the client's connect), the record is one log whose time only grows, one row per state sent."""
    from hil_adapter.core import Recorder

    plant = Plant(quadrotor_fmu)
    rec = Recorder(tmp_path / "reconnect.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0, dt_s=DT, recorder=rec,
                    watchdog=Watchdog(timeout_s=2.0))
    waits, times = [], []
    try:
        with serving(srv):
            for k in range(6):
                t0 = time.perf_counter()
                px4 = FakePx4(srv.address)
                first = px4.read_step()
                if k:
                    waits.append(time.perf_counter() - t0)
                times.append(first["HIL_SENSOR"].time_usec)
                for j in range(30):
                    px4.send_controls(j, [1000.0] * 4)
                    times.append(px4.read_step()["HIL_SENSOR"].time_usec)
                px4.close()
    finally:
        srv.close()
        plant.close()
        rec.close()
    print(f"PX4 reconnect: first state after {1e3 * max(waits):.2f} ms at most (median "
          f"{1e3 * sorted(waits)[2]:.2f} ms) over {len(waits)} reconnects")
    assert max(waits) < 0.1
    assert srv.stats.reconnects >= 5 and all(b > a for a, b in itertools.pairwise(times))
    with rec.path.open() as fh:
        rows = list(csv.DictReader(fh))
    t_rows = [float(r["time_s"]) for r in rows]
    assert len(rows) >= len(times) and all(b > a for a, b in itertools.pairwise(t_rows))


def test_first_packet_has_positive_time_and_the_vehicle_rests_on_its_gear(quadrotor_fmu: Path) -> None:
    """The model starts at its ground-contact equilibrium: from the first packet (at a positive time) the
    accelerometer reads -g, with no settling transient."""
    plant = Plant(quadrotor_fmu)
    port_srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0, dt_s=DT,
                         watchdog=Watchdog(timeout_s=2.0))
    try:
        with serving(port_srv):
            px4 = FakePx4(port_srv.address)
            try:
                readings = []
                for k in range(50):  # 0.2 s
                    sensor = px4.read_step()["HIL_SENSOR"]
                    readings.append((sensor.time_usec, sensor.zacc, sensor.xacc))
                    px4.send_controls(k, [1000.0] * 4)
            finally:
                px4.close()
    finally:
        port_srv.close()
        plant.close()
    assert readings[0][0] > 0
    g = 9.808  # WGS-84 normal gravity near 47 deg latitude
    assert all(abs(z + g) < 0.02 and abs(x) < 1e-3 for _, z, x in readings), readings[:5]

"""Fake autopilots for the HIL tests: a quadrotor altitude/attitude controller on top of what an autopilot
receives (state estimates), and helpers to turn interface messages into the controller's inputs."""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from fmu_models.common.units import G0_M_S2
from identification.flights.scenarios import QuadrotorAutopilot, published_thrust_inverse

#: the lockstep step of the fakes [s] (250 Hz, PX4's and the bench's default)
DT = 0.004


def euler_from_quat(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def body_velocity(q: tuple[float, float, float, float], v_ned: tuple[float, float, float]) -> np.ndarray:
    w, x, y, z = q
    r_b2n = np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ])
    return r_b2n.T @ np.asarray(v_ned)


def controller_inputs(q: tuple[float, float, float, float], rates: tuple[float, float, float],
                      altitude_m: float, v_ned: tuple[float, float, float]) -> dict[str, float]:
    roll, pitch, yaw = euler_from_quat(*q)
    vb = body_velocity(q, v_ned)
    return {"altitude_m": altitude_m, "vel_down_m_s": v_ned[2], "roll_rad": roll, "pitch_rad": pitch,
            "yaw_rad": yaw, "rate_body_x_rad_s": rates[0], "rate_body_y_rad_s": rates[1],
            "rate_body_z_rad_s": rates[2], "vel_body_x_m_s": vb[0], "vel_body_y_m_s": vb[1]}


def hold_10m_autopilot() -> QuadrotorAutopilot:
    return QuadrotorAutopilot(lambda t: 10.0, published_thrust_inverse())


def recorded(server: Any, timeout_s: float = 5.0) -> Any:
    """The server's recorder once it has written a row for every step (the row of the frame just answered is
    written after the reply, off the autopilot's critical path); bounded wait."""
    deadline = time.monotonic() + timeout_s
    while server.recorder.rows < server.stats.steps and time.monotonic() < deadline:
        time.sleep(0.001)
    return server.recorder


@contextmanager
def serving(server: Any, **serve_kwargs: Any) -> Iterator[Any]:
    """Run ``server.serve(stop=...)`` in a thread for the duration of the block; always stop and join it."""
    stop = threading.Event()
    th = threading.Thread(target=server.serve, kwargs={"stop": stop, **serve_kwargs}, daemon=True)
    th.start()
    try:
        yield server
    finally:
        stop.set()
        th.join(timeout=10)


class FakeSitl:
    """An ArduPilot SITL stand-in on the JSON interface: sends servo frames at ``rate_hz`` to the adapter and
    reads the JSON state back (``exchange``)."""

    def __init__(self, address: tuple[str, int], rate_hz: int = 250) -> None:
        import socket

        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(2.0)
        self.address, self.rate_hz = address, rate_hz

    def exchange(self, count: int, pwm: list[int]) -> dict:
        from hil_adapter.packets import ServoPacket, parse_json_state

        self.sock.sendto(ServoPacket(self.rate_hz, count, tuple(pwm + [0] * (16 - len(pwm)))).pack(), self.address)
        data, _ = self.sock.recvfrom(65536)
        assert data.startswith(b"\n") and data.endswith(b"\n")
        return parse_json_state(data)


class LockstepPx4Client:
    """A minimal PX4 SITL stand-in over TCP: answers each HIL_SENSOR with HIL_ACTUATOR_CONTROLS and checks that
    the time it is sent never goes backwards. Runs until the adapter closes the connection (or ``max_s``)."""

    def __init__(self, port: int, controls: float = 0.0, max_s: float = 30.0) -> None:
        self.port, self.controls, self.max_s = port, controls, max_s
        self.steps = 0
        self.backwards = 0
        self.times_us: list[int] = []
        #: monotonic wall time [s] at which each HIL_SENSOR arrived (beside ``times_us``)
        self.wall_s: list[float] = []
        self.connected = threading.Event()
        self.error = ""

    def run(self) -> None:
        import socket
        import time

        from pymavlink.dialects.v20 import common as mavlink2

        deadline = time.monotonic() + self.max_s
        sock = None
        while sock is None and time.monotonic() < deadline:
            try:
                sock = socket.create_connection(("127.0.0.1", self.port), timeout=0.2)
            except OSError:
                time.sleep(0.02)
        if sock is None:
            self.error = "could not connect"
            return
        self.connected.set()
        sock.settimeout(2.0)
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        last = -1
        try:
            while time.monotonic() < deadline:
                data = sock.recv(65536)
                if not data:
                    return  # the adapter stopped
                for m in mav.parse_buffer(data) or []:
                    if m.get_type() != "HIL_SENSOR":
                        continue
                    self.backwards += m.time_usec <= last
                    last = m.time_usec
                    self.times_us.append(last)
                    self.wall_s.append(time.monotonic())
                    self.steps += 1
                    sock.sendall(mav.hil_actuator_controls_encode(
                        m.time_usec, [self.controls] * 16, mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, 1).pack(mav))
        except OSError as err:  # reset by the adapter on its way out: fine
            self.error = str(err) if not isinstance(err, ConnectionError) else ""
        finally:
            sock.close()


def px4_pace(fmu: str | Path, speed: float | None, seconds: float) -> tuple[float, float, Any]:
    """(simulation seconds, wall seconds) a fake lockstep PX4 saw over ``seconds`` of answering, and the
    server's stats: the pace of a lockstep run at ``speed`` (None: unpaced)."""
    from hil_adapter.core import Plant, Watchdog
    from hil_adapter.px4 import Px4Server
    from hil_adapter.sensors import SensorConfig, SensorSuite

    plant = Plant(fmu)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0, dt_s=DT, speed=speed,
                    watchdog=Watchdog(timeout_s=2.0))
    client = LockstepPx4Client(srv.address[1], controls=0.0, max_s=seconds)
    try:
        with serving(srv):
            th = threading.Thread(target=client.run)
            th.start()
            th.join(timeout=seconds + 10)
    finally:
        srv.close()
        plant.close()
    if client.error or client.backwards or len(client.times_us) < 10:
        why = client.error or ("time went backwards" if client.backwards else "no steps")
        raise RuntimeError(f"fake PX4: {why}")
    first = 5  # after the first answers: the schedule is anchored at the first locked step
    sim = (client.times_us[-1] - client.times_us[first]) * 1e-6
    return sim, client.wall_s[-1] - client.wall_s[first], srv.stats


def json_pace(fmu: str | Path, speed: float | None, seconds: float) -> tuple[float, float, Any]:
    """(simulation seconds, wall seconds) a fake SITL saw over ``seconds`` of lockstep frames at 250 Hz, and
    the server's stats."""
    from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport
    from hil_adapter.core import Plant

    plant = Plant(fmu)
    srv = ArduPilotJsonServer(plant, UdpTransport("127.0.0.1", 0), speed=speed)
    times, walls = [], []
    try:
        with serving(srv, poll_s=0.05):
            sitl = FakeSitl(srv.transport.address, rate_hz=round(1 / DT))
            end = time.monotonic() + seconds
            k = 0
            while time.monotonic() < end:
                k += 1
                times.append(sitl.exchange(k, [1000] * 4)["timestamp"])
                walls.append(time.monotonic())
            sitl.sock.close()
    finally:
        srv.transport.close()
        plant.close()
    return times[-1] - times[0], walls[-1] - walls[0], srv.stats


class HeightFilter:
    """Third-order complementary filter (height up, vertical speed, accelerometer bias) on the vertical
    specific force, corrected by the barometer at every sample; the barometer's offset is pulled towards the
    GPS altitude with the time constant ``offset_tau_s`` (as PX4's EKF2 corrects baro height to GPS)."""

    def __init__(self, omega_rad_s: float = 2.0, offset_tau_s: float = 10.0) -> None:
        self.k1, self.k2, self.k3 = 3 * omega_rad_s, 3 * omega_rad_s ** 2, omega_rad_s ** 3
        self.offset_tau_s = offset_tau_s
        self.h: float | None = None
        self.v = self.bias = self.offset = 0.0
        self.baro_h = 0.0

    def predict(self, dt: float, q: tuple[float, float, float, float], accel_body: tuple[float, float, float]) -> None:
        w, x, y, z = q
        f_down = (2 * (x * z - w * y) * accel_body[0] + 2 * (y * z + w * x) * accel_body[1]
                  + (w * w - x * x - y * y + z * z) * accel_body[2])
        acc_up = -(f_down + G0_M_S2) - self.bias
        if self.h is None:
            return
        self.h += self.v * dt + 0.5 * acc_up * dt * dt
        self.v += acc_up * dt

    def baro(self, dt: float, pressure_alt_m: float) -> None:
        self.baro_h = pressure_alt_m
        if self.h is None:
            self.h = pressure_alt_m
            return
        err = (pressure_alt_m - self.offset) - self.h
        self.h += self.k1 * err * dt
        self.v += self.k2 * err * dt
        self.bias -= self.k3 * err * dt

    def gps(self, dt_fix: float, alt_m: float) -> None:
        self.offset += (self.baro_h - alt_m - self.offset) * min(dt_fix / self.offset_tau_s, 1.0)



def receive_step(sock: socket.socket, mav: mavlink2.MAVLink, pending: list) -> dict[str, object]:
    """The messages of one lockstep step as PX4 reads them, by type, up to its HIL_STATE_QUATERNION (the last one
    the adapter sends per step); ``pending`` keeps what was parsed beyond it for the next call."""
    got: dict[str, object] = {}
    while "HIL_STATE_QUATERNION" not in got:
        if not pending:
            pending += mav.parse_buffer(sock.recv(65536)) or []
            continue
        m = pending.pop(0)
        got[m.get_type()] = m
    return got


def fly_px4_altitude(server: Any, altitude_m: Callable[[float], float], seconds: float,
                     filt: HeightFilter | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fly the quadrotor through a lockstep ``Px4Server`` as a fake PX4 would: altitude reference
    ``altitude_m(t)`` held on the estimate of ``filt`` (a :class:`HeightFilter` by default) from the HIL_SENSOR
    and HIL_GPS messages; (times [s], true heights, estimated heights) above home, one per step."""
    from fmu_models.quadrotor.constants import N_MOTORS
    from hil_adapter.sensors import UPDATED_BARO

    home = server.plant.host.start_value("home_height_m")
    ap = QuadrotorAutopilot(altitude_m, published_thrust_inverse())
    filt = filt or HeightFilter()
    sock = socket.create_connection(server.address, timeout=5.0)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    times, truth, est, pending, sensor, last_fix, last_baro = [], [], [], [], None, None, None
    try:
        for k in range(round(seconds / server.dt_s)):
            got = receive_step(sock, mav, pending)
            sensor, state = got["HIL_SENSOR"], got["HIL_STATE_QUATERNION"]
            q = tuple(state.attitude_quaternion)
            filt.predict(server.dt_s, q, (sensor.xacc, sensor.yacc, sensor.zacc))
            if sensor.fields_updated & UPDATED_BARO == UPDATED_BARO:  # a new barometer reading (50 Hz)
                t_baro = sensor.time_usec * 1e-6
                filt.baro(t_baro - (last_baro if last_baro is not None else t_baro - server.dt_s), sensor.pressure_alt)
                last_baro = t_baro
            if "HIL_GPS" in got:
                fix = got["HIL_GPS"]
                filt.gps(0.2 if last_fix is None else (fix.time_usec - last_fix) * 1e-6, fix.alt * 1e-3)
                last_fix = fix.time_usec
            times.append(sensor.time_usec * 1e-6)
            truth.append(state.alt * 1e-3 - home)
            est.append(filt.h - filt.offset - home)
            v = (state.vx / 100.0, state.vy / 100.0, -filt.v)
            y = controller_inputs(q, (state.rollspeed, state.pitchspeed, state.yawspeed), est[-1], v)
            cmd = ap(k * server.dt_s, y)
            controls = [(cmd[f"pwm_{i}_us"] - 1000.0) / 1000.0 for i in range(1, N_MOTORS + 1)] + [0.0] * 12
            sock.sendall(mav.hil_actuator_controls_encode(state.time_usec, controls,
                                                          mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, 1).pack(mav))
    finally:
        sock.close()
    return np.array(times), np.array(truth), np.array(est)


def free_tcp_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def sigint_sessions(fmu: str, sessions: int, seed: int) -> int:
    """Run ``sessions`` lockstep PX4 sessions through ``hil_adapter.session.serve`` in this process's main
    thread, each stopped by a SIGINT at a random moment; prints one line per session and a total. Exit
    status 0 when every session ended with a summary and no client saw time go backwards."""
    import os
    import random
    import signal
    import time

    from hil_adapter.session import serve

    rng = random.Random(seed)
    bad = 0
    for k in range(sessions):
        port = free_tcp_port()
        client = LockstepPx4Client(port, controls=rng.choice([0.0, 0.3, 0.6]))
        delay = rng.uniform(0.0, 0.25)

        def interrupt(c: LockstepPx4Client = client, d: float = delay) -> None:
            if c.connected.wait(10.0):
                time.sleep(d)
            os.kill(os.getpid(), signal.SIGINT)

        threads = [threading.Thread(target=client.run), threading.Thread(target=interrupt)]
        for th in threads:
            th.start()
        result = serve(fmu, "px4", port=port)
        for th in threads:
            th.join(timeout=10)
        ok = (result.stopped_by == "signal SIGINT" and "steps" in result.summary and client.backwards == 0
              and not client.error and result.summary["sim_time_s"] > 0)
        bad += not ok
        print(f"session {k}: {'ok' if ok else 'FAILED'} stopped_by={result.stopped_by} steps={client.steps} "
              f"backwards={client.backwards} delay={delay:.3f}s {client.error}", flush=True)
    print(f"sigint sessions: {sessions}, failed: {bad}", flush=True)
    return 0 if bad == 0 else 1

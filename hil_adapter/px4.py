"""PX4 simulator interface: MAVLink 2 over TCP port 4560, PX4 connects as the client.

We send HIL_SENSOR (``fields_updated``: the IMU every step, magnetometer and barometer at their own rates),
HIL_GPS at the GPS rate, HIL_STATE_QUATERNION (ground truth), HEARTBEAT at 1 Hz and optionally RC_CHANNELS;
PX4 answers with HIL_ACTUATOR_CONTROLS (``controls[16]``:
motors 0..1, surfaces -1..1; ``mode`` carries the armed bit; ``flags`` bit 0 asks for lockstep).

Lockstep: send the sensors of time t, log the step, busy-poll then wait for the actuator reply, step the FMU,
repeat (the log row and the sinks run after the send, off PX4's critical path). Real time: step at
a fixed rate on the wall clock with the latest actuator controls, deadline scheduling, overruns counted.
A disconnect re-initialises the FMU and waits for the next connection. The same message builders serve the
generic MAVLink bridge (``hil_adapter.mavlink_bridge``).
"""

from __future__ import annotations

import logging
import math
import operator
import socket
import struct
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

from pymavlink.dialects.v20 import common as mavlink2

from fmu_models.common.atmosphere import G0_M_S2, eas_to_tas
from fmu_models.quadrotor.constants import N_MOTORS
from hil_adapter.core import BUSY_POLL_S, Pacer, Plant, Recorder, SimClockPacer, SocketSpinner, Stats, Watchdog
from hil_adapter.mavlink_fast import FastMavlink

log = logging.getLogger(__name__)
DEFAULT_PORT = 4560
ARMED_FLAG = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
LOCKSTEP_FLAG = 1  # HIL_ACTUATOR_CONTROLS.flags bit 0
#: a used control beyond this magnitude (PX4 sends -1..1, motors 0..1) makes the message malformed
CONTROL_LIMIT = 1.0 + 1e-6
MG_PER_M_S2 = 1000.0 / G0_M_S2  #: HIL_STATE_QUATERNION accelerations are in milli-g
#: fixed wing: which control index drives which output channel (PX4's classic roll, pitch, yaw, throttle group)
WING_CONTROLS = {1: 0, 2: 1, 3: 3, 4: 2}


#: the FMU outputs HIL_STATE_QUATERNION carries, fetched in one call
_STATE_OUTPUTS = operator.itemgetter(
    "quat_w", "quat_x", "quat_y", "quat_z", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
    "lat_deg", "lon_deg", "height_m", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s",
    "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2")


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if not math.isfinite(v) else min(max(v, lo), hi)


_MOTORS_OFF = dict.fromkeys(range(1, N_MOTORS + 1), 1000.0)


def controls_to_pwm(controls: Sequence[float], vehicle: str, armed: bool,
                    wing_controls: Mapping[int, int] | None = None) -> dict[int, float]:
    """PWM by output channel from normalised controls: motors/throttle 0..1 -> 1000..2000 us, surfaces
    -1..1 -> 1000..2000 us around 1500; unarmed: motors and throttle at 1000 us. ``wing_controls`` maps output
    channel -> control index for the fixed wing (default ``WING_CONTROLS``; channel 3 is the throttle)."""
    if vehicle == "quadrotor":
        if not armed:
            return dict(_MOTORS_OFF)
        c1, c2, c3, c4 = controls[:4]  # in range is the common case: one chained test each (NaN fails it)
        return {1: 1000.0 + 1000.0 * (c1 if 0.0 <= c1 <= 1.0 else _clip(c1, 0.0, 1.0)),
                2: 1000.0 + 1000.0 * (c2 if 0.0 <= c2 <= 1.0 else _clip(c2, 0.0, 1.0)),
                3: 1000.0 + 1000.0 * (c3 if 0.0 <= c3 <= 1.0 else _clip(c3, 0.0, 1.0)),
                4: 1000.0 + 1000.0 * (c4 if 0.0 <= c4 <= 1.0 else _clip(c4, 0.0, 1.0))}
    out = {}
    for ch, idx in (wing_controls or WING_CONTROLS).items():
        if ch == 3:
            out[ch] = 1000.0 + 1000.0 * (_clip(controls[idx], 0.0, 1.0) if armed else 0.0)
        else:
            out[ch] = 1500.0 + 500.0 * _clip(controls[idx], -1.0, 1.0)
    return out


def _int16(value: float) -> int:
    """``value`` rounded and saturated to a MAVLink int16 field."""
    return min(max(round(value), -32768), 32767)


def _uint16(value: float) -> int:
    """``value`` rounded and saturated to a MAVLink uint16 field."""
    return min(max(round(value), 0), 65535)


class HilMessages:
    """Builds the HIL_* messages of one time step from the FMU state and the sensor frame (framed by
    :class:`hil_adapter.mavlink_fast.FastMavlink` on ``mav``: sequence numbers advance per message)."""

    def __init__(self, mav: mavlink2.MAVLink, vehicle: str) -> None:
        self.mav = mav
        self.codec = FastMavlink(mav)
        self.mav_type = mavlink2.MAV_TYPE_QUADROTOR if vehicle == "quadrotor" else mavlink2.MAV_TYPE_FIXED_WING

    def sensor(self, t_us: int, frame: Any) -> bytes:
        a, g, m, pressure_pa, temp_c, diff_pa, pressure_alt_m, _, updated = frame  # a SensorFrame, in field order
        return self.codec.pack_wire(  # wire order: time_usec, 13 floats, fields_updated, id
            mavlink2.MAVLink_hil_sensor_message, t_us, a[0], a[1], a[2], g[0], g[1], g[2], m[0], m[1], m[2],
            pressure_pa / 100.0, diff_pa / 100.0, pressure_alt_m, temp_c, updated, 0)

    def gps(self, t_us: int, fix: Any) -> bytes:
        vn, ve, vd = fix.vel_ned_m_s
        return self.codec.pack(
            mavlink2.MAVLink_hil_gps_message, t_us, int(fix.fix_type), round(fix.lat_deg * 1e7),
            round(fix.lon_deg * 1e7), round(fix.alt_msl_m * 1e3), _uint16(fix.eph_m * 100), _uint16(fix.epv_m * 100),
            _uint16(fix.ground_speed_m_s * 100), _int16(vn * 100),
            _int16(ve * 100), _int16(vd * 100), round(fix.course_deg * 100) % 36000, int(fix.satellites))

    def state(self, t_us: int, s: Mapping[str, float]) -> bytes:
        """Ground truth; velocities [cm/s] and accelerations [mG] saturate at the int16 range (a crash
        landing can exceed 32 g)."""
        mg = MG_PER_M_S2
        qw, qx, qy, qz, p, q, r, lat, lon, height, vn, ve, vd, ax, ay, az = _STATE_OUTPUTS(s)
        tas = s.get("airspeed_m_s", 0.0)
        air = round(tas * 100)
        air = air if 0 <= air <= 65535 else min(max(air, 0), 65535)
        # indicated airspeed: the equivalent one at these speeds (the pitot reads rho, not rho_0: ArduPilot's and
        # PX4's airspeed sensors report it), the true one divided by EAS2TAS at the height [m AMSL]
        ind = round(air / eas_to_tas(float(height))) if air and -1e4 < height < 1e5 else air
        ind = ind if 0 <= ind <= 65535 else min(max(ind, 0), 65535)
        small = [round(vn * 100), round(ve * 100), round(vd * 100), round(ax * mg), round(ay * mg), round(az * mg)]
        for k, v in enumerate(small):  # in range is the common case: one chained test each
            if not -32768 <= v <= 32767:
                small[k] = min(max(v, -32768), 32767)
        vx, vy, vz, xacc, yacc, zacc = small
        return self.codec.pack_wire(  # wire order = declared order, the quaternion expanded
            mavlink2.MAVLink_hil_state_quaternion_message, t_us, qw, qx, qy, qz, p, q, r, round(lat * 1e7),
            round(lon * 1e7), round(height * 1e3), vx, vy, vz, ind, air, xacc, yacc, zacc)

    def heartbeat(self) -> bytes:
        return self.codec.pack(mavlink2.MAVLink_heartbeat_message, self.mav_type, mavlink2.MAV_AUTOPILOT_INVALID,
                               0, 0, mavlink2.MAV_STATE_ACTIVE, 3)

    def rc(self, t_ms: int, channels: Sequence[int]) -> bytes:
        ch = [int(c) for c in channels][:18] + [65535] * (18 - len(channels))
        return self.codec.pack(mavlink2.MAVLink_rc_channels_message, t_ms, len(channels), *ch, 255)


class Listener(Protocol):
    """Where PX4 connections come from: a listening TCP socket, or in tests anything that hands out one end of
    a ``socket.socketpair()``."""

    def accept(self) -> tuple[socket.socket, Any]: ...

    def settimeout(self, timeout: float | None) -> None: ...

    def getsockname(self) -> Any: ...

    def close(self) -> None: ...


def tcp_listener(host: str = "127.0.0.1", port: int = DEFAULT_PORT) -> socket.socket:
    """The TCP socket PX4 connects to (``host`` 127.0.0.1 unless told otherwise)."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind((host, port))
    server.listen(1)
    return server


class Px4Server:
    """Serve PX4 SITL/HIL over TCP. ``serve()`` handles connect, lockstep or real-time steps, disconnects."""

    def __init__(self, plant: Plant, sensors: Any, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 lockstep: bool = True, dt_s: float = 0.004, stats: Stats | None = None,
                 recorder: Recorder | None = None, watchdog: Watchdog | None = None,
                 rc_channels: Sequence[int] | None = None, listener: Listener | None = None,
                 wing_controls: Mapping[int, int] | None = None, busy_poll_s: float = BUSY_POLL_S,
                 speed: float | None = None) -> None:
        self.plant, self.sensors = plant, sensors

        #: lockstep: busy-poll this long [s] for the actuator reply before blocking (``core.SocketSpinner``)
        self.busy_poll_s = SocketSpinner.check(busy_poll_s)
        self.lockstep, self.dt_s = lockstep, dt_s
        self.stats = stats or Stats()
        #: lockstep: simulation seconds per wall second once PX4 answers (None: unpaced, ``--speed max``; the
        #: session's default is 1); before its first answer the steps run at this pace too (real time for None)
        self.pacer = SimClockPacer(speed, self.stats)
        #: called after every step with (t_s, FMU outputs): auxiliary outputs such as the NMEA GPS
        self.sinks: list[Callable[[float, Mapping[str, float]], None]] = []
        self.recorder = recorder
        self.watchdog = watchdog or Watchdog()
        self.rc_channels = list(rc_channels) if rc_channels else None
        self.wing_controls = dict(wing_controls) if wing_controls else None
        if self.wing_controls and not all(1 <= c <= 16 and 0 <= i < 16 for c, i in self.wing_controls.items()):
            raise ValueError(f"wing_controls {self.wing_controls}: channels 1..16 -> control indices 0..15")
        #: the control indices that drive an output (checked in every actuator message)
        self._used_controls = (tuple(range(4)) if plant.vehicle == "quadrotor"
                               else tuple((self.wing_controls or WING_CONTROLS).values()))
        self.server = listener if listener is not None else tcp_listener(host, port)
        self.address = self.server.getsockname()
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=51)
        self.mav.robust_parsing = True  # bad CRC / garbage become MAVLink_bad_data, counted, never raised
        self.msgs = HilMessages(self.mav, plant.vehicle)
        self.pwm: dict[int, float] = {}
        self.armed = False
        self.last_frame: Any = None
        self._last_heartbeat = -math.inf
        self._accepted: float | None = None

    def close(self) -> None:
        self.server.close()

    # ---------------------------------------------------------------- one connection
    def _send_step(self, conn: socket.socket, retry: bool = True) -> None:
        """Sensors of the current state out; outputs no message can hold restart the FMU (once: if even its
        start state cannot be sent, the step is logged and skipped, and the watchdog takes over)."""
        t_s = self.plant.t_s
        t_us = round(t_s * 1e6)
        frame = self.sensors.sample(t_s, self.plant.state, self.plant.imu)
        self.last_frame = frame
        try:
            data = self.msgs.sensor(t_us, frame) + self.msgs.state(t_us, self.plant.state)
            if frame.gps is not None:
                data += self.msgs.gps(t_us, frame.gps)
        except (struct.error, OverflowError) as err:  # outputs no MAVLink field holds: like an FMU error
            reason = f"t = {t_s:.6g} s: FMU outputs do not fit the HIL messages ({err})"
            if retry:
                self.plant.fail(reason)
                self._send_step(conn, retry=False)
            else:
                log.error("%s; not sent", reason)
            return
        if t_s - self._last_heartbeat >= 1.0:
            data += self.msgs.heartbeat()
            if self.rc_channels:
                data += self.msgs.rc(round(t_s * 1e3), self.rc_channels)
            self._last_heartbeat = t_s
        conn.sendall(data)
        if self._accepted is not None:  # the first state on a new connection: how long the (re)connect took
            self.stats.reconnect_s.append(time.perf_counter() - self._accepted)
            self._accepted = None

    def _absorb(self, data: bytes) -> bool:
        """Parse received bytes; True when an actuator message arrived."""
        got = False
        fast = self.msgs.codec.actuator_controls(data)  # the common case: one whole actuator frame
        if fast is not None:
            controls, mode, _flags, data = fast
            got = self._actuators(controls, mode)
            if not data:
                return got
        try:
            msgs = self.mav.parse_buffer(data) or []
        except mavlink2.MAVError as err:  # robust_parsing makes this rare; count, resynchronise, go on
            self.stats.malformed += 1
            log.debug("MAVLink parse error: %s", err)
            return got
        for m in msgs:
            kind = m.get_type()
            if kind == "BAD_DATA":
                self.stats.malformed += 1
            elif kind == "HIL_ACTUATOR_CONTROLS":
                got = self._actuators(m.controls, m.mode) or got
        return got

    def _actuators(self, controls: Sequence[float], mode: int) -> bool:
        """Take an actuator message; a malformed one (a used control non-finite or beyond +-1) is counted and
        dropped without touching the state. True when taken."""
        for i in self._used_controls:
            if not -CONTROL_LIMIT <= controls[i] <= CONTROL_LIMIT:  # also catches NaN
                self.stats.malformed += 1
                return False
        self.armed = bool(mode & ARMED_FLAG)
        self.pwm = controls_to_pwm(controls, self.plant.vehicle, self.armed, self.wing_controls)
        return True

    def _step(self) -> None:
        if self.pwm and not self.watchdog.tripped:
            self.plant.apply(self.pwm)
        self.plant.advance(self.dt_s)
        self.stats.step(self.plant.out_of_band, self.dt_s)

    def _after_send(self) -> None:
        """Bookkeeping of the state just sent, off the autopilot's critical path: the log row (PWM that led to
        it, FMU inputs and outputs, the sensor readings sent) and the sinks."""
        if self.recorder is not None:
            self.recorder.write(self.plant.t_s, self.pwm, self.plant.inputs, self.plant.state, self.watchdog.tripped,
                                self.last_frame, self.plant.out_of_band)
        for sink in self.sinks:
            sink(self.plant.t_s, self.plant.state)

    def _free_run(self, conn: socket.socket, pacer: Pacer) -> bool | None:
        """Before the first actuator message of a connection: take whatever arrived, without waiting for more,
        then keep the real-time pace (Gazebo's mavlink interface steps on at its real-time rate until PX4's
        first actuator message, then locks step). True when an actuator message arrived, None when the
        connection ended."""
        pacer.wait()
        conn.setblocking(False)
        try:
            return self._drain(conn)
        finally:
            conn.settimeout(self.watchdog.timeout_s)

    def _drain(self, conn: socket.socket) -> bool | None:
        """Take every byte waiting on the non-blocking ``conn``: True when an actuator message was among them,
        None when the connection ended."""
        got = False
        try:
            while True:
                data = conn.recv(65536)
                if not data:
                    return None
                got = self._absorb(data) or got
        except BlockingIOError:
            return got

    def _run_lockstep(self, conn: socket.socket, stop: threading.Event | None, max_steps: int | None) -> bool:
        """Returns False when the connection ended. Until the autopilot's first actuator message the steps run
        at the wall-clock pace without waiting for it (PX4 boots in seconds instead of a watchdog timeout per
        step), then in lockstep."""
        conn.settimeout(self.watchdog.timeout_s)
        spinner = SocketSpinner(conn, self.busy_poll_s)
        got_input: float | None = None
        speed = self.pacer.speed or 1.0  # the free run before PX4's first answer: real time unless a speed is set
        pacer: Pacer | None = Pacer(self.dt_s / speed, Stats())  # its overruns are not the lockstep loop's
        self.pacer.reset()
        while not (stop is not None and stop.is_set()) and (max_steps is None or self.stats.steps < max_steps):
            if pacer is None:
                self.pacer.wait(self.plant.t_s)  # hold the lockstep run to its speed factor
            t0 = time.perf_counter()
            self._send_step(conn)
            if got_input is not None:
                self.stats.busy.append(time.perf_counter() - got_input)
            self._after_send()
            if pacer is not None:
                started = self._free_run(conn, pacer)
                if started is None:
                    return False
                if not started:
                    self.stats.free_steps += 1
                    self._step()
                    continue
                pacer = None
                self.watchdog.fed()
                self._step()
                continue
            while True:
                spinner.wait()
                try:
                    data = conn.recv(65536)
                except TimeoutError:
                    if self.watchdog.check(self.plant, self.stats):
                        break  # step on with the failsafe inputs: the autopilot may be restarting
                    continue
                received = time.perf_counter()  # busy time counts from here: parsing is the adapter's work
                if not data:
                    return False
                if self._absorb(data):
                    got_input = received
                    self.watchdog.fed()
                    self.stats.latencies.append(got_input - t0)
                    break
            self._step()
        return True

    def _run_realtime(self, conn: socket.socket, stop: threading.Event | None, max_steps: int | None) -> bool:
        conn.setblocking(False)
        pacer = Pacer(self.dt_s, self.stats)
        while not (stop is not None and stop.is_set()) and (max_steps is None or self.stats.steps < max_steps):
            t0 = time.perf_counter()
            got = self._drain(conn)
            if got is None:
                return False
            if got:
                self.watchdog.fed()
            self.watchdog.check(self.plant, self.stats)
            self._step()
            try:
                self._send_step(conn)
            except BlockingIOError:
                self.stats.dropped += 1
            self._after_send()
            self.stats.busy.append(time.perf_counter() - t0)
            pacer.wait()
        return True

    def serve(self, stop: threading.Event | None = None, max_steps: int | None = None,
              accept_timeout_s: float | None = None) -> Stats:
        """Accept PX4, run until ``stop``/``max_steps``; on a disconnect restart the FMU (the clock goes on: the
        record stays one continuous log) and accept again."""
        self.server.settimeout(0.2)
        self.plant.clock_at_least(self.dt_s)  # the first HIL_SENSOR carries a positive time
        waited = 0.0
        while not (stop is not None and stop.is_set()) and (max_steps is None or self.stats.steps < max_steps):
            try:
                conn, addr = self.server.accept()
            except TimeoutError:
                waited += 0.2
                if accept_timeout_s is not None and waited >= accept_timeout_s:
                    break
                continue
            waited = 0.0
            log.info("PX4 connected from %s", addr)
            if conn.family in (socket.AF_INET, socket.AF_INET6):
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.watchdog.fed()
            self._accepted = time.perf_counter()
            try:
                run = self._run_lockstep if self.lockstep else self._run_realtime
                ended = not run(conn, stop, max_steps)
            except (ConnectionError, OSError) as err:
                log.warning("PX4 connection lost: %s", err)
                ended = True
            finally:
                conn.close()
            if ended:
                self._reconnecting()
        return self.stats

    def _reconnecting(self) -> None:
        """PX4 went away: a fresh FMU start state (on the same, continuing clock) and parser for the next one."""
        self.stats.reconnects += 1
        self.plant.restart()
        self.plant.clock_at_least(self.plant.t_s + self.dt_s)  # the new connection's first time is a new one
        self.pwm, self.armed = {}, False
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=51)
        self.mav.robust_parsing = True
        self.msgs = HilMessages(self.mav, self.plant.vehicle)
        self._last_heartbeat = -math.inf

"""ArduPilot SITL JSON backend: servo packets in over UDP (port 9002), a JSON state per frame back.

SITL drives the clock (lockstep by construction): every servo frame advances the FMU by ``1/frame_rate``.
A repeated ``frame_count`` is a resend (answered with the last state, no step); one slightly below the last
(within ``REORDER_WINDOW``) is a late datagram and is dropped; a count back at 0 or 1, or far below the last,
means SITL restarted (the FMU restarts; the new SITL process is sent time since its own start, as SIM_JSON
adds each timestamp step to its clock, while the plant's clock and the record go on). Malformed datagrams
(layout, frame rate, a mapped PWM out of range such as 0, a frame_count leap) are counted and dropped before
they change anything.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from fmu_models.signals.pwm_mapping import MappingError
from hil_adapter.core import BUSY_POLL_S, Plant, Recorder, SimClockPacer, SocketSpinner, Stats
from hil_adapter.packets import PacketError, ServoPacket, json_state

log = logging.getLogger(__name__)
DEFAULT_PORT = 9002
#: a frame_count at most this far below the last one is a late (reordered) datagram, not a SITL restart
REORDER_WINDOW = 8
#: SITL frame rates we accept [Hz] (ArduPilot runs 50..8000 Hz physics; 0 is rejected by the packet parser)
FRAME_RATE_HZ = (10, 10000)
#: a frame_count more than this far ahead of the last one is malformed, not packet loss (10 s at 1 kHz)
MAX_FRAME_GAP = 10000


class DatagramTransport(Protocol):
    def recv(self, timeout_s: float) -> tuple[bytes, Any] | None: ...

    def send(self, data: bytes, addr: Any) -> None: ...

    def close(self) -> None: ...


class UdpTransport:
    """A UDP socket bound to ``host:port`` (127.0.0.1 unless told otherwise); each receive busy-polls for
    ``busy_poll_s`` [s] before it blocks (:class:`hil_adapter.core.SocketSpinner`; 0 turns it off)."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, busy_poll_s: float = BUSY_POLL_S) -> None:
        SocketSpinner.check(busy_poll_s)  # before the socket is bound
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.address = self.sock.getsockname()
        self.spinner = SocketSpinner(self.sock, busy_poll_s)
        self._timeout_s: float | None = None

    def recv(self, timeout_s: float) -> tuple[bytes, Any] | None:
        if timeout_s != self._timeout_s:  # settimeout costs system calls: only when it changes
            self.sock.settimeout(timeout_s)
            self._timeout_s = timeout_s
        self.spinner.wait(timeout_s)
        try:
            return self.sock.recvfrom(65536)
        except (TimeoutError, BlockingIOError):
            return None

    def send(self, data: bytes, addr: Any) -> None:
        try:
            self.sock.sendto(data, addr)
        except OSError as err:  # the other side went away: SITL will resend or reconnect
            log.warning("reply to %s failed: %s", addr, err)

    def close(self) -> None:
        self.sock.close()


class ArduPilotJsonServer:
    """Serve one SITL instance from ``plant``; ``handle`` is the per-datagram logic (the reply), ``after_reply``
    the bookkeeping done once the reply is out."""

    def __init__(self, plant: Plant, transport: DatagramTransport, stats: Stats | None = None,
                 recorder: Recorder | None = None, sensors: Any = None, speed: float | None = None) -> None:
        self.plant, self.transport = plant, transport
        self.stats = stats or Stats()
        #: simulation seconds per wall second: each reply to a new frame waits for its time on this schedule
        #: (None: unpaced, ``--speed max``; the session's default is 1). SITL paces itself too, to its own
        #: ``--speedup`` (``Aircraft::time_advance`` -> ``sync_frame_time``): the slower of the two sets the pace
        self.pacer = SimClockPacer(speed, self.stats)
        #: called after every step with (t_s, FMU outputs): auxiliary outputs such as the NMEA GPS
        self.sinks: list[Callable[[float, Mapping[str, float]], None]] = []
        self.recorder, self.sensors = recorder, sensors
        self.last_count: int | None = None
        #: the output channels the PWM mapping reads: the only ones decoded per frame
        self._sources = sorted({c.source for c in plant.mapping.channels})
        self.last_reply = b""
        #: the sensor frame of the last reply (when ``sensors`` is set), for the log
        self.last_frame: Any = None
        self._stepped_pwm: dict[int, float] | None = None
        #: where the current SITL process's clock began on the plant's clock [s]: a restarted SITL starts its
        #: own clock again and adds every timestamp step to it, so it is sent time since its start; the
        #: plant's clock (and the record) goes on
        self.sitl_epoch_s = plant.t_s

    def reply(self) -> bytes:
        s = self.plant.state
        if self.plant.imu is not None:  # what a real IMU reports: the means over the frame's interval
            accel, gyro = self.plant.imu
        else:  # a start state: no interval yet
            gyro = (s["rate_body_x_rad_s"], s["rate_body_y_rad_s"], s["rate_body_z_rad_s"])
            accel = (s["accel_body_x_m_s2"], s["accel_body_y_m_s2"], s["accel_body_z_m_s2"])
        if self.sensors is not None:  # noisy IMU (SITL adds its own noise model on top if configured)
            self.last_frame = self.sensors.sample(self.plant.t_s, s, self.plant.imu)
            gyro, accel = self.last_frame.gyro_body_rad_s, self.last_frame.accel_body_m_s2
        return json_state(self.plant.t_s - self.sitl_epoch_s, gyro, accel,
                          [s["pos_north_m"], s["pos_east_m"], s["pos_down_m"]],
                          [s["vel_north_m_s"], s["vel_east_m_s"], s["vel_down_m_s"]],
                          [s["quat_w"], s["quat_x"], s["quat_y"], s["quat_z"]],
                          s.get("airspeed_m_s") if self.plant.has_airspeed else None)

    def handle(self, data: bytes) -> bytes | None:
        """One datagram in, the reply out (None for a malformed or late one).

        The whole packet is checked before anything changes: a malformed one (bad layout, frame rate outside
        ``FRAME_RATE_HZ``, a mapped PWM outside the plausible range, e.g. 0, or a frame_count jump beyond
        ``MAX_FRAME_GAP``) is counted and dropped with no reset, no step and no other counter touched."""
        try:
            pkt = ServoPacket.unpack(data)
            if not FRAME_RATE_HZ[0] <= pkt.frame_rate_hz <= FRAME_RATE_HZ[1]:
                raise PacketError(f"frame_rate {pkt.frame_rate_hz} Hz outside {FRAME_RATE_HZ[0]}..{FRAME_RATE_HZ[1]}")
            pwm = {s: float(pkt.pwm_us[s - 1]) for s in self._sources if s <= len(pkt.pwm_us)}
            inputs = self.plant.check(pwm)
            last = self.last_count
            if last is not None and pkt.frame_count > last + MAX_FRAME_GAP:
                raise PacketError(f"frame_count jumps from {last} to {pkt.frame_count}")
        except (PacketError, MappingError) as err:
            self.stats.malformed += 1
            log.debug("malformed servo packet (%d bytes): %s", len(data), err)
            return None
        if last is not None and pkt.frame_count == last:
            self.stats.resends += 1
            return self.last_reply
        if last is not None and 1 < pkt.frame_count < last and last - pkt.frame_count <= REORDER_WINDOW:
            self.stats.out_of_order += 1  # a late datagram: its frame was answered or skipped already
            return None
        if last is not None and pkt.frame_count < last:
            log.info("frame_count went from %d to %d: SITL restarted, restarting the FMU (the clock goes on)",
                     last, pkt.frame_count)
            self.stats.restarts += 1
            self.plant.restart()
            self.sitl_epoch_s = self.plant.t_s
        elif last is not None:
            self.stats.dropped += pkt.frame_count - last - 1
        self.plant.inputs = inputs
        self.last_count = pkt.frame_count
        self.plant.advance(1.0 / pkt.frame_rate_hz)
        self.stats.step(self.plant.out_of_band, 1.0 / pkt.frame_rate_hz)
        self._stepped_pwm = pwm
        try:
            self.last_reply = self.reply()
        except PacketError as err:  # outputs SITL cannot take: like an FMU error, restart the simulation
            self.plant.fail(f"t = {self.plant.t_s:.6g} s: {err}")
            try:
                self.last_reply = self.reply()
            except PacketError as again:  # not even the start state: no reply, SITL resends
                log.error("FMU start state cannot be sent either: %s", again)
                return None
        return self.last_reply

    def after_reply(self) -> None:
        """Bookkeeping of the frame just answered, off SITL's critical path: the log row (PWM in, FMU inputs and
        outputs, the IMU readings sent when ``sensors`` is set) and the sinks. Nothing for a resend."""
        pwm, self._stepped_pwm = self._stepped_pwm, None
        if pwm is None:
            return
        if self.recorder is not None:
            self.recorder.write(self.plant.t_s, pwm, self.plant.inputs, self.plant.state, sensors=self.last_frame,
                                 out_of_band=self.plant.out_of_band)
        for sink in self.sinks:
            sink(self.plant.t_s, self.plant.state)

    def serve(self, stop: threading.Event | None = None, max_frames: int | None = None,
              idle_timeout_s: float | None = None, poll_s: float = 0.1) -> Stats:
        """Answer frames until ``stop`` is set, ``max_frames`` were stepped, or ``idle_timeout_s`` passes."""
        idle_since = time.perf_counter()
        while not (stop is not None and stop.is_set()):
            if max_frames is not None and self.stats.steps >= max_frames:
                break
            got = self.transport.recv(poll_s)
            if got is None:
                if idle_timeout_s is not None and time.perf_counter() - idle_since > idle_timeout_s:
                    break
                continue
            t0 = time.perf_counter()
            idle_since = t0
            data, addr = got
            stepped = self.stats.steps
            out = self.handle(data)
            if out is not None:
                if self.stats.steps != stepped:  # a new frame (not a resend): its reply waits for its time
                    paced = time.perf_counter()
                    self.pacer.wait(self.plant.t_s)
                    t0 += time.perf_counter() - paced  # the wait is neither latency nor adapter work
                self.transport.send(out, addr)
                busy = time.perf_counter() - t0
                self.stats.latencies.append(busy)
                self.stats.busy.append(busy)
            self.after_reply()
        return self.stats

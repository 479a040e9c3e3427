"""Generic MAVLink HIL for bench autopilots over UDP or serial: SERVO_OUTPUT_RAW (PWM) in, HIL_* out.

The autopilot runs its own clock, so the bridge runs in real time: every ``dt_s`` it steps the FMU with the
latest servo outputs and sends HIL_SENSOR, HIL_STATE_QUATERNION and (at the GPS rate) HIL_GPS, with a
HEARTBEAT each second. The connection is any pymavlink ``mavutil`` connection string
(``udpin:127.0.0.1:14560``, ``udpout:...``, ``/dev/ttyACM0``); tests pass an in-memory pair.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from pymavlink import mavutil

from fmu_models.signals.pwm_mapping import MappingError
from hil_adapter.core import Pacer, Plant, Recorder, Stats, Watchdog
from hil_adapter.px4 import HilMessages

log = logging.getLogger(__name__)


class MavConnection(Protocol):
    """What the bridge needs of a pymavlink connection."""

    mav: Any

    def recv_match(self, type: Any = None, blocking: bool = False, timeout: float | None = None) -> Any: ...

    def write(self, buf: bytes) -> Any: ...

    def close(self) -> None: ...


def connect(url: str, baud: int = 57600) -> MavConnection:
    """A pymavlink connection; UDP servers default to 127.0.0.1 (``udpin:127.0.0.1:port``)."""
    return mavutil.mavlink_connection(url, baud=baud, source_system=1, source_component=51, dialect="common")


def servo_pwm(msg: Any) -> dict[int, float]:
    """PWM by output channel from a SERVO_OUTPUT_RAW message (channels 9-16 only when non-zero)."""
    out = {}
    for k in range(1, 17):
        v = getattr(msg, f"servo{k}_raw", 0)
        if v:
            out[k] = float(v)
    return out


class MavlinkBridge:
    def __init__(self, plant: Plant, sensors: Any, conn: MavConnection, dt_s: float = 0.004,
                 stats: Stats | None = None, recorder: Recorder | None = None,
                 watchdog: Watchdog | None = None) -> None:
        self.plant, self.sensors, self.conn, self.dt_s = plant, sensors, conn, dt_s
        self.stats = stats or Stats()
        #: called after every step with (t_s, FMU outputs): auxiliary outputs such as the NMEA GPS
        self.sinks: list[Callable[[float, Mapping[str, float]], None]] = []
        self.recorder = recorder
        self.watchdog = watchdog or Watchdog()
        self.msgs = HilMessages(conn.mav, plant.vehicle)
        self.pwm: dict[int, float] = {}
        self._last_heartbeat = -math.inf

    def _receive(self) -> None:
        while True:
            try:
                msg = self.conn.recv_match(blocking=False)
            except (OSError, ValueError) as err:  # a garbled stream or a vanished port: count and carry on
                self.stats.malformed += 1
                log.debug("MAVLink receive error: %s", err)
                return
            if msg is None:
                return
            kind = msg.get_type()
            if kind == "BAD_DATA":
                self.stats.malformed += 1
            elif kind == "SERVO_OUTPUT_RAW":
                pwm = servo_pwm(msg)
                try:
                    self.plant.apply(pwm)
                except MappingError as err:
                    self.stats.malformed += 1
                    log.warning("servo outputs rejected: %s", err)
                    continue
                self.pwm = pwm
                self.watchdog.fed()

    def step(self) -> None:
        """Receive what arrived, step the FMU once, send the sensors."""
        self._receive()
        self.watchdog.check(self.plant, self.stats)
        self.plant.advance(self.dt_s)
        self.stats.step(self.plant.out_of_band, self.dt_s)
        t_s = self.plant.t_s
        t_us = round(t_s * 1e6)
        frame = self.sensors.sample(t_s, self.plant.state, self.plant.imu)
        out = [self.msgs.sensor(t_us, frame), self.msgs.state(t_us, self.plant.state)]
        if frame.gps is not None:
            out.append(self.msgs.gps(t_us, frame.gps))
        if t_s - self._last_heartbeat >= 1.0:
            out.append(self.msgs.heartbeat())
            self._last_heartbeat = t_s
        try:
            self.conn.write(b"".join(out))
        except OSError as err:
            self.stats.dropped += 1
            log.debug("send failed: %s", err)
        if self.recorder is not None:
            self.recorder.write(t_s, self.pwm, self.plant.inputs, self.plant.state, self.watchdog.tripped, frame,
                                 self.plant.out_of_band)
        for sink in self.sinks:
            sink(self.plant.t_s, self.plant.state)

    def serve(self, stop: threading.Event | None = None, max_steps: int | None = None) -> Stats:
        """Real-time loop with deadline scheduling; overruns counted, no catch-up bursts."""
        pacer = Pacer(self.dt_s, self.stats)
        while not (stop is not None and stop.is_set()) and (max_steps is None or self.stats.steps < max_steps):
            t0 = time.perf_counter()
            self.step()
            self.stats.latencies.append(time.perf_counter() - t0)
            self.stats.busy.append(time.perf_counter() - t0)
            pacer.wait()
        return self.stats

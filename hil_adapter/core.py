"""What every simulator interface shares: the FMU plant, statistics, the crash-safe recorder, the watchdog.

The plant drives the FMU only through FMI (FMPy's FMU2Slave, via ``fmu_models.fmi.host``): PWM in through the
PWM mapping, outputs by name out. An FMU error never propagates: it is counted, logged, and the FMU is
re-initialised at its start state, as a bench operator would restart the simulation.
"""

from __future__ import annotations

import csv
import logging
import math
import select
import socket
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from fmu_models.fmi.host import FmuHost, FmuRunError
from fmu_models.signals.names import OUTPUT_TO_LOG
from fmu_models.signals.pwm_mapping import MappingError, PwmMapping, default_mapping

log = logging.getLogger(__name__)

#: FMU outputs every interface needs (both of our FMUs have them)
STATE_OUTPUTS = (
    "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "rate_body_x_rad_s", "rate_body_y_rad_s",
    "rate_body_z_rad_s", "quat_w", "quat_x", "quat_y", "quat_z", "roll_rad", "pitch_rad", "yaw_rad",
    "pos_north_m", "pos_east_m", "pos_down_m", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s",
    "lat_deg", "lon_deg", "height_m", "altitude_m",
)
OPTIONAL_OUTPUTS = ("airspeed_m_s",)
#: lockstep default of the busy poll before a blocking receive [s]; see :class:`SocketSpinner`
BUSY_POLL_S = 0.0005


class SocketSpinner:
    """Polls one socket without sleeping for up to ``spin_s`` [s] before the caller's blocking receive.

    Written here because nothing covers it for local sockets: the kernel's SO_BUSY_POLL serves NIC queues
    only. In lockstep the autopilot answers within microseconds, but a core that sleeps in ``recv`` (and on
    a virtual machine, its virtual CPU) takes tens to hundreds of microseconds to wake and then runs the
    step with cold caches; spinning briefly first keeps the step hot. After ``spin_s`` the blocking wait
    takes over, so a stalled autopilot costs no more CPU than ``spin_s`` per step. The poll object is made
    once per socket, not per step.
    """

    def __init__(self, sock: socket.socket, spin_s: float) -> None:
        self.spin_s = self.check(spin_s)
        self._sock = sock
        self._poller = None
        if hasattr(select, "poll"):  # no FD_SETSIZE limit; Windows falls back to select() on sockets
            self._poller = select.poll()
            self._poller.register(sock, select.POLLIN)

    @staticmethod
    def check(spin_s: float) -> float:
        """``spin_s`` if it is a valid busy-poll time, else ``ValueError`` naming it and the range."""
        if not 0.0 <= spin_s <= 0.1:
            raise ValueError(f"busy_poll_s = {spin_s}; allowed 0..0.1 s")
        return spin_s

    def _ready(self) -> bool:
        if self._poller is not None:
            return bool(self._poller.poll(0))
        return bool(select.select([self._sock], [], [], 0.0)[0])

    def wait(self, limit_s: float | None = None) -> bool:
        """Spin for at most ``spin_s`` (and ``limit_s``) [s]; True as soon as data is waiting."""
        spin_s = self.spin_s if limit_s is None else min(self.spin_s, limit_s)
        if spin_s <= 0.0:
            return False
        end = time.perf_counter() + spin_s
        while not self._ready():
            if time.perf_counter() >= end:
                return False
        return True


class Plant:
    """The FMU behind the adapter: ``apply(pwm)`` then ``advance(dt)``; restarts itself after an FMU error."""

    def __init__(self, fmu: str | Path, mapping: PwmMapping | None = None,
                 start_values: Mapping[str, float] | None = None) -> None:
        self.host = FmuHost(fmu, instance_name="hil")
        names = set(self.host.variables)
        try:
            self.vehicle = self.host.vehicle
        except FmuRunError:
            self.host.close()
            raise
        self.mapping = mapping or default_mapping(self.vehicle)
        missing = [c.target for c in self.mapping.channels if c.target not in names]
        if missing:
            self.host.close()
            raise MappingError(f"PWM mapping targets {', '.join(missing)} are not inputs of {self.host.path.name}")
        self.outputs = tuple(n for n in STATE_OUTPUTS + OPTIONAL_OUTPUTS if n in names)
        self.start_values = dict(start_values or {})
        self.inputs: dict[str, float] = {c.target: c.failsafe for c in self.mapping.channels}
        self.fmu_errors = 0
        self.last_error = ""
        #: wall time of each FMU step (setReal + doStep + getReal) [s], for the statistics
        self.step_times: deque[float] = deque(maxlen=20000)
        self.restart()

    @property
    def has_airspeed(self) -> bool:
        return "airspeed_m_s" in self.outputs

    def restart(self) -> None:
        """Back to the start state at t = 0 (SITL restarted, or after an FMU error)."""
        self.t_s = 0.0
        self.host.start(self.start_values)
        self.state = self.host.get(self.outputs)

    def apply(self, pwm_us: Mapping[int, float], failsafe: bool = False) -> dict[str, float]:
        """FMU inputs from PWM by output channel (1-based); a bad pulse raises ``MappingError``."""
        self.inputs = self.mapping.apply(pwm_us, failsafe=failsafe)
        return self.inputs

    def advance(self, dt_s: float) -> dict[str, float]:
        """One FMU step of ``dt_s`` with the current inputs; returns the outputs by name."""
        t0 = time.perf_counter()
        try:
            self.host.step(self.t_s, dt_s, self.inputs)
            self.t_s += dt_s
            self.state = self.host.get(self.outputs)
            self.step_times.append(time.perf_counter() - t0)
        except FmuRunError as err:
            self.fail(str(err))
        return self.state

    def fail(self, reason: str) -> None:
        """The FMU failed (or gave outputs no interface can send): count, log, restart from the start state."""
        self.fmu_errors += 1
        self.last_error = reason
        log.error("FMU error, restarting the simulation: %s", reason)
        self.restart()

    def close(self) -> None:
        self.host.close()


@dataclass
class Stats:
    """Live counters of an adapter run; latencies in seconds."""

    steps: int = 0
    overruns: int = 0
    dropped: int = 0
    malformed: int = 0
    resends: int = 0
    out_of_order: int = 0
    restarts: int = 0
    reconnects: int = 0
    failsafes: int = 0
    started: float = field(default_factory=time.perf_counter)
    latencies: deque[float] = field(default_factory=lambda: deque(maxlen=20000))
    #: adapter busy time per step [s]: from the autopilot's input to our reply sent (FMU step included)
    busy: deque[float] = field(default_factory=lambda: deque(maxlen=20000))

    def percentile(self, q: float) -> float:
        if not self.latencies:
            return math.nan
        s = sorted(self.latencies)
        return s[min(len(s) - 1, int(q / 100.0 * len(s)))]

    @property
    def rate_hz(self) -> float:
        return self.steps / max(time.perf_counter() - self.started, 1e-9)

    def summary(self, plant: Plant | None = None) -> dict[str, Any]:
        busy = 1e3 * sum(self.busy) / len(self.busy) if self.busy else math.nan
        out = {"steps": self.steps, "step_rate_hz": round(self.rate_hz, 1), "busy_mean_ms": round(busy, 4),
               "latency_p50_ms": round(1e3 * self.percentile(50), 4),
               "latency_p99_ms": round(1e3 * self.percentile(99), 4),
               "overruns": self.overruns, "dropped": self.dropped, "malformed": self.malformed,
               "resends": self.resends, "out_of_order": self.out_of_order, "restarts": self.restarts,
               "reconnects": self.reconnects, "failsafes": self.failsafes}
        if plant is not None:
            fmu = 1e3 * sum(plant.step_times) / len(plant.step_times) if plant.step_times else math.nan
            out |= {"sim_time_s": round(plant.t_s, 3), "fmu_step_mean_ms": round(fmu, 4),
                    "fmu_errors": plant.fmu_errors}
        return out

    def line(self, plant: Plant | None = None) -> str:
        s = self.summary(plant)
        return (f"t={s.get('sim_time_s', 0):8.2f}s steps={s['steps']} rate={s['step_rate_hz']:.0f}/s "
                f"rtt p50={s['latency_p50_ms']:.3f}ms p99={s['latency_p99_ms']:.3f}ms overruns={s['overruns']} "
                f"dropped={s['dropped']} malformed={s['malformed']} fmu_errors={s.get('fmu_errors', 0)}")


#: sensor readings sent to the autopilot, recorded beside the FMU's true outputs
SENSOR_COLUMNS = ("sens_accel_x_m_s2", "sens_accel_y_m_s2", "sens_accel_z_m_s2", "sens_gyro_x_rad_s",
                  "sens_gyro_y_rad_s", "sens_gyro_z_rad_s", "sens_mag_x_gauss", "sens_mag_y_gauss",
                  "sens_mag_z_gauss", "sens_abs_pressure_pa", "sens_diff_pressure_pa", "sens_temperature_degc")


def sensor_values(frame: Any) -> tuple[float, ...]:
    """A sensor frame (``hil_adapter.sensors.SensorFrame``) in the order of ``SENSOR_COLUMNS``."""
    return (*frame.accel_body_m_s2, *frame.gyro_body_rad_s, *frame.mag_body_gauss, frame.abs_pressure_pa,
            frame.diff_pressure_pa, frame.temperature_degc)


class Recorder:
    """Every step's PWM in, FMU inputs and outputs, as a CSV log the project's readers read back.

    Each row is flushed as it is written, so a crash or Ctrl-C loses at most the row being written.
    """

    def __init__(self, path: str | Path, channels: Sequence[int], inputs: Sequence[str], outputs: Sequence[str]):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: TextIO = self.path.open("w", newline="", buffering=1)
        self._w = csv.writer(self._fh)
        self.channels, self.inputs, self.outputs = list(channels), list(inputs), list(outputs)
        self._w.writerow(["time_s", *(f"servo_{c}_pwm_us" for c in self.channels), *self.inputs,
                          *(OUTPUT_TO_LOG.get(o, o) for o in self.outputs), "failsafe", *SENSOR_COLUMNS])
        self.rows = 0

    def write(self, t_s: float, pwm_us: Mapping[int, float], inputs: Mapping[str, float],
              outputs: Mapping[str, float], failsafe: bool = False, sensors: Any = None) -> None:
        """One row; ``sensors`` is the sensor frame sent this step (NaN columns when none was sent)."""
        sens = sensor_values(sensors) if sensors is not None else (math.nan,) * len(SENSOR_COLUMNS)
        self._w.writerow([repr(t_s), *(repr(float(pwm_us.get(c, math.nan))) for c in self.channels),
                          *(repr(float(inputs[n])) for n in self.inputs),
                          *(repr(float(outputs[n])) for n in self.outputs), int(failsafe), *map(repr, sens)])
        self.rows += 1

    def close(self) -> None:
        self._fh.close()


class Pacer:
    """Real-time pacing with deadline scheduling: ``wait()`` sleeps until the next period; a missed deadline
    counts an overrun and restarts the schedule from now (no catch-up bursts)."""

    def __init__(self, period_s: float, stats: Stats) -> None:
        self.period_s, self.stats = period_s, stats
        self.next_t = time.perf_counter()

    def wait(self) -> None:
        self.next_t += self.period_s
        delay = self.next_t - time.perf_counter()
        if delay < 0:
            self.stats.overruns += 1
            self.next_t = time.perf_counter()
        else:
            time.sleep(delay)


@dataclass
class Watchdog:
    """Input watchdog: after ``timeout_s`` of wall time without actuator input, the failsafe applies.

    ``mode`` ``hold`` keeps the last inputs; ``throttle_off`` sets every channel's failsafe value (motors
    and throttle off, surfaces at their failsafe).
    """

    timeout_s: float = 0.5
    mode: str = "throttle_off"
    last_input: float = field(default_factory=time.perf_counter)
    tripped: bool = False

    def __post_init__(self) -> None:
        if self.mode not in ("hold", "throttle_off"):
            raise ValueError(f"watchdog mode {self.mode!r}; allowed: hold, throttle_off")
        if not self.timeout_s > 0:
            raise ValueError(f"watchdog timeout {self.timeout_s} s; allowed: > 0")

    def fed(self) -> None:
        self.last_input = time.perf_counter()
        self.tripped = False

    def check(self, plant: Plant, stats: Stats) -> bool:
        """True while the failsafe is active; applies it once when the timeout passes."""
        if time.perf_counter() - self.last_input < self.timeout_s:
            return False
        if not self.tripped:
            self.tripped = True
            stats.failsafes += 1
            log.warning("no actuator input for %.2f s: failsafe (%s)", self.timeout_s, self.mode)
            if self.mode == "throttle_off":
                plant.apply({}, failsafe=True)
        return True

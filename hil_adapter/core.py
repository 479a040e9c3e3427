"""What every simulator interface shares: the FMU plant, statistics, the crash-safe recorder, the watchdog.

The plant drives the FMU only through FMI (FMPy's FMU2Slave, via ``fmu_models.fmi.host``): PWM in through the
PWM mapping, outputs by name out. An FMU error never propagates: it is counted, logged, and the FMU instance is
freed and instantiated afresh at its start state (never ``fmi2Reset`` after a failed call: FMI 2.0 allows
nothing but ``fmi2FreeInstance`` after ``fmi2Fatal``), as a bench operator would restart the simulation.
Simulation time never goes backwards: after any restart the clock the autopilot sees continues from the last
time sent (the FMU's own clock starts at 0 again; ``Plant.t_s`` = ``epoch_s`` + the FMU's time).
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
from hil_adapter.config import SPEED_RANGE
from hil_adapter.sensors import GRAVITY_OUTPUT, Vec3, interval_imu

log = logging.getLogger(__name__)

#: FMU outputs every interface needs (both of our FMUs have them)
STATE_OUTPUTS = (
    "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "rate_body_x_rad_s", "rate_body_y_rad_s",
    "rate_body_z_rad_s", "quat_w", "quat_x", "quat_y", "quat_z", "roll_rad", "pitch_rad", "yaw_rad",
    "pos_north_m", "pos_east_m", "pos_down_m", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s",
    "lat_deg", "lon_deg", "height_m", "altitude_m",
)
OPTIONAL_OUTPUTS = ("airspeed_m_s", GRAVITY_OUTPUT)
#: FMU output flagging PWM above idle outside the thrust map's trained band (quadrotor)
OUT_OF_BAND_OUTPUT = "thrust_map_out_of_range"
#: a pause in stepping longer than this [s] (waiting for the autopilot, reconnecting) is not stepping time
IDLE_GAP_S = 0.25
#: lockstep default of the busy poll before a blocking receive [s]; see :class:`SocketSpinner`
BUSY_POLL_S = 0.0005
#: a lockstep run further behind its schedule than this [s] starts the schedule again from now (no burst)
MAX_LAG_S = 0.25


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
    """The FMU behind the adapter: ``apply(pwm)`` then ``advance(dt)``; re-instantiates itself after an FMU error.

    ``t_s`` [s] is the simulation time the autopilot sees: it starts at ``start_time_s`` and never goes back,
    across restarts (``epoch_s`` is where the current FMU run began on that clock). ``imu`` is what a real IMU
    reports for the last step (mean specific force and body rate over it, ``sensors.interval_imu``); None at a
    start state (no interval yet: the sensors read the outputs as they are).
    """

    def __init__(self, fmu: str | Path, mapping: PwmMapping | None = None,
                 start_values: Mapping[str, float] | None = None, start_time_s: float = 0.0) -> None:
        if not (math.isfinite(start_time_s) and 0.0 <= start_time_s <= 1.0):
            raise ValueError(f"start_time_s = {start_time_s}; allowed 0..1 s")
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
        #: the FMU's Boolean out-of-band flag, read beside the Real outputs (None when the FMU has none)
        self._oob_vr = self.host.refs([OUT_OF_BAND_OUTPUT]) if OUT_OF_BAND_OUTPUT in names else None
        self.out_of_band = False
        self.start_values = dict(start_values or {})
        self.inputs: dict[str, float] = {c.target: c.failsafe for c in self.mapping.channels}
        self.fmu_errors = 0
        #: FMU instances freed and made afresh after an error
        self.reinstantiations = 0
        self.last_error = ""
        #: wall time of each FMU step (setReal + doStep + getReal) [s], for the statistics
        self.step_times: deque[float] = deque(maxlen=20000)
        self.epoch_s = float(start_time_s)
        self._imu: tuple[Vec3, Vec3] | None = None
        self._interval: tuple[dict[str, float], float] | None = None
        self.fmu_t_s = 0.0
        self.t_s = self.epoch_s
        self.restart()

    @property
    def imu(self) -> tuple[Vec3, Vec3] | None:
        """(mean specific force [m/s^2], mean body rate [rad/s]) over the last step, body FRD: what a real IMU
        reports for it (``sensors.interval_imu``, computed on first use after each step); None at a start state."""
        if self._interval is not None:
            before, dt_s = self._interval
            self._interval = None
            self._imu = interval_imu(before, self.state, dt_s)
        return self._imu

    @imu.setter
    def imu(self, value: tuple[Vec3, Vec3] | None) -> None:
        self._interval, self._imu = None, value

    @property
    def has_airspeed(self) -> bool:
        return "airspeed_m_s" in self.outputs

    def restart(self) -> None:
        """Back to the start state (SITL or PX4 restarted); the clock goes on from the last time."""
        self.epoch_s = self.t_s
        self.fmu_t_s = 0.0
        self.out_of_band = False
        self.host.start(self.start_values)
        self.state = self.host.get(self.outputs)
        self.imu = None

    def clock_at_least(self, t_s: float) -> None:
        """Move the clock (not the FMU) forward to ``t_s`` if it is behind: the first packet carries a positive
        time (PX4 and ArduPilot take 0 as "no time yet")."""
        if self.t_s < t_s:
            self.epoch_s += t_s - self.t_s
            self.t_s = self.epoch_s + self.fmu_t_s

    def apply(self, pwm_us: Mapping[int, float], failsafe: bool = False) -> dict[str, float]:
        """FMU inputs from PWM by output channel (1-based); a bad pulse raises ``MappingError``."""
        self.inputs = self.mapping.apply(pwm_us, failsafe=failsafe)
        return self.inputs

    def check(self, pwm_us: Mapping[int, float]) -> dict[str, float]:
        """The FMU inputs ``pwm_us`` would give, without applying them (``MappingError`` for a bad pulse)."""
        return self.mapping.apply(pwm_us)

    def advance(self, dt_s: float) -> dict[str, float]:
        """One FMU step of ``dt_s`` with the current inputs; returns the outputs by name."""
        t0 = time.perf_counter()
        before = self.state
        try:
            self.host.step(self.fmu_t_s, dt_s, self.inputs)
            self.fmu_t_s += dt_s
            self.t_s = self.epoch_s + self.fmu_t_s
            self.state = self.host.get(self.outputs)
            if self._oob_vr is not None:  # PWM above idle outside the thrust map's trained band (quadrotor)
                self.out_of_band = bool(self.host.slave.getBoolean(self._oob_vr)[0])
            self.step_times.append(time.perf_counter() - t0)
            self._interval = (before, dt_s)  # the IMU means over this step, computed when a sensor reads them
        except FmuRunError as err:
            self.fail(str(err))
            self.clock_at_least(self.t_s + dt_s)  # the failed step's time has passed: the next time is a new one
        return self.state

    def fail(self, reason: str) -> None:
        """The FMU failed (or gave outputs no interface can send): count, log, free the instance and start a new
        one at the start state; the clock goes on from the last time."""
        self.fmu_errors += 1
        self.last_error = reason
        log.error("FMU error, restarting the simulation on a new instance: %s", reason)
        self.reinstantiate()

    def reinstantiate(self) -> None:
        """Free the FMU instance and instantiate it afresh (never ``fmi2Reset`` after a failed call)."""
        self.reinstantiations += 1
        fresh = getattr(self.host, "reinstantiate", None)  # FmuHost's own: frees and instantiates in place
        if fresh is not None:
            fresh()
        else:
            path = self.host.path
            self.host.close()
            self.host = FmuHost(path, instance_name="hil")
        self.restart()

    def close(self) -> None:
        self.host.close()


@dataclass
class Stats:
    """Live counters of an adapter run; latencies in seconds.

    Rates count stepping time only: ``active_s`` sums the wall time between consecutive steps, leaving out
    pauses longer than ``IDLE_GAP_S`` (waiting for the autopilot to connect, reconnects, after it stopped).
    """

    steps: int = 0
    overruns: int = 0
    dropped: int = 0
    malformed: int = 0
    resends: int = 0
    out_of_order: int = 0
    restarts: int = 0
    reconnects: int = 0
    failsafes: int = 0
    #: lockstep PX4: steps run at the wall-clock pace before the autopilot's first actuator message
    free_steps: int = 0
    #: steps whose FMU outputs flagged PWM outside the thrust map's trained band
    out_of_band: int = 0
    #: wall time between the first and the last step, pauses left out [s]
    active_s: float = 0.0
    #: simulation time stepped [s] (the FMU steps' sizes summed)
    sim_s: float = 0.0
    started: float = field(default_factory=time.perf_counter)
    last_step: float = -math.inf
    #: wall time [s] of each reconnect: connection lost (or accepted again) -> first state sent on the new one
    reconnect_s: deque[float] = field(default_factory=lambda: deque(maxlen=1000))
    latencies: deque[float] = field(default_factory=lambda: deque(maxlen=20000))
    #: adapter busy time per step [s]: from the autopilot's input to our reply sent (FMU step included)
    busy: deque[float] = field(default_factory=lambda: deque(maxlen=20000))
    _live: tuple[int, float, float] = (0, 0.0, 0.0)

    def step(self, out_of_band: bool = False, dt_s: float = 0.0) -> None:
        """Count one FMU step of ``dt_s`` [s] of simulation time (and whether it was out of the thrust map's
        band)."""
        now = time.perf_counter()
        gap = now - self.last_step
        if gap < IDLE_GAP_S:
            self.active_s += gap
        self.last_step = now
        self.steps += 1
        self.sim_s += dt_s
        if out_of_band:  # reported once, with the count, in the summary (and per step in the record)
            self.out_of_band += 1

    def percentile(self, q: float) -> float:
        if not self.latencies:
            return math.nan
        s = sorted(self.latencies)
        return s[min(len(s) - 1, int(q / 100.0 * len(s)))]

    @property
    def rate_hz(self) -> float:
        """Steps per second of stepping time (waits, reconnects and the time after the last step left out)."""
        return self.steps / self.active_s if self.active_s > 0 else 0.0

    @property
    def real_time_factor(self) -> float:
        """Simulation seconds per wall second of stepping time (1 = real time; pauses left out)."""
        return self.sim_s / self.active_s if self.active_s > 0 else 0.0

    def live_rates(self) -> tuple[float, float]:
        """(steps per second, real-time factor) over the stepping time since the previous call (the status line
        calls it every second); zeros once stepping has stopped."""
        steps, active, sim = self._live
        self._live = (self.steps, self.active_s, self.sim_s)
        d_active = self.active_s - active
        if d_active <= 0:
            return 0.0, 0.0
        return (self.steps - steps) / d_active, (self.sim_s - sim) / d_active

    def live_rate_hz(self) -> float:
        """Steps per second of stepping time since the previous call; 0 once stepping has stopped."""
        return self.live_rates()[0]

    def summary(self, plant: Plant | None = None) -> dict[str, Any]:
        busy = 1e3 * sum(self.busy) / len(self.busy) if self.busy else math.nan
        out = {"steps": self.steps, "step_rate_hz": round(self.rate_hz, 1), "stepping_s": round(self.active_s, 3),
               "real_time_factor": round(self.real_time_factor, 4),
               "busy_mean_ms": round(busy, 4),
               "latency_p50_ms": round(1e3 * self.percentile(50), 4),
               "latency_p99_ms": round(1e3 * self.percentile(99), 4),
               "overruns": self.overruns, "dropped": self.dropped, "malformed": self.malformed,
               "resends": self.resends, "out_of_order": self.out_of_order, "restarts": self.restarts,
               "reconnects": self.reconnects, "reconnect_max_ms": round(1e3 * max(self.reconnect_s, default=0.0), 3),
               "failsafes": self.failsafes, "free_steps": self.free_steps, "out_of_band_steps": self.out_of_band}
        if plant is not None:
            fmu = 1e3 * sum(plant.step_times) / len(plant.step_times) if plant.step_times else math.nan
            out |= {"sim_time_s": round(plant.t_s, 3), "fmu_step_mean_ms": round(fmu, 4),
                    "fmu_errors": plant.fmu_errors}
        return out

    def line(self, plant: Plant | None = None) -> str:
        """The live status line; its rate is over the last second of stepping."""
        s = self.summary(plant)
        rate, rtf = self.live_rates()
        return (f"t={s.get('sim_time_s', 0):8.2f}s steps={s['steps']} rate={rate:.0f}/s rtf={rtf:.2f}x "
                f"rtt p50={s['latency_p50_ms']:.3f}ms p99={s['latency_p99_ms']:.3f}ms overruns={s['overruns']} "
                f"dropped={s['dropped']} malformed={s['malformed']} fmu_errors={s.get('fmu_errors', 0)}"
                + (f" out_of_band={self.out_of_band}" if self.out_of_band else ""))


#: sensor readings sent to the autopilot, recorded beside the FMU's true outputs
SENSOR_COLUMNS = ("sens_accel_x_m_s2", "sens_accel_y_m_s2", "sens_accel_z_m_s2", "sens_gyro_x_rad_s",
                  "sens_gyro_y_rad_s", "sens_gyro_z_rad_s", "sens_mag_x_gauss", "sens_mag_y_gauss",
                  "sens_mag_z_gauss", "sens_abs_pressure_pa", "sens_diff_pressure_pa", "sens_temperature_degc")


def sensor_values(frame: Any) -> tuple[float, ...]:
    """A sensor frame (``hil_adapter.sensors.SensorFrame``) in the order of ``SENSOR_COLUMNS``."""
    return (*frame.accel_body_m_s2, *frame.gyro_body_rad_s, *frame.mag_body_gauss, frame.abs_pressure_pa,
            frame.diff_pressure_pa, frame.temperature_degc)


class Recorder:
    """Every step's PWM in, FMU inputs and outputs, as a CSV log the project's readers read back; with ``band``
    also the 5-95 % prediction band of each output its discrepancy covers (columns ``<log name>_band_lo|hi``).

    Each row is flushed as it is written, so a crash or Ctrl-C loses at most the row being written.
    """

    def __init__(self, path: str | Path, channels: Sequence[int], inputs: Sequence[str], outputs: Sequence[str],
                 band: Any = None):
        #: ``hil_adapter.record_band.RecordBand``: each row also gets the prediction band of the outputs it covers
        self.band = band
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: TextIO = self.path.open("w", newline="", buffering=1)
        self._w = csv.writer(self._fh)
        self.channels, self.inputs, self.outputs = list(channels), list(inputs), list(outputs)
        self._w.writerow(["time_s", *(f"servo_{c}_pwm_us" for c in self.channels), *self.inputs,
                          *(OUTPUT_TO_LOG.get(o, o) for o in self.outputs), "failsafe", "out_of_band",
                          *SENSOR_COLUMNS, *(band.columns if band is not None else ())])
        self.rows = 0

    def write(self, t_s: float, pwm_us: Mapping[int, float], inputs: Mapping[str, float],
              outputs: Mapping[str, float], failsafe: bool = False, sensors: Any = None,
              out_of_band: bool = False) -> None:
        """One row; ``sensors`` is the sensor frame sent this step (NaN columns when none was sent);
        ``out_of_band``: the FMU flagged PWM above idle outside the thrust map's trained band."""
        sens = sensor_values(sensors) if sensors is not None else (math.nan,) * len(SENSOR_COLUMNS)
        self._w.writerow([repr(t_s), *(repr(float(pwm_us.get(c, math.nan))) for c in self.channels),
                          *(repr(float(inputs[n])) for n in self.inputs),
                          *(repr(float(outputs[n])) for n in self.outputs), int(failsafe), int(out_of_band),
                          *map(repr, sens), *(map(repr, self.band.values(t_s, outputs)) if self.band else ())])
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


def check_speed(speed: float | None) -> float | None:
    """A lockstep speed factor (simulation seconds per wall second) in ``SPEED_RANGE``, or None (unpaced)."""
    if speed is None:
        return None
    if isinstance(speed, bool) or not (math.isfinite(speed) and SPEED_RANGE[0] <= speed <= SPEED_RANGE[1]):
        raise ValueError(f"speed = {speed!r}; allowed {SPEED_RANGE[0]:g}..{SPEED_RANGE[1]:g} or 'max'")
    return float(speed)


class SimClockPacer:
    """Holds a lockstep loop to ``speed`` simulation seconds per wall second (Gazebo's lockstep runs at real
    time unless ``PX4_SIM_SPEED_FACTOR`` says otherwise): ``wait(t_sim_s)`` sleeps until the wall clock reaches
    the time the schedule gives simulation time ``t_sim_s``. The schedule is anchored at the first call and
    after ``reset()``; a loop more than ``MAX_LAG_S`` behind (the autopilot or FMU too slow) starts it again from
    now instead of bursting to catch up: counted as an overrun while stepping, not after a pause (a reconnect,
    an autopilot that stopped sending). ``speed`` None: no pacing (``--speed max``)."""

    def __init__(self, speed: float | None, stats: Stats) -> None:
        self.speed = check_speed(speed)
        self.stats = stats
        self._anchor: tuple[float, float] | None = None  # (wall [s], simulation [s]) where the schedule starts
        self._last = -math.inf

    def reset(self) -> None:
        """Start the schedule again at the next ``wait`` (a new connection, a restarted SITL)."""
        self._anchor = None

    def wait(self, t_sim_s: float) -> None:
        if self.speed is None:
            return
        now = time.perf_counter()
        paused, self._last = now - self._last > IDLE_GAP_S, now
        if self._anchor is None:
            self._anchor = (now, t_sim_s)
            return
        delay = self._anchor[0] + (t_sim_s - self._anchor[1]) / self.speed - now
        if delay > 0.0:
            time.sleep(delay)
            self._last = time.perf_counter()
        elif delay < -MAX_LAG_S or t_sim_s < self._anchor[1]:
            if not paused and delay < -MAX_LAG_S:
                self.stats.overruns += 1
            self._anchor = (now, t_sim_s)


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

"""The measurement chain a real autopilot log went through, read from the log itself.

An autopilot does not log what its sensors saw: the gyro and accelerometer samples pass a low-pass filter at the
IMU rate before anything else reads or logs them (ArduPilot ``INS_GYRO_FILTER`` / ``INS_ACCEL_FILTER``, a 2-pole
``LowPassFilter2p``; PX4 ``IMU_GYRO_CUTOFF`` / ``IMU_ACCEL_CUTOFF``), the servo commands are computed once per
main loop (ArduPilot ``SCHED_LOOP_RATE``) and held until the next, and the servo outputs may be logged at a
fraction of that rate. :func:`sensor_chain` reads these values from the log's parameters and message times;
``identify aero`` passes the model's rate and specific-force outputs through the same filters before it compares
them with the log (``identification.estimation.oem.sensor_lowpass``) and says which elements it modelled.

**The loop's commands** (:class:`LoopClock`). ArduPlane (4.x, ``ArduPlane.cpp``) runs ``ahrs_update`` (which
logs ``IMU`` with ``LOG_BITMASK`` bit IMU), ``stabilize`` and ``set_servos`` as fast tasks at the start of every
loop, and logs ``RCOU`` from ``update_logging25``, a 25 Hz task: every second loop at the default 50 Hz
``SCHED_LOOP_RATE``, time-stamped in that loop, after ``set_servos`` (the same ``TimeUS`` as that loop's IMU
sample in SITL, a few hundred microseconds later on hardware), with the command that loop computed and held
until the next. So each RCOU sample is on time; the loops between two samples are not logged. The gyro's time
stamps are the loop ticks; :meth:`LoopClock.grid` steps the fit on them and :meth:`LoopClock.commands` gives the
command each loop held: the logged one where logged, else the mean of the two logged neighbours weighted by the
loop's place between them (a command that stepped once between two samples stepped at either of the loops with
equal chance: its expected value). A zero-order hold of the samples instead shows every step made in an
unlogged loop one loop late (10 ms late on average at 25 Hz of 50 Hz), and a fit grid started between two ticks
adds up to one more period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.logs.flightlog import FlightLog

#: (gyro cut-off, accelerometer cut-off) parameter names per autopilot; 0 disables the filter in both
CUTOFF_PARAMS = (("INS_GYRO_FILTER", "INS_ACCEL_FILTER"), ("IMU_GYRO_CUTOFF", "IMU_ACCEL_CUTOFF"))
#: the outputs each filter acts on
GYRO_OUTPUTS = ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s")
ACCEL_OUTPUTS = ("accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2")


@dataclass(frozen=True)
class SensorChain:
    """What the log says about its measurement chain; None where it says nothing."""

    gyro_cutoff_hz: float | None
    accel_cutoff_hz: float | None
    gyro_param: str | None
    accel_param: str | None
    loop_rate_hz: float | None  #: ArduPilot SCHED_LOOP_RATE
    servo_log_rate_hz: float | None  #: median rate of the logged servo outputs
    imu_log_rate_hz: float | None  #: median rate of the logged gyro

    def output_filters(self, outputs: tuple[str, ...] | list[str]) -> dict[str, float]:
        """Cut-off [Hz] per fitted output that passed a logged sensor filter."""
        out = {}
        for names, fc in ((GYRO_OUTPUTS, self.gyro_cutoff_hz), (ACCEL_OUTPUTS, self.accel_cutoff_hz)):
            if fc:
                out.update({n: fc for n in names if n in outputs})
        return out

    def lines(self, filters_modelled: bool = True, clock: LoopClock | None = None,
              clock_wanted: bool = True) -> list[str]:
        """The chain in words, with the values read from the log; ``filters_modelled``: whether the fit applies
        the sensor filters; ``clock``: the loop ticks the fit steps on (None: not used, ``clock_wanted`` says
        whether they were asked for)."""
        def rate(v: float | None) -> str:
            return "not logged" if v is None else f"{v:.0f} Hz"

        out = []
        for what, fc, name in (("gyro", self.gyro_cutoff_hz, self.gyro_param),
                               ("accelerometer", self.accel_cutoff_hz, self.accel_param)):
            use = ("modelled on the fitted outputs" if filters_modelled else
                   "not modelled (identify aero --sensor-filters models it)")
            out.append(f"{what} low-pass {fc:g} Hz ({name}, 2-pole): {use}" if fc else
                       f"{what} low-pass: {'off (' + name + ' = 0)' if name else 'no parameter in the log'}; "
                       "not modelled")
        if self.loop_rate_hz and clock is not None:
            every = clock.servo_every(self.servo_log_rate_hz)
            out.append(f"main loop {self.loop_rate_hz:g} Hz (SCHED_LOOP_RATE; ticks from the gyro's time stamps, "
                       f"{clock.period_s * 1e3:.3f} ms): the fit steps on the loop ticks and holds each loop's "
                       "servo command until the next" + (
                           f"; servo outputs logged every {every} loops: an unlogged loop's command is the mean of "
                           "its logged neighbours" if every > 1 else ""))
        elif self.loop_rate_hz:
            why = ("identify aero --loop-ticks uses them" if not clock_wanted else
                   f"gyro logged at {rate(self.imu_log_rate_hz)}, not once per loop")
            out.append(f"main loop {self.loop_rate_hz:g} Hz (SCHED_LOOP_RATE): servo commands held one loop; the fit "
                       f"holds the logged command over each of its samples (loop ticks not used: {why})")
        out.append(f"logged rates: servo outputs {rate(self.servo_log_rate_hz)}, gyro {rate(self.imu_log_rate_hz)}"
                   + (" (servo outputs logged below the loop rate: commands between log samples are unseen)"
                      if self.loop_rate_hz and self.servo_log_rate_hz
                      and self.servo_log_rate_hz < 0.9 * self.loop_rate_hz else ""))
        return out


def _median_rate(log: FlightLog, names: tuple[str, ...]) -> float | None:
    for n in names:
        if log.has(n):
            dt = np.diff(np.asarray(log.signal(n).t_s, float))
            dt = dt[dt > 0]
            if dt.size:
                return float(1.0 / np.median(dt))
    return None


def sensor_chain(log: FlightLog) -> SensorChain:
    """The measurement chain of ``log`` (see the module docstring)."""
    gyro = accel = None
    gname = aname = None
    for g, a in CUTOFF_PARAMS:
        if g in log.params or a in log.params:
            gname, aname = g, a
            gyro = float(log.params.get(g, 0.0)) or None
            accel = float(log.params.get(a, 0.0)) or None
            break
    loop = float(log.params["SCHED_LOOP_RATE"]) if log.params.get("SCHED_LOOP_RATE") else None
    return SensorChain(gyro, accel, gname, aname, loop,
                       _median_rate(log, ("aileron_pwm_us", "servo_1_pwm_us")),
                       _median_rate(log, ("gyro_body_x_rad_s",)))


#: a log sample belongs to the loop of the latest tick at most this far after it [s] (float rounding of TimeUS)
TICK_TOLERANCE_S = 1e-4
#: the gyro counts as logged once per loop when its median rate is within this share of SCHED_LOOP_RATE
LOOP_RATE_MATCH = 0.1


@dataclass(frozen=True)
class LoopClock:
    """The autopilot's main-loop ticks [s, log time] as the log shows them (see the module docstring)."""

    tick_s: np.ndarray
    period_s: float  #: mean tick interval (gaps left out)

    def servo_every(self, servo_log_rate_hz: float | None) -> int:
        """Loops per logged servo sample (1: every loop)."""
        return max(1, round(1.0 / (self.period_s * servo_log_rate_hz))) if servo_log_rate_hz else 1

    def grid(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Uniform fit times ``period_s`` apart from the first tick at or after ``t0_s`` up to ``t1_s``."""
        k = int(np.searchsorted(self.tick_s, t0_s - TICK_TOLERANCE_S))
        start = float(self.tick_s[min(k, len(self.tick_s) - 1)]) if k < len(self.tick_s) else t0_s
        n = int(np.floor((t1_s - start) / self.period_s + 1e-9))
        return start + np.arange(max(n, 0) + 1) * self.period_s

    def loop_index(self, t_s: np.ndarray) -> np.ndarray:
        """Index of the loop whose command acts at ``t_s``: the latest tick at or before it (a quarter period of
        slack absorbs the drift of a uniform grid against the ticks)."""
        idx = np.searchsorted(self.tick_s, np.asarray(t_s, float) + 0.25 * self.period_s, side="right") - 1
        return np.clip(idx, 0, len(self.tick_s) - 1)

    def commands(self, log_t_s: np.ndarray, values: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """The command each loop held, at ``t_s``: the logged sample of that loop, else linear in the loop index
        between the logged neighbours (its expected value; see the module docstring)."""
        before, after, share, _ = self.bracket(log_t_s, values, t_s)
        return before + share * (after - before)

    def bracket(self, log_t_s: np.ndarray, values: np.ndarray, t_s: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For the loop acting at each of ``t_s``: the logged command at or before it and the next one, the
        loop's share of the way between them (0 for a logged loop) and whether it was logged. An unlogged loop's
        command lies between the two (a held command changes once per loop)."""
        log_t_s = np.asarray(log_t_s, float)
        values = np.asarray(values, float)
        j = np.searchsorted(self.tick_s, log_t_s + TICK_TOLERANCE_S, side="right") - 1
        ok = j >= 0
        j, v = j[ok], values[ok]
        n = len(np.atleast_1d(t_s))
        if not j.size:
            nan = np.full(n, np.nan)
            return nan, nan, np.zeros(n), np.zeros(n, bool)
        loops, first_in_rev = np.unique(j[::-1], return_index=True)  # the last sample of each loop
        v = v[::-1][first_in_rev]
        q = self.loop_index(t_s)
        k = np.clip(np.searchsorted(loops, q, side="right") - 1, 0, len(loops) - 1)
        k1 = np.minimum(k + 1, len(loops) - 1)
        logged = loops[k] == q
        span = np.maximum(loops[k1] - loops[k], 1)
        share = np.where(logged | (k1 == k) | (q < loops[0]), 0.0, (q - loops[k]) / span)
        return v[k], np.where(logged, v[k], v[k1]), np.clip(share, 0.0, 1.0), logged


def loop_clock(log: FlightLog) -> LoopClock | None:
    """The loop ticks of ``log``: the gyro's time stamps when the log has ``SCHED_LOOP_RATE`` and the gyro is
    logged once per loop (ArduPilot ``ahrs_update`` logs IMU every loop); else None."""
    loop = float(log.params.get("SCHED_LOOP_RATE", 0.0) or 0.0)
    imu = _median_rate(log, ("gyro_body_x_rad_s",))
    if loop <= 0 or imu is None or abs(imu - loop) > LOOP_RATE_MATCH * loop:
        return None
    t = np.asarray(log.signal("gyro_body_x_rad_s").t_s, float)
    dt = np.diff(t)
    dt = dt[(dt > 0) & (dt < 1.5 / imu)]  # gaps in the log left out
    # the mean interval, not the median: SITL at SIM_RATE_HZ 1200 steps 24 frames (19.992 ms) per loop and one
    # more every hundred loops; a grid at the median drifts 0.8 ms per 2 s against the ticks
    return LoopClock(t, float(np.mean(dt)))


__all__ = ["LoopClock", "SensorChain", "loop_clock", "sensor_chain"]

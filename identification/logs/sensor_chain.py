"""The measurement chain a real autopilot log went through, read from the log itself.

An autopilot does not log what its sensors saw: the gyro and accelerometer samples pass a low-pass filter at the
IMU rate before anything else reads or logs them (ArduPilot ``INS_GYRO_FILTER`` / ``INS_ACCEL_FILTER``, a 2-pole
``LowPassFilter2p``; PX4 ``IMU_GYRO_CUTOFF`` / ``IMU_ACCEL_CUTOFF``), the servo commands are computed once per
main loop (ArduPilot ``SCHED_LOOP_RATE``) and held until the next, and the servo outputs may be logged at a
fraction of that rate. :func:`sensor_chain` reads these values from the log's parameters and message times;
``identify aero`` passes the model's rate and specific-force outputs through the same filters before it compares
them with the log (``identification.estimation.oem.sensor_lowpass``) and says which elements it modelled.
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

    def lines(self, filters_modelled: bool = True) -> list[str]:
        """The chain in words, with the values read from the log; ``filters_modelled``: whether the fit applies
        the sensor filters."""
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
        if self.loop_rate_hz:
            out.append(f"main loop {self.loop_rate_hz:g} Hz (SCHED_LOOP_RATE): servo commands held one loop; "
                       "the fit holds the logged command over each of its samples")
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


__all__ = ["SensorChain", "sensor_chain"]

"""Canonical signals from PX4 topic fields, shared by the ULog and the ulog2csv readers.

Both readers name raw fields ``<topic>[_<instance>].<field>`` (in the topic's units, time in s) and alias the
same canonical names from them; an alias never replaces a signal that is already there.
"""

from __future__ import annotations

import numpy as np

from identification.logs.flightlog import Signal


def alias(signals: dict[str, Signal], name: str, key: str, unit: str, scale: float = 1.0, offset: float = 0.0) -> None:
    """``signals[name] = scale * signals[key] + offset`` [``unit``], when ``key`` is there and ``name`` is not."""
    if key in signals and name not in signals:
        s = signals[key]
        signals[name] = Signal(name, s.t_s, s.values * scale + offset, unit, f"from {key}")


def add_imu_and_attitude(signals: dict[str, Signal]) -> None:
    """``accel_body_{x,y,z}_m_s2`` and ``gyro_body_{x,y,z}_rad_s`` (sensor_combined), and the 3-2-1 Euler angles
    ``roll_rad``, ``pitch_rad``, ``yaw_rad`` of the ``vehicle_attitude`` quaternion."""
    for i, a in enumerate("xyz"):
        alias(signals, f"accel_body_{a}_m_s2", f"sensor_combined.accelerometer_m_s2[{i}]", "m/s2")
        alias(signals, f"gyro_body_{a}_rad_s", f"sensor_combined.gyro_rad[{i}]", "rad/s")
    if "vehicle_attitude.q[0]" in signals:
        w, x, y, z = (signals[f"vehicle_attitude.q[{i}]"].values for i in range(4))
        t = signals["vehicle_attitude.q[0]"].t_s
        euler = {
            "roll_rad": np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
            "pitch_rad": np.arcsin(np.clip(2 * (w * y - x * z), -1, 1)),
            "yaw_rad": np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)),
        }
        for n, v in euler.items():
            signals[n] = Signal(n, t, v, "rad", "from vehicle_attitude.q")


def add_local_position(signals: dict[str, Signal]) -> None:
    """``altitude_m`` and ``climb_rate_m_s`` (up) from ``vehicle_local_position`` (NED ``z``, ``vz``), and the
    land detector's ``landed`` flag (``vehicle_land_detected.landed``, 1 on the ground: where the vehicle is
    parked, and, never set, that a log started in flight has no ground phase)."""
    alias(signals, "altitude_m", "vehicle_local_position.z", "m", -1.0)
    alias(signals, "climb_rate_m_s", "vehicle_local_position.vz", "m/s", -1.0)
    alias(signals, "landed", "vehicle_land_detected.landed", "")


def add_outputs(signals: dict[str, Signal], n_motors: int) -> None:
    """``servo_<n>_pwm_us`` (actuator_outputs 0..15) and ``motor_<k>_pwm_us`` (PX4 quadrotor: the first
    ``n_motors`` outputs)."""
    for n in range(16):
        alias(signals, f"servo_{n + 1}_pwm_us", f"actuator_outputs.output[{n}]", "us")
    for k in range(1, n_motors + 1):
        alias(signals, f"motor_{k}_pwm_us", f"servo_{k}_pwm_us", "us")

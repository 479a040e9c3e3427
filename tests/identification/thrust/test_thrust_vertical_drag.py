"""The vertical drag in ``-m a_z``: on a climbing and sinking flight it follows the climb rate, which leads the
thrust, so the delay search lands on a negative (unphysical) delay and says so; given the drag coefficient, the
measured thrust is the rotor thrust again and the delay is the true one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from identification.thrust.dataset import ThrustDatasetConfig, build_thrust_dataset
from tests.identification.thrust.test_thrust_dataset import G_M_S2, MASS_KG, MOTOR, true_thrust_N

KD_Z_N_S_M = 0.25  #: the synthetic vehicle's vertical drag (the demo quadrotor's)


class ClimbingLog:
    """A FlightLog stand-in (``signal(name) -> (t_s, values)``): 10-100 s airborne at level attitude, altitude
    ``10 + 2.5 sin(2 pi t / 9) + sin(2 pi t / 3.1)`` m flown exactly: the motors (50 Hz, held) give the thrust that
    the climb acceleration and the drag ``kd_z v_up`` ask for; IMU at 100 Hz without delay, 0.1 m/s2 noise;
    NED velocity and attitude at 10 Hz."""

    def __init__(self, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        w1, w2 = 2 * math.pi / 9.0, 2 * math.pi / 3.1

        def climb(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            alt = 10.0 + 2.5 * np.sin(w1 * t) + np.sin(w2 * t)
            return alt, 2.5 * w1 * np.cos(w1 * t) + w2 * np.cos(w2 * t), \
                -2.5 * w1 ** 2 * np.sin(w1 * t) - w2 ** 2 * np.sin(w2 * t)

        t_pwm = np.arange(10.0, 100.0, 0.02)
        _, v_up, a_up = climb(t_pwm)
        need = MASS_KG * (G_M_S2 + a_up) + KD_Z_N_S_M * v_up  # total thrust [N]
        grid = np.linspace(1150.0, 2000.0, 20001)
        per_motor = np.interp(need, true_thrust_N(4.0 * grid), grid)
        self.signals: dict[str, tuple[np.ndarray, np.ndarray]] = {
            f"motor_{k}_pwm_us": (t_pwm, per_motor) for k in range(1, 5)}
        t_imu = np.arange(10.0, 100.0, 0.01)
        idx = np.clip(np.searchsorted(t_pwm, t_imu + 1e-9, side="right") - 1, 0, t_pwm.size - 1)
        _, v_imu, _ = climb(t_imu)
        thrust = true_thrust_N(4.0 * per_motor[idx])
        self.signals["accel_body_z_m_s2"] = (t_imu, (-thrust + KD_Z_N_S_M * v_imu) / MASS_KG
                                             + 0.1 * rng.standard_normal(t_imu.size))
        t_slow = np.arange(10.0, 100.0, 0.1)
        alt, v_slow, _ = climb(t_slow)
        self.signals.update({"altitude_m": (t_slow, alt), "vel_down_m_s": (t_slow, -v_slow),
                             **{n: (t_slow, np.zeros(t_slow.size)) for n in
                                ("vel_north_m_s", "vel_east_m_s", "roll_rad", "pitch_rad", "yaw_rad")}})
        self.path = "climbing.bin"

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self.signals:
            raise KeyError(name)
        return self.signals[name]


def _slope(ds) -> float:
    """Least-squares slope of the measured thrust on the true rotor thrust at the same commands."""
    true = true_thrust_N(ds.pwm_sum_us)
    return float(np.polyfit(true - true.mean(), ds.fz_N - ds.fz_N.mean(), 1)[0])


def test_the_drag_moves_the_delay_search_to_a_negative_delay_and_it_is_stated() -> None:
    log = ClimbingLog()
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, edge_guard_s=0.0))
    assert ds.lag_estimated and ds.lag_s <= -0.05  # the accelerometer "ahead" of the motors
    assert any("AHEAD of the motor commands" in n and "vertical drag" in n for n in ds.notes), ds.notes
    assert MOTOR.pwm_idle_us < ds.pwm_sum_us.min() / 4.0


def test_a_known_vertical_drag_gives_the_rotor_thrust_and_the_true_delay() -> None:
    log = ClimbingLog()
    plain = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, edge_guard_s=0.0, lag_s=0.0))
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, edge_guard_s=0.0,
                                                       vertical_drag_N_s_m=KD_Z_N_S_M))
    # the thrust responds within the IMU step: the search lands on 0 or the next accelerometer sample
    assert 0.0 <= ds.lag_s <= 0.01 + 1e-9
    assert not any("AHEAD" in n for n in ds.notes) and any("kd_z = 0.25" in n for n in ds.notes)
    resid = ds.fz_N - true_thrust_N(ds.pwm_sum_us)
    # each F_z averages 2 IMU samples: noise m 0.1 / sqrt(2), plus the velocity's 10 Hz interpolation
    assert abs(resid.mean()) < 0.01 and resid.std() < 1.3 * MASS_KG * 0.1 / math.sqrt(2)
    assert _slope(ds) == pytest.approx(1.0, abs=0.01)
    # without the drag, at the true delay, -m a_z is the thrust minus kd_z v_up: off by up to 0.7 N
    off = plain.fz_N - true_thrust_N(plain.pwm_sum_us)
    assert np.abs(off).max() > 0.5


def test_a_drag_correction_needs_velocity_and_attitude() -> None:
    log = ClimbingLog()
    del log.signals["vel_down_m_s"]
    with pytest.raises(ValueError, match="vel_down_m_s"):
        build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, vertical_drag_N_s_m=0.25))

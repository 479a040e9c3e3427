"""Thrust data set on synthetic logs: alignment, lag, airborne selection, Pearson gate, k of eq. 6."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmu_models.quadrotor.constants import N_MOTORS
from identification.thrust.anfis_train import AnfisTrainConfig, train_anfis
from identification.thrust.dataset import (
    CorrelationGateError,
    MotorSpeedModel,
    ThrustDataError,
    ThrustDatasetConfig,
    build_thrust_dataset,
    check_gate,
    interleaved_blocks,
    interval_means,
    k_thrust_from_curve,
    pearson,
)

MASS_KG = 1.14
G_M_S2 = 9.80665
K_TRUE_N_S2 = 4.4e-6  #: thrust constant of the synthetic vehicle
MOTOR = MotorSpeedModel()  #: Omega = Kv V (pwm - idle)/(max - idle), defaults


def true_thrust_N(pwm_sum_us: np.ndarray) -> np.ndarray:
    """T = 4 k Omega^2 with Omega linear in per-motor PWM above idle (every motor at S/4)."""
    omega = MOTOR.omega_per_us * np.maximum(pwm_sum_us / 4.0 - MOTOR.pwm_idle_us, 0.0)
    return 4.0 * K_TRUE_N_S2 * omega**2


class SyntheticLog:
    """A FlightLog stand-in: ``signal(name) -> (t_s, values)``, KeyError when not logged.

    Motors at 10 Hz (zero-order hold), IMU at 50 Hz lagging the command by ``lag_s``, altitude at 10 Hz.
    0-10 s on the ground with motors spinning (accelerometer reads 1 g), 10-100 s airborne, 100-110 s on
    the ground again.
    """

    def __init__(
        self,
        lag_s: float = 0.1,
        accel_noise_m_s2: float = 0.3,
        seed: int = 0,
        pwm_swing_us: float = 120.0,
        battery: bool = False,
        duration_s: float = 110.0,
    ) -> None:
        rng = np.random.default_rng(seed)
        t_pwm = np.arange(0.0, duration_s, 0.1)
        airborne = (t_pwm >= 10.0) & (t_pwm < duration_s - 10.0)
        per_motor = np.where(
            airborne,
            1700.0 + pwm_swing_us * np.sin(2 * np.pi * t_pwm / 7.0) + 40.0 * np.sin(2 * np.pi * t_pwm / 1.3),
            1300.0,
        )
        offsets = np.array([-10.0, 10.0, -5.0, 5.0])
        pwm = per_motor[:, None] + offsets[None, :]
        self.signals: dict[str, tuple[np.ndarray, np.ndarray]] = {
            f"motor_{k + 1}_pwm_us": (t_pwm, pwm[:, k]) for k in range(4)
        }
        t_imu = np.arange(0.0, duration_s, 0.02)
        idx = np.clip(np.searchsorted(t_pwm, t_imu - lag_s, side="right") - 1, 0, t_pwm.size - 1)
        thrust = true_thrust_N(pwm.sum(axis=1))[idx]
        on_ground = ~airborne[idx]
        az = np.where(on_ground, -G_M_S2, -thrust / MASS_KG) + accel_noise_m_s2 * rng.standard_normal(
            t_imu.size
        )
        self.signals["accel_body_z_m_s2"] = (t_imu, az)
        self.signals["altitude_m"] = (t_pwm, np.where(airborne, 5.0, 0.0))
        self.signals["armed"] = (np.array([0.0, 1.0, duration_s - 1.0]), np.array([0.0, 1.0, 0.0]))
        self.signals["climb_rate_m_s"] = (t_pwm, 0.1 * rng.standard_normal(t_pwm.size))
        if battery:
            self.signals["battery_voltage_V"] = (t_pwm, 12.6 - 0.01 * t_pwm)
        self.n_airborne = int(airborne.sum())
        self.path = "synthetic.bin"

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self.signals:
            raise KeyError(name)
        return self.signals[name]


def test_interval_means_match_a_direct_loop() -> None:
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0.0, 10.0, 300))
    v = rng.standard_normal(300)
    edges = np.array([0.0, 0.5, 0.5, 2.0, 2.05, 7.3, 10.0])
    mean, count = interval_means(t, v, edges)
    for k in range(edges.size - 1):
        sel = (t >= edges[k]) & (t < edges[k + 1])
        assert count[k] == sel.sum()
        if sel.any():
            assert mean[k] == pytest.approx(v[sel].mean(), rel=1e-12)
        else:
            assert math.isnan(mean[k])


def test_touchdown_guard_keeps_the_edges_of_short_dips_in_the_air() -> None:
    """Only a take-off/touch-down edge (>= edge_guard_s on the ground, or the log's ends) loses its guard; a
    0.3 s dip of the motors below the airborne threshold mid-flight keeps its neighbours."""
    log = SyntheticLog(accel_noise_m_s2=0.3)
    t, alt = log.signals["altitude_m"]
    mid = t[alt > 0][len(t[alt > 0]) // 2]
    for k in range(1, N_MOTORS + 1):
        tk, pk = log.signals[f"motor_{k}_pwm_us"]
        log.signals[f"motor_{k}_pwm_us"] = (tk, np.where((tk >= mid) & (tk < mid + 0.3), 1000.0, pk))
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.0))
    assert set(np.unique(ds.segment)) == {0, 1}
    gap = np.diff(ds.time_s).max()
    assert gap == pytest.approx(0.4, abs=0.05)  # the 3 dip samples and nothing else went at the dip


def test_aligned_force_is_the_thrust_and_lag_is_found() -> None:
    log = SyntheticLog(lag_s=0.1, accel_noise_m_s2=0.3)
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG))
    assert ds.lag_estimated and ds.lag_s == pytest.approx(0.1, abs=0.021)
    # ground run-up (motors spinning, altitude 0) is excluded, and 1 s (10 samples) after take-off and before
    # touch-down (ground contact); a 2-sample edge may go with the lag
    assert log.n_airborne - 23 <= ds.n_samples <= log.n_airborne - 20
    assert any("take-off or touch-down" in n for n in ds.notes)
    assert set(np.unique(ds.segment)) == {0}
    whole = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, edge_guard_s=0.0))
    assert log.n_airborne - 3 <= whole.n_samples <= log.n_airborne
    resid = ds.fz_N - true_thrust_N(ds.pwm_sum_us)
    # each F_z averages 5 IMU samples: noise m * 0.3 / sqrt(5)
    assert abs(resid.mean()) < 0.02
    assert resid.std() == pytest.approx(MASS_KG * 0.3 / math.sqrt(5), rel=0.1)
    corr = ds.correlations()
    assert corr["pwm_sum_us"] > 0.95 and abs(corr["climb_rate_m_s"]) < 0.3  # climb: pure noise here
    assert check_gate(corr, ("pwm_sum_us",)) == []


def test_wrong_lag_lowers_the_correlation() -> None:
    log = SyntheticLog(lag_s=0.1)
    right = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1))
    wrong = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=-0.2))
    assert not right.lag_estimated
    assert pearson(right.pwm_sum_us, right.fz_N) > pearson(wrong.pwm_sum_us, wrong.fz_N) + 0.01


def test_lowpass_removes_noise_but_keeps_the_signal() -> None:
    log = SyntheticLog(accel_noise_m_s2=1.5)
    raw = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1))
    filt = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1, lowpass_hz=1.0))
    err_raw = np.std(raw.fz_N - true_thrust_N(raw.pwm_sum_us))
    err_filt = np.std(filt.fz_N - true_thrust_N(filt.pwm_sum_us))
    assert err_filt < 0.7 * err_raw
    assert filt.correlations()["pwm_sum_us"] > raw.correlations()["pwm_sum_us"]


def test_ground_samples_are_kept_without_altitude_and_say_so() -> None:
    log = SyntheticLog()
    del log.signals["altitude_m"]
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1))
    assert ds.n_samples > log.n_airborne + 50  # motors above 1150 us on the ground too
    assert any("altitude_m" in n for n in ds.notes)


def test_extra_inputs_when_logged() -> None:
    ds = build_thrust_dataset(SyntheticLog(battery=True), ThrustDatasetConfig(mass_kg=MASS_KG))
    assert "battery_voltage_V" in ds.inputs and "climb_rate_m_s" in ds.inputs
    assert ds.inputs["battery_voltage_V"][0] == pytest.approx(12.6 - 0.01 * 10.05, abs=0.01)
    ds2 = build_thrust_dataset(SyntheticLog(), ThrustDatasetConfig(mass_kg=MASS_KG))
    assert "battery_voltage_V" not in ds2.inputs
    assert any("battery_voltage_V" in n for n in ds2.notes)


def test_damaged_accelerometer_tail_gives_the_intact_part() -> None:
    log = SyntheticLog()
    t, az = log.signals["accel_body_z_m_s2"]
    az = az.copy()
    az[t > 80.0] = np.nan  # a reader that could not decode the tail
    log.signals["accel_body_z_m_s2"] = (t, az)
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1))
    assert ds.time_s.max() < 80.0 and ds.n_samples > 600
    assert np.all(np.isfinite(ds.fz_N))


def test_split_is_in_time_order() -> None:
    ds = build_thrust_dataset(SyntheticLog(), ThrustDatasetConfig(mass_kg=MASS_KG, lag_s=0.1))
    train, test = ds.split(0.7)
    assert train.n_samples + test.n_samples == ds.n_samples
    assert train.n_samples == round(0.7 * ds.n_samples)
    assert train.time_s.max() < test.time_s.min()
    chk = interleaved_blocks(train.n_samples, 50)
    assert (
        chk.sum() == pytest.approx(train.n_samples / 5, abs=50) and not chk[:200].any() and chk[200:250].all()
    )


def test_gate_refuses_weak_correlation_and_explains() -> None:
    corr = {"pwm_sum_us": 0.38, "motor_1_pwm_us": 0.2, "climb_rate_m_s": 0.1}
    with pytest.raises(CorrelationGateError) as err:
        check_gate(corr, ("pwm_sum_us",), 0.85, source="x.bin")
    msg = str(err.value)
    for needle in ("x.bin", "r(pwm_sum_us, F_z) = 0.380", "0.85", "--skip-pearson-gate", "motor_1_pwm_us"):
        assert needle in msg
    assert err.value.correlations == corr
    with pytest.warns(UserWarning, match="0.380"):
        assert len(check_gate(corr, ("pwm_sum_us",), 0.85, force=True)) == 1
    assert check_gate(corr, ("pwm_sum_us",), 0.3) == []
    with pytest.raises(CorrelationGateError):  # NaN (constant input) never passes
        check_gate({"pwm_sum_us": float("nan")}, ("pwm_sum_us",), 0.85)


def test_noisy_hover_log_is_refused() -> None:
    log = SyntheticLog(accel_noise_m_s2=4.0, pwm_swing_us=10.0)
    ds = build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG))
    with pytest.raises(CorrelationGateError):
        check_gate(ds.correlations(), ("pwm_sum_us",))


def test_k_from_the_slope_of_a_trained_curve_recovers_the_motor_constant() -> None:
    """Data made with T_i = k Omega_i^2: k from the trained curve's slope (and level) is the true k."""
    ds = build_thrust_dataset(SyntheticLog(accel_noise_m_s2=0.1), ThrustDatasetConfig(mass_kg=MASS_KG))
    res = train_anfis(ds.pwm_sum_us, ds.fz_N, AnfisTrainConfig(n_mfs=3, order=1, epochs=50))
    kc = k_thrust_from_curve(res.amap, ds.pwm_sum_us, MOTOR)
    assert kc.k_N_s2 == pytest.approx(K_TRUE_N_S2, rel=0.03)
    assert kc.k_from_level_N_s2 == pytest.approx(K_TRUE_N_S2, rel=0.01)
    half = MotorSpeedModel(battery_V=MOTOR.battery_V / 2.0)  # half the speed -> four times the k
    assert k_thrust_from_curve(res.amap, ds.pwm_sum_us, half).k_N_s2 == pytest.approx(4 * kc.k_N_s2, rel=1e-9)


def test_missing_signal_and_bad_options_are_named() -> None:
    log = SyntheticLog()
    del log.signals["motor_3_pwm_us"]
    with pytest.raises(ThrustDataError, match="'motor_3_pwm_us' is not in the log"):
        build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=MASS_KG))
    with pytest.raises(ThrustDataError, match=r"mass_kg = -1.0; allowed range \[0.05, 50.0\]"):
        ThrustDatasetConfig(mass_kg=-1.0)
    with pytest.raises(ThrustDataError, match="extra input 'airspeed'"):
        ThrustDatasetConfig(mass_kg=1.0, extra_inputs=("airspeed",))
    with pytest.raises(ThrustDataError, match="Nyquist"):
        build_thrust_dataset(SyntheticLog(), ThrustDatasetConfig(mass_kg=MASS_KG, lowpass_hz=8.0))
    with pytest.raises(ThrustDataError, match=r"kv_rpm_per_V = 0\.0"):
        MotorSpeedModel(kv_rpm_per_V=0.0)


@pytest.mark.parametrize(("kwargs", "expected"), [
    ({"mass_kg": True}, r"mass_kg = True; allowed range \[0\.05, 50\.0\] kg"),  # never taken as 1 kg
    ({"mass_kg": "1.2"}, r"mass_kg = '1\.2'; allowed range"),
    ({"mass_kg": math.nan}, r"mass_kg = nan; allowed range"),
    ({"mass_kg": 1.0, "n_motors": 4.0}, r"n_motors = 4\.0; allowed range \[1, 12\] \(an integer\)"),
    ({"mass_kg": 1.0, "lag_s": math.inf}, r"lag_s = inf; allowed range \[-5\.0, 5\.0\] s .* or None"),
])
def test_options_refuse_booleans_strings_and_non_finite_values(kwargs: dict, expected: str) -> None:
    with pytest.raises(ThrustDataError, match=expected):
        ThrustDatasetConfig(**kwargs)


def test_options_take_numpy_numbers_and_none_where_optional() -> None:
    cfg = ThrustDatasetConfig(mass_kg=np.float64(1.2), n_motors=np.int64(4), lag_s=None, lowpass_hz=None)
    assert cfg.mass_kg == 1.2 and cfg.n_motors == 4


def test_a_replay_drops_the_same_take_off_and_touch_down_samples() -> None:
    """``without_ground_contact`` (the replay's hover battery state) drops 1 s after take-off and before
    touch-down, and keeps a short dip of the motors in flight (not a ground contact)."""
    from identification.thrust.dataset import without_ground_contact

    t = np.arange(0.0, 25.0, 0.1)
    airborne = (t >= 5.0) & (t < 20.0) & ~((t >= 12.0) & (t < 12.3))
    kept = without_ground_contact(airborne, t)
    assert not kept[(t >= 5.0) & (t < 5.95)].any() and kept[(t >= 6.05) & (t < 12.0)].all()
    assert kept[(t >= 12.3) & (t < 18.95)].all() and not kept[(t >= 19.05)].any()
    assert np.array_equal(without_ground_contact(airborne, t, guard_s=0.0), airborne)

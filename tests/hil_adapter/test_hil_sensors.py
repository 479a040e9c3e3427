"""HIL sensor models: exact noise-free readings, ISA baro, Earth field, GPS rate and latency, seeded noise,
noise statistics, bias drift, config checking, missing outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmu_models.common.wgs84 import radii_of_curvature
from hil_adapter.sensors import (
    AccelConfig,
    GpsConfig,
    MagConfig,
    MissingOutputError,
    SensorConfig,
    SensorConfigError,
    SensorSuite,
)

G0 = 9.80665


def outputs(**overrides: float) -> dict[str, float]:
    """At rest, level, heading north, on the ground at 0 m."""
    out = {
        "accel_body_x_m_s2": 0.0, "accel_body_y_m_s2": 0.0, "accel_body_z_m_s2": -G0,
        "rate_body_x_rad_s": 0.0, "rate_body_y_rad_s": 0.0, "rate_body_z_rad_s": 0.0,
        "roll_rad": 0.0, "pitch_rad": 0.0, "yaw_rad": 0.0,
        "quat_w": 1.0, "quat_x": 0.0, "quat_y": 0.0, "quat_z": 0.0,
        "lat_deg": 47.3977, "lon_deg": 8.5456, "height_m": 0.0, "altitude_m": 0.0,
        "vel_north_m_s": 0.0, "vel_east_m_s": 0.0, "vel_down_m_s": 0.0,
    }
    out.update(overrides)
    return out


def yawed(yaw_deg: float) -> dict[str, float]:
    half = math.radians(yaw_deg) / 2
    return {"quat_w": math.cos(half), "quat_z": math.sin(half), "yaw_rad": 2 * half}


def noise_free(**sections) -> SensorConfig:
    return SensorConfig.noise_free().replace(**sections)


def quiet_gps(**settings) -> GpsConfig:
    """A GPS without position and velocity noise."""
    return GpsConfig(**{"pos_noise_std_h_m": 0.0, "pos_noise_std_v_m": 0.0, "vel_noise_std_m_s": 0.0,
                        "vel_noise_std_down_m_s": 0.0, "pos_gm_std_h_m": 0.0, "pos_gm_std_v_m": 0.0, **settings})


# ------------------------------------------------------------------------------------------ noise-free physics
def test_at_rest_on_the_ground_noise_free_reads_exact_values() -> None:
    frame = SensorSuite(noise_free(), seed=3).sample(0.0, outputs())
    assert frame.accel_body_m_s2 == (0.0, 0.0, -G0)
    assert frame.gyro_body_rad_s == (0.0, 0.0, 0.0)
    assert frame.abs_pressure_pa == 101325.0
    assert frame.temperature_degc == pytest.approx(15.0, abs=1e-9)
    assert frame.pressure_alt_m == pytest.approx(0.0, abs=1e-9)
    assert frame.diff_pressure_pa == 0.0  # no airspeed output: no pitot
    assert all(isinstance(v, float) for v in (*frame.accel_body_m_s2, *frame.gyro_body_rad_s, *frame.mag_body_gauss))
    # later samples stay exact too (no drift creeps in)
    suite = SensorSuite(noise_free(), seed=3)
    for k in range(100):
        f = suite.sample(k * 0.004, outputs(rate_body_x_rad_s=0.1, accel_body_x_m_s2=1.5))
        assert f.accel_body_m_s2 == (1.5, 0.0, -G0) and f.gyro_body_rad_s == (0.1, 0.0, 0.0)


def test_baro_follows_isa_at_1000_m() -> None:
    frame = SensorSuite(noise_free()).sample(0.0, outputs(height_m=1000.0, altitude_m=1000.0))
    assert frame.abs_pressure_pa == pytest.approx(89874.6, abs=0.05)
    assert frame.temperature_degc == pytest.approx(8.5, abs=1e-9)
    assert frame.pressure_alt_m == pytest.approx(1000.0, abs=1e-6)


def test_baro_uses_height_not_altitude_above_home() -> None:
    frame = SensorSuite(noise_free()).sample(0.0, outputs(height_m=500.0, altitude_m=0.0))
    assert frame.pressure_alt_m == pytest.approx(500.0, abs=1e-6)
    assert frame.abs_pressure_pa < 101325.0 - 5000.0


def test_diff_pressure_is_dynamic_pressure_of_airspeed() -> None:
    suite = SensorSuite(noise_free())
    assert suite.sample(0.0, outputs(airspeed_m_s=20.0)).diff_pressure_pa == pytest.approx(0.5 * 1.225 * 400.0,
                                                                                          rel=1e-4)
    assert suite.sample(0.1, outputs(airspeed_m_s=0.0)).diff_pressure_pa == 0.0
    high = suite.sample(0.2, outputs(airspeed_m_s=20.0, height_m=1000.0)).diff_pressure_pa
    assert high == pytest.approx(0.5 * 1.1116 * 400.0, rel=1e-4)  # thinner air at 1000 m


MAG = SensorConfig.noise_free().mag.replace(intensity_gauss=0.5, declination_deg=0.0, inclination_deg=60.0)


def test_mag_level_heading_north_points_north_and_down() -> None:
    m = SensorSuite(noise_free(mag=MAG)).sample(0.0, outputs()).mag_body_gauss
    assert m == pytest.approx((0.25, 0.0, 0.4330127), abs=1e-7)


def test_mag_rotates_with_heading() -> None:
    east = SensorSuite(noise_free(mag=MAG)).sample(0.0, outputs(**yawed(90.0))).mag_body_gauss
    assert east == pytest.approx((0.0, -0.25, 0.4330127), abs=1e-7)  # north is on the body's left
    south = SensorSuite(noise_free(mag=MAG)).sample(0.0, outputs(**yawed(180.0))).mag_body_gauss
    assert south == pytest.approx((-0.25, 0.0, 0.4330127), abs=1e-7)


def test_mag_declination_is_east_positive() -> None:
    mag = MAG.replace(declination_deg=10.0)
    # nose on magnetic north (10 deg east of true north): the horizontal field is along the nose again
    m = SensorSuite(noise_free(mag=mag)).sample(0.0, outputs(**yawed(10.0))).mag_body_gauss
    assert m == pytest.approx((0.25, 0.0, 0.4330127), abs=1e-7)


def test_mag_with_unnormalised_quaternion() -> None:
    q = {k: 1.001 * v for k, v in yawed(90.0).items() if k.startswith("quat")}
    m = SensorSuite(noise_free(mag=MAG)).sample(0.0, outputs(**q)).mag_body_gauss
    assert m == pytest.approx((0.0, -0.25, 0.4330127), abs=1e-7)


def test_constant_bias_is_added() -> None:
    cfg = noise_free(accel=SensorConfig.noise_free().accel.replace(bias=(0.1, -0.2, 0.3)))
    suite = SensorSuite(cfg)
    for k in range(10):
        assert suite.sample(k * 0.01, outputs()).accel_body_m_s2 == pytest.approx((0.1, -0.2, -G0 + 0.3))


# ------------------------------------------------------------------------------------------ GPS
@pytest.mark.parametrize(("gps_hz", "sample_hz", "expected"), [(5.0, 250, 5), (10.0, 100, 10), (1.0, 250, 1),
                                                             (50.0, 250, 50)])
def test_gps_comes_at_its_rate(gps_hz: float, sample_hz: int, expected: int) -> None:
    suite = SensorSuite(noise_free(gps=quiet_gps(rate_hz=gps_hz, latency_s=0.0)))
    times = [k / sample_hz for k in range(sample_hz)]  # 1 s
    fixes = [(t, f.gps) for t in times if (f := suite.sample(t, outputs())).gps is not None]
    assert len(fixes) == expected
    assert [t for t, _ in fixes] == pytest.approx([k / gps_hz for k in range(expected)])


def test_gps_after_a_gap_keeps_its_grid_without_a_burst() -> None:
    suite = SensorSuite(noise_free(gps=quiet_gps(rate_hz=10.0, latency_s=0.0)))
    got = {t: suite.sample(t, outputs()).gps is not None for t in (0.0, 1.0, 1.05, 1.1, 1.15, 1.2)}
    assert got == {0.0: True, 1.0: True, 1.05: False, 1.1: True, 1.15: False, 1.2: True}


def test_gps_latency_reports_the_earlier_state() -> None:
    latency = 0.2
    suite = SensorSuite(noise_free(gps=quiet_gps(rate_hz=5.0, latency_s=latency)))

    def state(t: float) -> dict[str, float]:  # climbing and speeding up northwards
        return outputs(lat_deg=47.0 + 1e-4 * t, lon_deg=8.0 - 2e-4 * t, height_m=100.0 + 3.0 * t,
                       vel_north_m_s=10.0 + t, vel_east_m_s=-1.0, vel_down_m_s=-3.0)

    fixes = {}
    for k in range(250):
        t = k * 0.004
        f = suite.sample(t, state(t))
        if f.gps is not None:
            fixes[round(t, 6)] = f.gps
    assert sorted(fixes) == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8])
    assert fixes[0.0].time_s == 0.0 and fixes[0.0].lat_deg == 47.0  # nothing earlier: the first state
    for t in (0.4, 0.6, 0.8):
        fix, then = fixes[t], state(t - latency)
        assert fix.time_s == pytest.approx(t - latency)
        assert fix.lat_deg == pytest.approx(then["lat_deg"], abs=1e-12)
        assert fix.lon_deg == pytest.approx(then["lon_deg"], abs=1e-12)
        assert fix.alt_msl_m == pytest.approx(then["height_m"], abs=1e-9)
        assert fix.vel_ned_m_s == pytest.approx((then["vel_north_m_s"], -1.0, -3.0), abs=1e-9)
        assert fix.lat_deg < state(t)["lat_deg"] - 1e-5  # measurably not the current position


def test_gps_latency_between_samples_interpolates() -> None:
    suite = SensorSuite(noise_free(gps=quiet_gps(rate_hz=1.0, latency_s=0.05)))
    suite.sample(0.0, outputs(height_m=0.0))
    suite.sample(0.9, outputs(height_m=90.0))
    fix = suite.sample(1.0, outputs(height_m=100.0)).gps
    assert fix is not None and fix.time_s == pytest.approx(0.95) and fix.alt_msl_m == pytest.approx(95.0)


def test_gps_fix_fields() -> None:
    cfg = GpsConfig(rate_hz=10.0, latency_s=0.0, eph_m=2.5, epv_m=4.0, fix_type=3, satellites=12,
                    pos_noise_std_h_m=0.0, pos_noise_std_v_m=0.0, vel_noise_std_m_s=0.0, vel_noise_std_down_m_s=0.0,
                    pos_gm_std_h_m=0.0, pos_gm_std_v_m=0.0)
    suite = SensorSuite(noise_free(gps=cfg))
    fix = suite.sample(0.0, outputs(vel_north_m_s=3.0, vel_east_m_s=4.0, height_m=432.1)).gps
    assert fix is not None
    assert (fix.lat_deg, fix.lon_deg, fix.alt_msl_m) == (47.3977, 8.5456, 432.1)
    assert fix.ground_speed_m_s == pytest.approx(5.0) and fix.course_deg == pytest.approx(53.130102, abs=1e-6)
    assert (fix.eph_m, fix.epv_m, fix.fix_type, fix.satellites) == (2.5, 4.0, 3, 12)
    west = suite.sample(0.1, outputs(vel_north_m_s=0.0, vel_east_m_s=-2.0)).gps
    assert west is not None and west.course_deg == pytest.approx(270.0)
    north_west = suite.sample(0.2, outputs(vel_north_m_s=1.0, vel_east_m_s=-1e-18)).gps
    assert north_west is not None and 0.0 <= north_west.course_deg < 360.0
    still = suite.sample(0.3, outputs(vel_north_m_s=-0.0)).gps
    assert still is not None and still.course_deg == 0.0 and still.ground_speed_m_s == 0.0


def test_time_going_back_restarts_the_gps_schedule() -> None:
    suite = SensorSuite(noise_free(gps=quiet_gps(rate_hz=1.0, latency_s=0.5)))
    assert suite.sample(0.0, outputs()).gps is not None
    assert suite.sample(0.5, outputs()).gps is None
    restarted = suite.sample(0.0, outputs(height_m=7.0)).gps  # FMU re-initialised
    assert restarted is not None and restarted.alt_msl_m == 7.0  # no stale state from before the restart


# ------------------------------------------------------------------------------------------ seeds
def run(suite: SensorSuite, n: int = 300) -> list:
    return [suite.sample(k * 0.004, outputs(height_m=50.0, airspeed_m_s=15.0)) for k in range(n)]


def test_same_seed_same_sequence_different_seed_different() -> None:
    a, b, c = run(SensorSuite(seed=42)), run(SensorSuite(seed=42)), run(SensorSuite(seed=43))
    assert a == b
    assert sum(fa.gps is not None for fa in a) == 6
    for fields in ("accel_body_m_s2", "gyro_body_rad_s", "mag_body_gauss", "abs_pressure_pa", "diff_pressure_pa"):
        assert all(getattr(fa, fields) != getattr(fc, fields) for fa, fc in zip(a, c, strict=True)), fields
    assert [fa.gps for fa in a if fa.gps] != [fc.gps for fc in c if fc.gps]


def test_reset_repeats_exactly() -> None:
    suite = SensorSuite(seed=7)
    first = run(suite)
    assert run(suite) != first  # without reset the noise goes on
    suite.reset()
    assert run(suite) == first


def test_noise_is_noise() -> None:
    f = SensorSuite(seed=1).sample(0.0, outputs())
    assert f.accel_body_m_s2 != (0.0, 0.0, -G0) and f.gyro_body_rad_s != (0.0, 0.0, 0.0)


# ------------------------------------------------------------------------------------------ statistics
def test_white_noise_has_the_configured_std() -> None:
    n = 20000
    cfg = SensorConfig.noise_free().replace(
        accel=SensorConfig.noise_free().accel.replace(noise_std=0.08),
        gyro=SensorConfig.noise_free().gyro.replace(noise_std=0.004),
        baro=SensorConfig.noise_free().baro.replace(noise_std=3.0),
        diff_pressure=SensorConfig.noise_free().diff_pressure.replace(noise_std=0.7),
        gps=GpsConfig(rate_hz=100.0, latency_s=0.0, pos_noise_std_h_m=1.5, pos_noise_std_v_m=2.5,
                      vel_noise_std_m_s=0.2, vel_noise_std_down_m_s=0.2, pos_gm_std_h_m=0.0, pos_gm_std_v_m=0.0),
    )
    suite = SensorSuite(cfg, seed=11)
    truth = outputs(airspeed_m_s=0.0)
    frames = [suite.sample(k * 0.01, truth) for k in range(n)]
    assert all(f.gps is not None for f in frames)
    r_m, r_n = radii_of_curvature(math.radians(truth["lat_deg"]))
    cos_lat = math.cos(math.radians(truth["lat_deg"]))
    errors = {
        0.08: np.array([f.accel_body_m_s2 for f in frames]) - (0.0, 0.0, -G0),
        0.004: np.array([f.gyro_body_rad_s for f in frames]),
        3.0: np.array([f.abs_pressure_pa for f in frames]) - 101325.0,
        0.7: np.array([f.diff_pressure_pa for f in frames]),
        1.5: np.column_stack([np.radians([f.gps.lat_deg - truth["lat_deg"] for f in frames]) * r_m,
                              np.radians([f.gps.lon_deg - truth["lon_deg"] for f in frames]) * r_n * cos_lat]),
        2.5: np.array([f.gps.alt_msl_m for f in frames]),
        0.2: np.array([f.gps.vel_ned_m_s for f in frames]),
    }
    for std, err in errors.items():
        err = err.reshape(n, -1)
        for axis in err.T:
            assert np.std(axis) == pytest.approx(std, rel=0.1), std
            assert abs(np.mean(axis)) < 5 * std / math.sqrt(n), std
    # axes are independent
    acc = errors[0.08]
    assert abs(np.corrcoef(acc[:, 0], acc[:, 1])[0, 1]) < 0.05


def test_bias_drift_grows_like_sqrt_t() -> None:
    sigma = 0.01  # rad/s per sqrt(s)
    cfg = noise_free(gyro=SensorConfig.noise_free().gyro.replace(drift_std=sigma))
    times = (0.0, 1.0, 4.0, 16.0)
    runs = []
    for s in range(1000):
        suite = SensorSuite(cfg, seed=s)
        runs.append([suite.sample(t, outputs()).gyro_body_rad_s for t in times])
    drift = np.array(runs)  # [seed, time, axis]
    assert np.all(drift[:, 0, :] == 0.0)
    for i, t in enumerate(times[1:], start=1):
        assert np.std(drift[:, i, :]) == pytest.approx(sigma * math.sqrt(t), rel=0.1)
    # it is a random walk: increments are independent of the past
    inc1, inc2 = drift[:, 1, :].ravel(), (drift[:, 2, :] - drift[:, 1, :]).ravel()
    assert abs(np.corrcoef(inc1, inc2)[0, 1]) < 0.1


def test_drift_does_not_depend_on_the_step() -> None:
    sigma = 0.02
    cfg = noise_free(baro=SensorConfig.noise_free().baro.replace(drift_std=sigma))
    ends = []
    for s in range(1000):
        suite = SensorSuite(cfg, seed=s)
        for k in range(51):
            f = suite.sample(k * 0.02, outputs())
        ends.append(f.abs_pressure_pa - 101325.0)
    assert np.std(ends) == pytest.approx(sigma * math.sqrt(1.0), rel=0.1)


# ------------------------------------------------------------------------------------------ config
def test_config_from_dict_defaults_and_normalisation() -> None:
    cfg = SensorConfig.from_dict({"accel": {"noise_std": 0.1, "bias": 0.05}, "gyro": {"bias": [0.01, 0, -0.01]},
                                  "gps": {"rate_hz": 10, "fix_type": 3}}, source="bench.toml")
    assert cfg.accel.noise_std == 0.1 and cfg.accel.bias == (0.05, 0.05, 0.05)
    assert cfg.gyro.bias == (0.01, 0.0, -0.01) and cfg.gyro.noise_std == SensorConfig().gyro.noise_std
    assert cfg.gps.rate_hz == 10.0 and isinstance(cfg.gps.rate_hz, float) and cfg.mag == MagConfig()
    assert SensorConfig.from_dict({}) == SensorConfig()
    with pytest.raises(ValueError, match="frozen"):
        cfg.accel.noise_std = 1.0


@pytest.mark.parametrize(("data", "expected"), [
    ({"accel": {"noise_std": -0.1}}, ["accel.noise_std = -0.1", ">= 0 and <= 10"]),
    ({"gyro": {"drift_std": math.nan}}, ["gyro.drift_std = nan", "finite", ">= 0 and <= 0.1"]),
    ({"gyro": {"bias": [0.0, 2.0, 0.0]}}, ["gyro.bias.1 = 2.0", ">= -1 and <= 1"]),
    ({"gyro": {"bias": [0.0, 0.0]}}, ["gyro.bias.2", "missing"]),
    ({"mag": {"inclination_deg": 95}}, ["mag.inclination_deg = 95", ">= -90 and <= 90"]),
    ({"mag": {"intensity_gauss": "0.5"}}, ["mag.intensity_gauss = '0.5'", "valid number", ">= 0.1 and <= 1"]),
    ({"baro": {"noise_std": math.inf}}, ["baro.noise_std = inf", "finite", ">= 0 and <= 1000"]),
    ({"gps": {"rate_hz": 0}}, ["gps.rate_hz = 0", ">= 0.1 and <= 100"]),
    ({"gps": {"fix_type": 3.0}}, ["gps.fix_type = 3.0", "valid integer", ">= 0 and <= 8"]),
    ({"gps": {"satellites": True}}, ["gps.satellites = True", "valid integer", ">= 0 and <= 255"]),
    ({"gps": {"latency_s": 2.0}}, ["gps.latency_s = 2.0", ">= 0 and <= 1"]),
    ({"accel": {"noise": 0.1}}, ["accel.noise = 0.1", "unknown key", "noise_std"]),
    ({"lidar": {}}, ["lidar", "unknown key", "accel"]),
    ({"gps": 5}, ["gps = 5", "dictionary"]),
])
def test_config_errors_name_source_field_value_and_range(data: dict, expected: list[str]) -> None:
    with pytest.raises(SensorConfigError) as err:
        SensorConfig.from_dict(data, source="bench/sensors.toml")
    text = str(err.value)
    assert text.startswith("bench/sensors.toml: ")
    for part in expected:
        assert part in text, (part, text)


def test_config_errors_are_all_listed() -> None:
    with pytest.raises(SensorConfigError) as err:
        SensorConfig.from_dict({"accel": {"noise_std": -1, "bias": 99}, "gps": {"eph_m": -1}}, source="x.toml")
    text = str(err.value)
    assert "accel.noise_std" in text and "accel.bias" in text and "gps.eph_m" in text
    assert isinstance(err.value, ValueError)


def test_section_from_dict_and_direct_construction_are_checked() -> None:
    assert GpsConfig.from_dict({"rate_hz": 2.0}).rate_hz == 2.0
    with pytest.raises(SensorConfigError, match=r"(?s)gps\.toml: .*field epv_m = -3"):
        GpsConfig.from_dict({"epv_m": -3}, source="gps.toml")
    with pytest.raises(ValueError, match=r"(?s)noise_std.*greater than or equal to 0"):
        AccelConfig(noise_std=-1.0)


def test_bad_seed() -> None:
    with pytest.raises(ValueError, match="seed"):
        SensorSuite(seed=-1)


# ------------------------------------------------------------------------------------------ outputs
def test_missing_output_is_named() -> None:
    out = outputs()
    del out["height_m"]
    with pytest.raises(MissingOutputError) as err:
        SensorSuite().sample(0.0, out)
    assert isinstance(err.value, KeyError)
    assert "height_m" in str(err.value) and "lat_deg" not in str(err.value)


def test_optional_and_unused_outputs_may_be_absent() -> None:
    out = outputs()
    for name in ("roll_rad", "pitch_rad", "yaw_rad", "altitude_m"):
        del out[name]
    assert SensorSuite().sample(0.0, out).diff_pressure_pa == 0.0


def test_gps_position_error_is_gauss_markov_with_the_configured_time_constant() -> None:
    """At rest, the GPS position error's autocorrelation at lag L is exp(-L / tau) (first-order Gauss-Markov),
    its std the configured one; the time constant fitted from the lag-1 correlation matches tau."""
    tau, rate = 2.0, 10.0
    gps = quiet_gps(rate_hz=rate, latency_s=0.0, pos_gm_std_h_m=1.2, pos_gm_std_v_m=2.0, pos_gm_tau_s=tau)
    suite = SensorSuite(noise_free(gps=gps), seed=4)
    r_m = 6.36e6  # meridian radius of curvature near 47 deg, for degrees -> metres (only ratios matter)
    north, down, rest = [], [], outputs()
    n = round(1000 * tau * rate)  # 1000 time constants: the correlation estimates are good to about 0.05
    for k in range(n):
        fix = suite.sample(k / rate, rest).gps
        north.append(math.radians(fix.lat_deg - rest["lat_deg"]) * r_m)
        down.append(rest["height_m"] - fix.alt_msl_m)
    for err, std in ((np.array(north), 1.2), (np.array(down), 2.0)):
        err = err - err.mean()
        assert np.std(err) == pytest.approx(std, rel=0.1)
        for lag_s in (0.5 * tau, tau, 2 * tau):
            lag = round(lag_s * rate)
            rho = np.dot(err[:-lag], err[lag:]) / np.dot(err, err)
            assert rho == pytest.approx(math.exp(-lag_s / tau), abs=0.06), lag_s
        rho1 = np.dot(err[:-1], err[1:]) / np.dot(err, err)
        assert -1.0 / rate / math.log(rho1) == pytest.approx(tau, rel=0.1)
    white = np.diff(north)  # not white noise: consecutive fixes differ by far less than the std
    assert np.std(white) < 0.4 * 1.2


# ------------------------------------------------------------------------------------------ profiles and sources
def test_gazebo_gps_error_is_what_the_plugin_update_law_gives() -> None:
    """PX4's Gazebo GPS plugin updates its bias every 4 ms physics step as b += rw sqrt(dt) n dt - b / 60; run
    that law directly: its stationary std and its correlation after 0.24 s are what ``gazebo_gps_error`` says
    (millimetres and e^-1), not 1 m and 60 s."""
    from scipy.signal import lfilter

    from hil_adapter.sensors import GAZEBO_STEP_S, gazebo_gps_error

    rng = np.random.default_rng(3)
    n = 400_000
    drive = 2.0 * math.sqrt(GAZEBO_STEP_S) * GAZEBO_STEP_S * rng.standard_normal(n)
    b = lfilter([1.0], [1.0, -(1.0 - 1.0 / 60.0)], drive)[1000:]  # b_k = (1 - 1/60) b_{k-1} + drive_k
    std, tau = gazebo_gps_error(2.0)
    assert np.std(b) == pytest.approx(std, rel=0.05) and 0.002 < std < 0.004
    lag = round(tau / GAZEBO_STEP_S)
    assert np.corrcoef(b[:-lag], b[lag:])[0, 1] == pytest.approx(math.exp(-1.0), abs=0.03)
    assert tau == pytest.approx(0.24, rel=1e-9)
    d = GpsConfig()
    assert (d.pos_gm_std_h_m, d.pos_gm_tau_s, d.latency_s, d.rate_hz) == (std, tau, 0.12, 5.0)


@pytest.mark.parametrize("section", ["accel", "gyro", "mag", "baro", "diff_pressure", "gps"])
def test_every_noise_default_names_its_source(section: str) -> None:
    cls = type(getattr(SensorConfig(), section))
    for name in ("noise_std", "noise_density", "drift_std", "drift_tau_s", "turn_on_bias_std", "rate_hz",
                 "latency_s", "pos_gm_std_h_m", "pos_gm_std_v_m", "pos_gm_tau_s", "vel_noise_std_m_s"):
        if name in cls.model_fields:
            text = cls.model_fields[name].description or ""
            assert text.startswith("default from ") and len(text) > 20, (section, name, text)


@pytest.mark.parametrize("dt", [0.004, 0.001])
def test_imu_white_noise_follows_its_density(dt: float) -> None:
    """Per-sample std = density / sqrt(dt): a faster loop sees more noise per sample, the same density."""
    density = 0.01
    cfg = noise_free(gyro=SensorConfig.noise_free().gyro.replace(noise_density=density))
    suite = SensorSuite(cfg, seed=5)
    g = np.array([suite.sample((k + 1) * dt, outputs()).gyro_body_rad_s for k in range(20000)])
    assert np.std(g[1:]) == pytest.approx(density / math.sqrt(dt), rel=0.05)


def test_ublox_profile_horizontal_error_has_the_datasheet_cep() -> None:
    """u-blox NEO-M8: 2.5 m CEP: half of the fixes (over receivers: independent seeds) within 2.5 m."""
    r_m, r_n = radii_of_curvature(math.radians(47.3977))
    cos_lat = math.cos(math.radians(47.3977))
    radii = []
    for seed in range(2000):
        fix = SensorSuite(SensorConfig.profile("ublox_m8"), seed=seed).sample(0.0, outputs()).gps
        north = math.radians(fix.lat_deg - 47.3977) * float(r_m)
        east = math.radians(fix.lon_deg - 8.5456) * float(r_n) * cos_lat
        radii.append(math.hypot(north, east))
    assert np.median(radii) == pytest.approx(2.5, rel=0.08)


def test_profile_from_the_bench_config(tmp_path) -> None:
    from hil_adapter.config import ConfigError, load_hil_config, sensor_suite

    path = tmp_path / "bench.toml"
    path.write_text('[sensors]\nprofile = "ublox_m8"\n[sensors.gps]\nrate_hz = 5.0\n')
    suite = sensor_suite(load_hil_config(path))
    assert suite.config.gps.rate_hz == 5.0 and suite.config.gps.eph_m == 2.5  # the profile, one value overridden
    path.write_text('[sensors]\nprofile = "gazebo"\n')
    with pytest.raises(ConfigError, match="px4_gazebo"):
        load_hil_config(path)


# The u-blox M8 profile's figures, each written here from its data sheet (not read from hil_adapter/sensors.py),
# with the unit conversion spelled out.
#: TDK InvenSense ICM-20602 data sheet DS-000176 rev 1.0, section 3.1 "Gyroscope specifications": rate noise
#: spectral density 0.004 deg/s/sqrt(Hz); in rad/s/sqrt(Hz): x pi / 180
ICM20602_GYRO_DENSITY_RAD_S = 0.004 * math.pi / 180.0
#: same data sheet, section 3.2 "Accelerometer specifications": noise power spectral density 100 ug/sqrt(Hz);
#: in m/s^2/sqrt(Hz): x 1e-6 g x 9.80665 m/s^2 per g (standard gravity)
ICM20602_ACCEL_DENSITY_M_S2 = 100.0 * 1e-6 * 9.80665
#: TE MS5611-01BA03 data sheet, "Technical data, pressure": resolution 0.012 mbar RMS at oversampling ratio 4096;
#: in Pa: x 100 Pa per mbar
MS5611_NOISE_PA = 0.012 * 100.0
#: u-blox NEO-M8 data sheet UBX-15031086, "Performance": horizontal position accuracy 2.5 m CEP (GPS + GLONASS),
#: velocity accuracy 0.05 m/s, navigation update rate 10 Hz (concurrent GNSS); CEP of a circular normal error =
#: sigma sqrt(2 ln 2) = 1.1774 sigma, so the per-axis sigma is 2.5 / 1.1774 m
NEO_M8_CEP_M, NEO_M8_VEL_M_S, NEO_M8_RATE_HZ = 2.5, 0.05, 10.0


def test_ublox_profile_values_are_the_data_sheet_figures() -> None:
    cfg = SensorConfig.profile("ublox_m8")
    assert cfg.gyro.noise_density == pytest.approx(ICM20602_GYRO_DENSITY_RAD_S, rel=1e-9)
    assert cfg.gyro.noise_density == pytest.approx(6.98e-5, rel=1e-3)  # the same figure, worked out by hand
    assert cfg.accel.noise_density == pytest.approx(ICM20602_ACCEL_DENSITY_M_S2, rel=1e-9)
    assert cfg.accel.noise_density == pytest.approx(9.81e-4, rel=1e-3)
    assert cfg.baro.noise_std == pytest.approx(MS5611_NOISE_PA, rel=1e-9)
    assert cfg.gps.eph_m == NEO_M8_CEP_M and cfg.gps.rate_hz == NEO_M8_RATE_HZ
    assert cfg.gps.pos_gm_std_h_m == pytest.approx(NEO_M8_CEP_M / math.sqrt(2.0 * math.log(2.0)), rel=1e-4)
    assert cfg.gps.vel_noise_std_m_s == NEO_M8_VEL_M_S


def test_ublox_profile_gyro_noise_measured_has_the_data_sheet_density() -> None:
    """The profile's gyro noise as the suite draws it (other gyro errors off): per-sample std = density / sqrt(dt)."""
    dt = 0.004
    gyro = SensorConfig.profile("ublox_m8").gyro.replace(drift_std=0.0, turn_on_bias_std=0.0)
    suite = SensorSuite(SensorConfig.noise_free().replace(gyro=gyro), seed=11)
    g = np.array([suite.sample((k + 1) * dt, outputs()).gyro_body_rad_s for k in range(20000)])
    assert np.std(g[1:]) == pytest.approx(ICM20602_GYRO_DENSITY_RAD_S / math.sqrt(dt), rel=0.05)

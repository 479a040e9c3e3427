"""A fixed-wing replay's window start velocity read from the logged specific force (``validation.start_fit``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fmu_models.config import ConfigError
from fmu_models.fmi.host import FmuHost
from identification.flights import synthetic
from identification.logs.log_state import initial_values_at
from identification.logs.readers import read_log
from identification.validation.output_map import FIXED_WING
from identification.validation.replay import ReplaySetup, options, replay_setup
from identification.validation.start_fit import START_FORCE_MAX_CHANGE_M_S, UNKNOWNS
from identification.validation.workflow import ValidationJob, validate

#: a GPS velocity error [m/s] along body y and z (its forward speed right): about 1.4 degrees of sideslip and 0.9 of
#: angle of attack at 25 m/s
GPS_ERROR_BODY = (0.0, 0.6, 0.4)


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The synthetic fixed-wing flight (noise-free), as logged and with its GPS velocity off by ``GPS_ERROR``, and
    one whose lateral specific force reads 30 m/s^2 more than any sideslip gives."""
    d = tmp_path_factory.mktemp("startfit")
    t, sig = synthetic.fixed_wing_flight(seconds=12.0, rate_hz=50.0)
    off = dict(sig)
    ned = ("vel_north_m_s", "vel_east_m_s", "vel_down_m_s")
    err = np.array([_body_to_ned(*a) @ np.asarray(GPS_ERROR_BODY)
                    for a in zip(sig["roll_rad"], sig["pitch_rad"], sig["yaw_rad"], strict=True)])
    for j, name in enumerate(ned):
        off[name] = sig[name] + err[:, j]
    wild = dict(off)
    wild["accel_body_y_m_s2"] = sig["accel_body_y_m_s2"] + 30.0
    return {"clean": synthetic.write_csv_log(d / "clean.csv", t, sig),
            "off": synthetic.write_csv_log(d / "off.csv", t, off),
            "wild": synthetic.write_csv_log(d / "wild.csv", t, wild),
            "mapping": synthetic.write_mapping_toml(d / "mapping.toml")}


def _body_to_ned(roll: float, pitch: float, yaw: float) -> np.ndarray:
    from fmu_models.common.rotations import euler_to_dcm_rows

    return np.asarray(euler_to_dcm_rows(roll, pitch, yaw, np))


def _setup(fmu: Path, log_path: Path, mapping: Path, start_velocity: str,
           overrides: dict[str, float] | None = None) -> ReplaySetup:
    from fmu_models.signals.pwm_mapping import PwmMapping

    log = read_log(log_path)
    with FmuHost(fmu) as host:
        return replay_setup(host, log, log_path, FIXED_WING, options(start_velocity=start_velocity),
                            overrides or {}, PwmMapping.load(mapping))


def test_start_velocity_is_recovered_from_the_specific_force(fixed_wing_fmu: Path, flights) -> None:
    """A GPS velocity 0.6 m/s off along body y and 0.4 m/s along body z: the start read from the specific force is back
    within a twentieth of that error of the true body velocity at every window start, the logged one is not."""
    s = _setup(fixed_wing_fmu, flights["off"], flights["mapping"], "force")
    truth = initial_values_at(read_log(flights["clean"]), s.t[s.edges[:-1]], forward_from_airspeed=True)
    logged = initial_values_at(read_log(flights["off"]), s.t[s.edges[:-1]], forward_from_airspeed=True)
    assert s.start_fit is not None and s.start_fit.fitted == sum(s.included) > 0 and not s.start_fit.kept
    for i, ok in enumerate(s.included):
        if not ok:
            continue
        gps_error = np.hypot(*(logged[i][n] - truth[i][n] for n in UNKNOWNS))
        assert gps_error > 0.4
        assert np.hypot(*(s.starts[i][n] - truth[i][n] for n in UNKNOWNS)) < 0.05 * gps_error, i
    # a noise-free accelerometer: next to no restart noise to add (what noise_std reads in a manoeuvre's curvature)
    assert all(0.0 <= v < 0.005 for v in s.start_fit.start_std.values())
    off = _setup(fixed_wing_fmu, flights["off"], flights["mapping"], "logged")
    assert off.start_fit is None and off.starts == [{**x} for x in logged]


def test_replay_error_falls_and_the_one_step_check_stays_on_the_logged_start(fixed_wing_fmu: Path, flights,
                                                                           tmp_path: Path) -> None:
    """Same flight: the specific force's and yaw rate's replay errors fall at least fivefold from the logged start
    to the fitted one, while the one-step force check (the force model at the logged state) reads the same."""
    res = {}
    for sv in ("logged", "force"):
        job = ValidationJob(fixed_wing_fmu, flights["off"], options(start_velocity=sv), mapping=flights["mapping"])
        res[sv] = validate(job).replay
    for name in ("accel_body_y_m_s2", "accel_body_z_m_s2", "rate_body_z_rad_s"):
        assert res["force"].overall[name].rmse < 0.2 * res["logged"].overall[name].rmse, name
    for name, score in res["logged"].one_step.items():
        assert res["force"].one_step[name].fit.rmse == pytest.approx(score.fit.rmse, rel=1e-9)
    assert res["logged"].one_step["accel_body_y_m_s2"].fit.rmse > 0.05  # the GPS error shows there
    assert res["force"].options["start_velocity"] == "force"
    from identification.validation.report import validation_page
    from identification.validation.workflow import START_WORDS, result_of

    for sv, shown in (("force", True), ("logged", False)):
        job = ValidationJob(fixed_wing_fmu, flights["off"], options(start_velocity=sv), mapping=flights["mapping"])
        lines = result_of(res[sv], job).lines()
        assert any(START_WORDS in line for line in lines) is shown
        assert ("whose specific force matches" in validation_page(res[sv])) is shown


def test_a_force_no_plausible_start_makes_keeps_the_logged_velocity_and_says_so(fixed_wing_fmu: Path,
                                                                                flights) -> None:
    s = _setup(fixed_wing_fmu, flights["wild"], flights["mapping"], "force")
    logged = initial_values_at(read_log(flights["wild"]), s.t[s.edges[:-1]], forward_from_airspeed=True)
    assert s.start_fit is not None and s.start_fit.fitted == 0
    assert sum(s.start_fit.kept.values()) == sum(s.included)
    assert all(s.starts[i][n] == logged[i][n] for i in range(len(logged)) for n in UNKNOWNS)
    note = next(n for n in s.notes if n.startswith("start velocity:"))
    assert f"{sum(s.included)} of {sum(s.included)} window starts kept the GPS's" in note
    assert f"a change above {START_FORCE_MAX_CHANGE_M_S:g} m/s: {sum(s.included)}" in note  # the reason, then its count


def test_a_start_velocity_given_by_set_stays(fixed_wing_fmu: Path, flights) -> None:
    s = _setup(fixed_wing_fmu, flights["off"], flights["mapping"], "force", {"init_vel_body_y_m_s": 0.3})
    assert s.start_fit is None and all(x["init_vel_body_y_m_s"] == 0.3 for x in s.starts)


def test_start_velocity_option_is_checked() -> None:
    with pytest.raises(ConfigError, match="start_velocity"):
        options(start_velocity="gps")


def test_the_restart_noise_of_fitted_starts_is_the_error_they_have(fixed_wing_fmu: Path, tmp_path: Path) -> None:
    """With sensor noise the fitted v, w carry the accelerometer's noise through the solve: the std the replay
    gives the Monte Carlo (``start_std``) is the RMS of the fitted starts' actual errors against the noise-free
    flight's body velocity, within what 20 windows can tell (0.6-1.5)."""
    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0, noise=True, seed=3)
    clean_t, clean = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0)
    noisy = synthetic.write_csv_log(tmp_path / "noisy.csv", t, sig)
    s = _setup(fixed_wing_fmu, noisy, synthetic.write_mapping_toml(tmp_path / "m.toml"), "force")
    truth = initial_values_at(read_log(synthetic.write_csv_log(tmp_path / "clean.csv", clean_t, clean)),
                              s.t[s.edges[:-1]], forward_from_airspeed=True)
    assert s.start_fit is not None and s.start_fit.fitted == sum(s.included) >= 18
    assert set(s.start_fit.start_std) == set(UNKNOWNS)
    for name in UNKNOWNS:
        err = [s.starts[i][name] - truth[i][name] for i, ok in enumerate(s.included) if ok]
        rms = float(np.sqrt(np.mean(np.square(err))))
        assert 0.6 <= rms / s.start_fit.start_std[name] <= 1.5, (name, rms, s.start_fit.start_std[name])


def test_a_batch_manifest_sets_it_per_job_and_names_a_bad_value(tmp_path: Path) -> None:
    from identification.validation.workflow import ManifestError, load_manifest

    good = tmp_path / "good.toml"
    good.write_text("[defaults]\nstart_velocity = 'logged'\n[[job]]\nfmu = 'a.fmu'\nlog = 'a.bin'\n"
                    "[[job]]\nfmu = 'b.fmu'\nlog = 'b.bin'\nstart_velocity = 'force'\n")
    assert [j.options.start_velocity for j in load_manifest(good)] == ["logged", "force"]
    bad = tmp_path / "bad.toml"
    bad.write_text("[[job]]\nfmu = 'a.fmu'\nlog = 'a.bin'\nstart_velocity = 'gps'\n")
    with pytest.raises(ManifestError, match="start_velocity") as err:
        load_manifest(bad)
    assert "gps" in str(err.value)


def test_a_discrepancy_learned_from_other_starts_is_named() -> None:
    """The discrepancy records the start velocity of the replays it was learned from; scored on replays started
    the other way, the summary says its early-horizon errors do not match."""
    from types import SimpleNamespace

    from identification.validation.discrepancy import learn
    from identification.validation.workflow import _band_lines

    rng = np.random.default_rng(0)
    t = np.arange(1, 2001) / 50.0
    res = SimpleNamespace(t_s=t, windows=[(a, a + 2.0) for a in np.arange(20) * 2.0], maps=FIXED_WING[:1],
                          measured={FIXED_WING[0].fmu: 0.01 * rng.standard_normal(t.size)},
                          model={FIXED_WING[0].fmu: np.zeros(t.size)},
                          options={"window_s": 2.0, "rate_hz": 50.0, "start_velocity": "logged"})
    disc = learn([res], ["a.bin"])
    assert disc.start_velocity == "logged"
    info = {"signals": list(disc.signals), "start_velocity": "logged", "same_starts": False}
    r = SimpleNamespace(signals={}, replay=SimpleNamespace(bands=SimpleNamespace(info={"discrepancy": info})))
    assert any("--start-velocity logged, this replay uses another" in line for line in _band_lines(r))
    info["same_starts"] = True
    assert not any("--start-velocity" in line for line in _band_lines(r))

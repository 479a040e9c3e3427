"""``identify_thrust``: many flights, voltage or a hover battery state, the FMU's own thrust
function, baselines with skill intervals, nested CV, overrides, masses, parameter uncertainty.

Synthetic flights check the physics and the error paths; the shared PX4 and Erle logs check the
done-when figures (skipped when ../shared/data is absent).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import identification.logs.readers as readers
import identification.thrust.workflow as thrust_workflow
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from identification.thrust.dataset import ThrustDataError
from identification.thrust.model import ModelSpec, fmu_total_thrust
from identification.thrust.workflow import (
    CONSTANT,
    FlightSpec,
    FoldResult,
    Score,
    ThrustConfig,
    comparisons,
    identify_thrust,
    verdict_of,
)
from tests.conftest import shared_data

G = 9.80665
K_N = 9.0  #: synthetic motor: T_i = K_N * (u_i * V / 11.1)^2, u = (pwm - 1000)/1000


class VoltLog:
    """FlightLog stand-in: four motors swinging around hover, battery sagging, thrust ~ (u V)^2."""

    def __init__(self, mass_kg: float, v0: float, v1: float, seed: int, noise: float = 0.3,
                 voltage: bool = True, duration_s: float = 80.0) -> None:
        rng = np.random.default_rng(seed)
        t = np.arange(0.0, duration_s, 0.02)
        volt = np.linspace(v0, v1, t.size)
        u_hover = np.sqrt(mass_kg * G / 4 / K_N) * 11.1 / volt  # command for hover at this voltage
        swing = 0.08 * np.sin(2 * np.pi * t / 3.0)[:, None] + 0.05 * rng.standard_normal((t.size, 1))
        diff = 0.06 * np.sin(2 * np.pi * t[:, None] / np.array([1.1, 1.7, 2.3, 2.9]))
        u = np.clip(u_hover[:, None] + swing + diff, 0.08, 0.95)
        pwm = 1000.0 + 1000.0 * u
        thrust = (K_N * (u * volt[:, None] / 11.1) ** 2).sum(axis=1)
        self.signals = {f"motor_{k + 1}_pwm_us": (t, pwm[:, k]) for k in range(4)}
        self.signals["accel_body_z_m_s2"] = (t, -thrust / mass_kg + noise * rng.standard_normal(t.size))
        self.signals["armed"] = (t, np.ones(t.size))
        if voltage:
            self.signals["battery_voltage_v"] = (t, volt)
        self.path = f"synthetic-{seed}"

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self.signals:
            raise KeyError(name)
        return self.signals[name]


@pytest.fixture
def fake_logs(monkeypatch: pytest.MonkeyPatch) -> dict[str, VoltLog]:
    """Flight 'name' -> synthetic log; ``read_log`` returns it for a path of that name."""
    made: dict[str, VoltLog] = {}
    monkeypatch.setattr(readers, "read_log", lambda p, channel_map=None: made[Path(p).name])
    return made


def _cfg(names: list[tuple[str, float]], **kw: object) -> ThrustConfig:
    return ThrustConfig(flights=tuple(FlightSpec(Path(n), m) for n, m in names), **kw)  # type: ignore[arg-type]


def test_voltage_model_transfers_between_flights_and_beats_baselines(fake_logs: dict[str, VoltLog]) -> None:
    fake_logs["a"] = VoltLog(1.3, 12.4, 10.8, seed=1)
    fake_logs["b"] = VoltLog(1.0, 11.6, 10.2, seed=2)
    fake_logs["c"] = VoltLog(1.15, 12.0, 10.5, seed=3)
    r = identify_thrust(_cfg([("a", 1.3), ("b", 1.0), ("c", 1.15)], fmu_mass_kg=1.15))
    assert r.metrics["voltage_compensation"] and r.verdict == "win" and r.exit_code == 0
    for c in r.comparisons.values():  # every baseline beaten beyond noise pooled, and on no flight beaten
        assert c["pooled"]["outcome"] == "win" and c["pooled"]["skill_lo"] > 0.0
        assert "lose" not in {o["outcome"] for o in c["per_held_out"].values()}
    for f in r.folds:  # noise 0.3 m/s^2 x ~1.1 kg: the model should sit near the noise floor
        assert f.model.rmse_N < 0.5 < f.baselines["constant m g"].rmse_N
        assert f.model.rmse_N < min(s.rmse_N for k, s in f.baselines.items() if k.startswith(("poly", "const")))
    # physics of the written model: zero at idle, monotone in command, more thrust at higher voltage
    p = r.params
    pwm = np.linspace(900.0, 2100.0, 400)[:, None].repeat(4, axis=1)
    for v in (10.0, 11.1, 12.6):
        t = fmu_total_thrust(p, pwm, np.full(400, v))
        assert np.all(t[pwm[:, 0] <= p.pwm_idle_us] == 0.0)
        assert np.all(np.diff(t) >= -1e-9) and np.all(np.isfinite(t))
    hover = np.full((1, 4), 1600.0)
    assert fmu_total_thrust(p, hover, np.array([12.0]))[0] > fmu_total_thrust(p, hover, np.array([10.5]))[0]
    # true thrust at 1600 us and 11 V: 4 K (0.6 * 11 / 11.1)^2
    truth = 4 * K_N * (0.6 * 11.0 / 11.1) ** 2
    assert fmu_total_thrust(p, hover, np.array([11.0]))[0] == pytest.approx(truth, rel=0.05)


def test_one_flight_uses_time_blocked_folds(fake_logs: dict[str, VoltLog], tmp_path: Path) -> None:
    fake_logs["solo"] = VoltLog(1.2, 12.3, 10.6, seed=4)
    out = tmp_path / "p.json"
    r = identify_thrust(_cfg([("solo", 1.2)], out=out, n_folds_single=3))
    assert [f.held_out for f in r.folds] == [f"solo block {b}/3" for b in (1, 2, 3)]
    m = json.loads(out.with_suffix(".metrics.json").read_text())
    assert m["cross_validation"] == "3 time blocks" and len(m["folds"]) == 3
    assert m["flights"][0]["samples"] > 1000 and m["flights"][0]["voltage_range_V"][0] == pytest.approx(10.6, abs=0.05)
    section = json.loads(out.read_text())["quadrotor"]
    assert QuadrotorParams.from_dict(section).battery_nominal_V == pytest.approx(r.params.battery_nominal_V)


def test_without_voltage_the_hover_state_recovers_each_battery_and_a_static_map_loses(
    fake_logs: dict[str, VoltLog], tmp_path: Path
) -> None:
    """Same vehicle, batteries at different voltages, none logged. A static map cannot transfer (it loses to
    the constant m g: exit 3, no parameter file unless asked); the hover battery state, computed from each
    flight's own PWM and mass, recovers the level and wins."""
    fake_logs["hi"] = VoltLog(1.2, 12.6, 12.4, seed=5, voltage=False)
    fake_logs["lo"] = VoltLog(1.2, 10.4, 10.2, seed=6, voltage=False)
    flights = [("hi", 1.2), ("lo", 1.2)]
    out = tmp_path / "p.json"
    static = identify_thrust(_cfg(flights, out=out, calibrate="off", battery_state=False, n_mfs=1))
    assert static.verdict == "lose" and static.exit_code == 3 and static.written is None and not out.exists()
    c = static.comparisons["model vs constant m g"]
    assert c["pooled"]["outcome"] == "lose" and c["pooled"]["skill_hi"] < 0.0
    assert any("LOSES" in w and "constant m g" in w for w in static.warnings)
    m = json.loads(out.with_suffix(".metrics.json").read_text())
    assert m["verdict"] == "lose" and m["parameters_written"] is None and m["overrides"] == []
    kept = identify_thrust(_cfg(flights, out=out, calibrate="off", battery_state=False, n_mfs=1,
                                write_losing_model=True))
    assert kept.exit_code == 3 and kept.written == out and out.exists()  # written, and still says it loses
    assert any(o.startswith("--write-losing-model") for o in kept.overrides)
    assert json.loads(out.with_suffix(".metrics.json").read_text())["verdict"] == "lose"
    state = identify_thrust(_cfg(flights, calibrate="off", n_mfs=1))
    assert state.spec.tau_s is not None
    for f in state.folds:
        assert f.model.rmse_N < 0.5 * f.baselines["model without battery state"].rmse_N
        assert f.model.rmse_N < f.baselines["constant m g (battery state)"].rmse_N
    # like for like: the polynomial given the same hover state is the one-rule map (same features), so the
    # two tie within 1 %; the constant with the state stays far behind
    same = state.comparisons["model vs poly sum u^2, sum u (battery state)"]
    assert same["information"] == "battery state" and same["in_verdict"] and abs(same["rmse_ratio"] - 1.0) < 0.01
    assert state.comparisons["model vs constant m g (battery state)"]["pooled"]["outcome"] == "win"
    # without the state the map still loses to m g: reported (comparison and warning), not in the verdict
    raw = state.comparisons["model without battery state vs constant m g"]
    assert raw["information"] == "raw" and not raw["in_verdict"] and raw["pooled"]["outcome"] == "lose"
    assert any("not in the verdict" in w and "model without battery state vs constant m g" in w
               for w in state.warnings)
    assert state.metrics["verdict_levels"] == ["battery state"]
    assert state.metrics["headline"]["information"] == "battery state"
    # the FMU gets the state as an equivalent battery voltage: thrust scales with V / V_nom
    p = state.params
    assert p.thrust_voltage_exponent == 1.0
    pwm = np.full((1, 4), 1600.0)
    v = p.battery_nominal_V
    assert fmu_total_thrust(p, pwm, np.array([1.1 * v]))[0] == pytest.approx(1.1 * fmu_total_thrust(
        p, pwm, np.array([v]))[0], rel=1e-12)


def test_per_flight_calibration_recovers_the_level_and_replays_with_thrust_scale(
    fake_logs: dict[str, VoltLog]
) -> None:
    fake_logs["hi"] = VoltLog(1.2, 12.6, 12.4, seed=5, voltage=False)
    fake_logs["lo"] = VoltLog(1.2, 10.4, 10.2, seed=6, voltage=False)
    cal = identify_thrust(_cfg([("hi", 1.2), ("lo", 1.2)], calibrate="on", n_mfs=1, battery_state=False))
    for f in cal.folds:
        assert f.baselines["model (calibrated)"].rmse_N < f.baselines["constant m g (calibrated)"].rmse_N
    c = cal.comparisons["model (calibrated) vs constant m g (calibrated)"]
    assert c["pooled"]["outcome"] == "win" and c["information"] == "calibrated" and c["in_verdict"]
    assert set(cal.calibration) == {"hi", "lo"}
    # replaying a flight with its scale: the FMU's thrust over its hover samples averages m g
    lo = cal.params_for("lo")
    assert lo.thrust_scale == cal.calibration["lo"] != 1.0
    t = np.asarray(fake_logs["lo"].signals["motor_1_pwm_us"][0])
    pwm = np.stack([fake_logs["lo"].signals[f"motor_{k}_pwm_us"][1] for k in range(1, N_MOTORS + 1)], axis=1)
    mean = fmu_total_thrust(lo, pwm, np.full(t.size, lo.battery_nominal_V))[t > 1.5].mean()
    assert mean == pytest.approx(1.2 * G, rel=0.02)


def test_different_masses_need_the_fmu_mass_named(fake_logs: dict[str, VoltLog], tmp_path: Path) -> None:
    fake_logs["a"] = VoltLog(1.3, 12.4, 10.8, seed=1)
    fake_logs["b"] = VoltLog(1.0, 11.6, 10.2, seed=2)
    with pytest.raises(ThrustDataError, match=r"different masses \(a 1\.3 kg, b 1\.0 kg\).*--fmu-mass-kg"):
        identify_thrust(_cfg([("a", 1.3), ("b", 1.0)]))
    out = tmp_path / "p.json"
    r = identify_thrust(_cfg([("a", 1.3), ("b", 1.0)], out=out, fmu_mass_kg=1.25, n_mfs=1))
    data = json.loads(out.read_text())
    assert data["quadrotor"]["mass_kg"] == 1.25 == r.params.mass_kg
    assert data["_identification"]["flights"] == [{"flight": "a", "mass_kg": 1.3}, {"flight": "b", "mass_kg": 1.0}]


def test_parameter_file_carries_the_thrust_map_covariance_under_fmu_names(
    fake_logs: dict[str, VoltLog], tmp_path: Path
) -> None:
    from fmu_models.quadrotor.model import QuadrotorModel

    fake_logs["a"] = VoltLog(1.2, 12.4, 10.8, seed=1)
    fake_logs["b"] = VoltLog(1.2, 11.6, 10.2, seed=2)
    out = tmp_path / "p.json"
    r = identify_thrust(_cfg([("a", 1.2), ("b", 1.2)], out=out))
    unc = json.loads(out.read_text())["uncertainty"]
    names, mean, cov = unc["names"], np.array(unc["mean"]), np.array(unc["covariance"])
    params = QuadrotorParams.from_dict(json.loads(out.read_text())["quadrotor"])
    fmu_params = {v.name: v.start for v in QuadrotorModel(params).params.variables}
    assert names and set(names) <= set(fmu_params)  # FMU parameter names: usable as FMPy start values
    np.testing.assert_allclose(mean, [fmu_params[n] for n in names])
    assert cov.shape == (len(names), len(names)) and np.allclose(cov, cov.T)
    assert np.all(np.linalg.eigvalsh(cov) > 0.0)
    assert r.uncertainty["names"] == names
    # truth T_i = K (u V / 11.1)^2 = K (V_nom / 11.1)^2 (u r)^2: the physical input u_eff, coefficients
    # (K (V_nom/11.1)^2, 0); the estimate lies within 4 standard deviations of it, and those are small
    if r.spec.input_name == "u_eff" and r.spec.n_rules == 1:
        truth = np.array([K_N * (r.spec.nominal_V / 11.1) ** 2, 0.0])
        sd = np.sqrt(np.diag(cov))
        assert np.all(np.abs(mean - truth) <= 4.0 * sd) and sd[0] < 0.01 * truth[0]
    else:
        pytest.fail(f"expected one rule on u_eff for a (u V)^2 motor, got {r.spec.describe()}")


@pytest.mark.parametrize("mass", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_mass_names_flight_and_field(mass: float) -> None:
    with pytest.raises(ThrustDataError, match=r"flight f8\.csv: field mass_kg"):
        identify_thrust(_cfg([("f8.csv", mass)]))


def test_bad_logs_name_flight_and_field(fake_logs: dict[str, VoltLog]) -> None:
    log = VoltLog(1.2, 12.0, 11.0, seed=7)
    del log.signals["motor_3_pwm_us"]
    fake_logs["nomotor"] = log
    with pytest.raises(ThrustDataError, match=r"flight nomotor.*motor_3_pwm_us"):
        identify_thrust(_cfg([("nomotor", 1.2)]))
    log = VoltLog(1.2, 12.0, 11.0, seed=8)
    t = log.signals["motor_1_pwm_us"][0]
    for k in range(1, N_MOTORS + 1):
        log.signals[f"motor_{k}_pwm_us"] = (t, np.full(t.size, 1050.0))
    fake_logs["ground"] = log
    with pytest.raises(ThrustDataError, match=r"flight ground: only 0 airborne samples"):
        identify_thrust(_cfg([("ground", 1.2)]))
    for bad in (0.0, math.nan):
        log = VoltLog(1.2, 12.0, 11.0, seed=9)
        log.signals["battery_voltage_v"] = (t, np.full(t.size, bad))
        fake_logs["flat"] = log
        with pytest.raises(ThrustDataError, match=r"flight flat: field 'battery_voltage_v'.*zero or NaN"):
            identify_thrust(_cfg([("flat", 1.2)]))


# --------------------------------------------------------------------------- shared real logs
PX4 = (("drone1-8", 1.32), ("drone1-10", 1.085))
ERLE = ("arducopter_x_quad_real_218.BIN", "arducopter_x_quad_real_104.BIN", "arducopter_x_quad_real_105.BIN")


def _px4_flights() -> tuple[FlightSpec, ...]:
    return tuple(FlightSpec(shared_data("quadrotor_px4_csv", n), m) for n, m in PX4)


def _erle_flights() -> tuple[FlightSpec, ...]:
    return tuple(FlightSpec(shared_data("quadrotor", n), 1.14) for n in ERLE)


@pytest.mark.slow
def test_px4_lofo_beats_every_baseline_raw_and_the_fmu_evaluates_it(tmp_path: Path) -> None:
    """Done-when (PX4, voltage logged): raw LOFO RMSE <= 0.95 x the best baseline's, no baseline beats the
    model on any held-out flight; the FMU built from the written file gives exactly the scored thrust."""
    out = tmp_path / "px4.json"
    r = identify_thrust(ThrustConfig(flights=_px4_flights(), out=out, fmu_mass_kg=1.2))
    raw = [c for k, c in r.comparisons.items() if k.startswith("model vs")]
    assert len(raw) == 3 and max(c["rmse_ratio"] for c in raw) <= 0.95
    assert r.verdict == "win" and all(c["pooled"]["outcome"] == "win" for c in raw)
    for c in raw:
        assert "lose" not in {o["outcome"] for o in c["per_held_out"].values()}
    _fmu_matches_scored_function(out, r.params)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured: PX4 LOFO with per-flight hover calibration, pooled RMSE "
                   "1.014 N vs 1.054 N of the calibrated voltage polynomial = 0.962, above the 0.95 target, which "
                   "lies below the rival family's own fit on the held-out flight (study: 1.003 vs 0.999); no motor "
                   "lag, terminal voltage or fitted filter closes it (bench/thrust_dynamics_study.py)")
def test_px4_lofo_calibrated_within_095_of_the_best_calibrated_baseline() -> None:
    r = identify_thrust(ThrustConfig(flights=_px4_flights(), fmu_mass_kg=1.2, calibrate="on"))
    cal = [c for k, c in r.comparisons.items() if k.startswith("model (calibrated) vs")]
    assert all("lose" not in {o["outcome"] for o in c["per_held_out"].values()} for c in cal)
    assert max(c["rmse_ratio"] for c in cal) <= 0.95


def _fmu_matches_scored_function(params_file: Path, p: QuadrotorParams) -> None:
    from tests.fmu_models.test_thrust_voltage_model import fmu_thrust_total

    rng = np.random.default_rng(0)
    pwm = rng.uniform(1050.0, 2000.0, (40, N_MOTORS))
    volt = rng.uniform(9.5, 12.6, 40)
    np.testing.assert_allclose(fmu_thrust_total(params_file, pwm, volt), fmu_total_thrust(p, pwm, volt),
                               rtol=1e-9, atol=1e-9)


@pytest.mark.slow
def test_erle_every_rival_gets_the_same_side_information_and_the_headline_is_like_for_like() -> None:
    """Erle, no voltage. Every comparison pairs predictors with the same information from the held-out flight
    (none, their own hover battery state, their own calibration). Measured (LOFO, pooled): with the state the
    model beats m g given the state (0.595x) and ties the polynomial given the same state (0.998x); calibrated
    it beats m g and ties the polynomial; without the state it loses to m g (1.22x): reported, not in the
    verdict, which judges the information the FMU is used with."""
    r = identify_thrust(ThrustConfig(flights=_erle_flights()))
    assert r.metrics["per_flight_calibration"] and r.spec.tau_s is not None
    suffix = {"raw": "", "battery state": " (battery state)", "calibrated": " (calibrated)"}
    for c in r.comparisons.values():  # the baseline carries exactly the model's information
        b = c["baseline"]
        assert b.endswith(suffix[c["information"]]) and not b[: len(b) - len(suffix[c["information"]])].endswith(")")
    assert {c["information"] for c in r.comparisons.values()} == {"raw", "battery state", "calibrated"}
    state = r.comparisons["model vs constant m g (battery state)"]
    assert state["rmse_ratio"] <= 0.65 and {o["outcome"] for o in state["per_held_out"].values()} == {"win"}
    poly = r.comparisons["model vs poly sum u^2, sum u (battery state)"]
    assert poly["rmse_ratio"] <= 1.0 and poly["pooled"]["outcome"] != "lose"
    h = r.metrics["headline"]
    assert (h["information"], h["baseline"]) == ("battery state", "poly sum u^2, sum u (battery state)")
    raw = r.comparisons["model without battery state vs constant m g"]
    assert raw["pooled"]["outcome"] == "lose" and not raw["in_verdict"] and raw["rmse_ratio"] > 1.1
    for f in r.folds:  # the battery state is what wins: without it the same map is worse on every flight
        assert f.model.rmse_N < f.baselines["model without battery state"].rmse_N
    cal = {k: c for k, c in r.comparisons.items() if c["information"] == "calibrated"}
    assert set(cal) == {"model without battery state (calibrated) vs constant m g (calibrated)",
                        "model without battery state (calibrated) vs poly sum u^2, sum u (calibrated)"}
    for c in cal.values():
        assert c["in_verdict"] and "lose" not in {o["outcome"] for o in c["per_held_out"].values()}
    assert r.verdict == "tie" and r.exit_code == 0
    assert all(f["attitude_logged"] for f in r.flights)  # the hover condition uses T cos(roll) cos(pitch)
    assert all(0.8 < s < 1.25 for s in r.calibration.values())


@pytest.mark.slow
def test_erle_yaw_torque_replay_no_worse_than_holding_yaw_rate() -> None:
    """c = b/k by output error with its CR bound; replaying PWM with it is no worse than
    holding the logged yaw rate on the fitted flights."""
    r = identify_thrust(ThrustConfig(flights=_erle_flights(), calibrate="on"))
    yaw = r.metrics["yaw"]
    assert yaw["n_windows"] > 50 and 0.0 < yaw["crb_std_m"] < abs(yaw["torque_per_thrust_m"])
    assert yaw["rmse_identified_rad_s"] <= yaw["rmse_hold_rad_s"] < yaw["rmse_default_rad_s"]
    assert r.params.b_drag_N_m_s2 == pytest.approx(yaw["b_drag_N_m_s2"])
    # leave-one-flight-out against holding the rate, per flight; a loss is said in the warnings (standards)
    held = yaw["held_out_vs_holding_the_rate"]
    assert set(held) == {f.name for f in _erle_flights()} and all(h["windows"] > 10 for h in held.values())
    losers = [name for name, h in held.items() if h["outcome"] == "lose"]
    said = [w for w in r.warnings if w.startswith("yaw torque LOSES")]
    assert bool(losers) == bool(said) and all(name in said[0] for name in losers)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured: with the 1 s take-off/touch-down guard (ground contact out of "
                   "the data) the yaw torque fitted on 218 and 104 loses to holding the yaw rate on 105, skill "
                   "-0.09 [-0.15, -0.03]; the earlier win came from touch-down samples")
def test_erle_yaw_torque_on_a_held_out_flight_is_not_beaten_by_holding_the_rate() -> None:
    r = identify_thrust(ThrustConfig(flights=_erle_flights()))
    held = r.metrics["yaw"]["held_out_vs_holding_the_rate"]
    assert held["arducopter_x_quad_real_105.BIN"]["outcome"] != "lose"


class _Damaged:
    """A reader's data-quality summary of a log that lost 30 % of its flight time."""

    damage_fraction = 0.3

    def lines(self) -> list[str]:
        return ["damaged.bin: time jump(s) +1e+06 s at t=56.0 s: the log was split there and 24.0 s dropped"]

    def to_dict(self) -> dict[str, object]:
        return {"damage_fraction": self.damage_fraction, "lines": self.lines()}


def test_a_badly_damaged_flight_is_refused_unless_accepted(fake_logs: dict[str, VoltLog], tmp_path: Path) -> None:
    """Identification refuses a log whose damage exceeds the limit (file, damage and the option
    named); accepted, it trains, says what it overrode, and the damage is in the metrics."""
    from identification.logs.flightlog import LogError

    log = VoltLog(1.2, 12.0, 11.0, seed=11)
    log.quality = _Damaged()  # type: ignore[attr-defined]
    log.source = "damaged.bin"  # type: ignore[attr-defined]
    fake_logs["damaged.bin"] = log
    with pytest.raises(LogError, match=r"damaged\.bin: 30\.0 % of the log is damaged.*--accept-damaged-log"):
        identify_thrust(_cfg([("damaged.bin", 1.2)]))
    out = tmp_path / "p.json"
    r = identify_thrust(_cfg([("damaged.bin", 1.2)], out=out, accept_damaged_log=True, n_mfs=1))
    assert r.flights[0]["quality"]["damage_fraction"] == 0.3
    assert len(r.overrides) == 1 and r.overrides[0].startswith("--accept-damaged-log: using damaged.bin")
    assert "30.0 %" in r.overrides[0] and r.verdict == "win" and r.exit_code == 0  # the verdict stays its own
    assert json.loads(out.with_suffix(".metrics.json").read_text())["flights"][0]["quality"]["lines"]


def _fold(name: str, n: int, model_err_N: float, base_err_N: float, seed: int) -> FoldResult:
    """A held-out set of ``n`` samples at 10 Hz whose model and constant baseline miss the measured thrust by
    white errors of the given RMS [N]."""
    rng = np.random.default_rng(seed)
    measured = 11.0 + np.sin(np.arange(n) / 7.0)
    model = measured + model_err_N * rng.standard_normal(n)
    const = measured + base_err_N * rng.standard_normal(n)
    spec = ModelSpec(1100.0, 1900.0, 11.1, voltage=True)
    rmse = lambda p: float(np.sqrt(np.mean((p - measured) ** 2)))  # noqa: E731
    return FoldResult(name, n, Score(rmse(model), 0.0), {CONSTANT: Score(rmse(const), 0.0)}, 1.0, spec, 0.1,
                      {"measured": measured, "model": model, CONSTANT: const})


#: flight "a" (600 samples): the model far better; flight "b" (300): the constant better (0.1 N against 0.2 N).
#: Pooled, the model's squared error is 600 x 0.05^2 + 300 x 0.2^2 = 13.5 N^2 against 600 x 1^2 + 300 x 0.1^2
#: = 603 N^2: a clear pooled win that hides a held-out flight lost.
def _pooled_win_one_flight_lost() -> list[FoldResult]:
    return [_fold("a", 600, 0.05, 1.0, seed=1), _fold("b", 300, 0.2, 0.1, seed=2)]


def test_a_pooled_win_with_one_held_out_flight_lost_is_a_loss() -> None:
    comp = comparisons(_pooled_win_one_flight_lost(), calibrate=False, block_s=1.0)
    c = comp[f"model vs {CONSTANT}"]
    assert c["pooled"]["outcome"] == "win" and c["pooled"]["skill_lo"] > 0.0  # the case: pooled, a clear win
    assert c["per_held_out"]["a"]["outcome"] == "win" and c["per_held_out"]["b"]["outcome"] == "lose"
    assert verdict_of(comp) == "lose"


def test_identify_thrust_reports_a_pooled_win_with_a_lost_flight_as_losing(
        fake_logs: dict[str, VoltLog], monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The whole workflow on folds constructed as above: verdict, exit code, warning and metrics JSON all say it
    loses, and name the flight."""
    fake_logs["a"] = VoltLog(1.2, 12.3, 10.6, seed=1)
    fake_logs["b"] = VoltLog(1.2, 12.1, 10.4, seed=2)
    monkeypatch.setattr(thrust_workflow, "fold_results", lambda *_a, **_k: _pooled_win_one_flight_lost())
    out = tmp_path / "params.json"
    r = identify_thrust(_cfg([("a", 1.2), ("b", 1.2)], out=out))
    assert r.comparisons[f"model vs {CONSTANT}"]["pooled"]["outcome"] == "win"
    assert r.verdict == "lose" and not r.model_beats_baselines and r.exit_code == 3
    assert any("LOSES" in w and "loses on b" in w for w in r.warnings)
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert metrics["verdict"] == "lose" and metrics["parameters_written"] is None and not out.exists()


def test_folds_that_selected_different_structures_are_compared_each_by_its_own() -> None:
    """One fold selects a hover battery state and the other none: each fold's model and baselines are read by
    that fold's structure (once a KeyError), and where a fold has no state its baseline gets none either."""
    from identification.thrust.model import ModelSpec
    from identification.thrust.workflow import CONSTANT, FoldResult, Score, comparisons

    rng = np.random.default_rng(0)
    y = 10.0 + rng.normal(0.0, 1.0, 200)
    good, bad = y + rng.normal(0.0, 0.1, 200), np.full(200, 10.0)
    plain = ModelSpec(1000.0, 2000.0, 11.1, False)
    state = dataclasses.replace(plain, tau_s=10.0)
    s = Score(0.1, 0.9)
    with_state = FoldResult("a", 200, s, {}, 1.0, state, 0.1, {
        "measured": y, "model": good, "model without battery state": good, CONSTANT: bad,
        f"{CONSTANT} (battery state)": bad, "model without battery state (calibrated)": good,
        f"{CONSTANT} (calibrated)": bad})
    without = FoldResult("b", 200, s, {}, 1.0, plain, 0.1, {
        "measured": y, "model": bad, CONSTANT: good, "model (calibrated)": good, f"{CONSTANT} (calibrated)": bad})
    comp = comparisons([with_state, without], True, 2.0)
    state_row = comp[f"model vs {CONSTANT} (battery state)"]
    # fold b: the model without a state (bad) against the constant without one (good): a loss there
    assert state_row["per_held_out"]["a"]["outcome"] == "win" and state_row["per_held_out"]["b"]["outcome"] == "lose"
    cal = comp[f"model without battery state (calibrated) vs {CONSTANT} (calibrated)"]
    assert cal["per_held_out"]["a"]["outcome"] == cal["per_held_out"]["b"]["outcome"] == "win"

"""FMPy replay of logged flights through our FMUs: a log of the same model replays exactly, a wrong mass
scores worse, windows limit drift, angles wrap, and bad input is named."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fmu_models.fmi.host import FmuHost, FmuRunError
from identification.flights import synthetic
from identification.flights.scenarios import QuadrotorAutopilot, fly, published_thrust_inverse
from identification.logs.readers import read_log
from identification.validation import output_map
from identification.validation.replay import ValidationInputError, replay


@pytest.fixture(scope="module")
def quad_log(quadrotor_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 12 s closed-loop climb to 6 m with a yaw step, flown by the FMU, as a CSV log at 50 Hz."""
    ap = QuadrotorAutopilot(lambda t: 0.0 if t < 1 else 6.0, published_thrust_inverse(), gravity_m_s2=9.8069,
                            yaw_rad=lambda t: 0.3 if t > 5 else 0.0)
    rec = fly(quadrotor_fmu, ap, 12.0, 0.02)
    assert rec.outputs["altitude_m"].max() > 4.0  # the flight went somewhere
    path = tmp_path_factory.mktemp("val") / "quad.csv"
    return synthetic.write_csv_log(path, rec.t_s, synthetic.recording_signals(rec))


def test_same_model_replays_its_own_log(quadrotor_fmu: Path, quad_log: Path) -> None:
    with FmuHost(quadrotor_fmu) as host:
        res = replay(host, read_log(quad_log), quad_log, output_map.QUADROTOR, rate_hz=50.0, window_s=None)
    for name in ("altitude_m", "roll_rad", "pitch_rad", "yaw_rad", "rate_body_z_rad_s"):
        assert res.overall[name].rmse < 1e-6, name
    # paper 000 Fig. 5: in a recorded flight F_z = -m a_z equals the thrust up to drag
    assert res.overall["thrust_total_N"].theil_u < 0.02
    assert not res.failed
    assert res.fmu["guid"] and res.log["sha256"] and res.fmu["parameters"]["mass_kg"] == pytest.approx(1.14)


def test_wrong_mass_scores_worse_and_windows_limit_the_drift(quadrotor_fmu: Path, quad_log: Path) -> None:
    log = read_log(quad_log)
    with FmuHost(quadrotor_fmu) as host:
        full = replay(host, log, quad_log, output_map.QUADROTOR, window_s=None, start_values={"mass_kg": 1.3})
        win = replay(host, log, quad_log, output_map.QUADROTOR, window_s=2.0, start_values={"mass_kg": 1.3})
    assert full.overall["altitude_m"].rmse > 0.5
    assert len(win.windows) == 6
    assert win.overall["altitude_m"].rmse < full.overall["altitude_m"].rmse


def test_yaw_is_compared_modulo_two_pi() -> None:
    m = replace(output_map.QUADROTOR[3])
    assert m.wrap
    measured = np.array([3.1, -3.1, 0.0])
    model = np.array([-3.15, 3.15, 2 * np.pi])
    np.testing.assert_allclose(m.align(model, measured) - measured, [-6.25 + 2 * np.pi, 6.25 - 2 * np.pi, 0.0],
                               atol=1e-12)


def test_missing_signal_and_unit_mismatch_are_named(quadrotor_fmu: Path, quad_log: Path) -> None:
    log = read_log(quad_log)
    del log.signals["yaw_rad"]
    with FmuHost(quadrotor_fmu) as host, pytest.raises(ValidationInputError, match="yaw_rad"):
        replay(host, log, quad_log, output_map.QUADROTOR)
    maps = output_map.from_dict({"signals": {"altitude_m": {"log": "altitude_m", "log_unit": "deg"}}}, "quadrotor")
    with FmuHost(quadrotor_fmu) as host, pytest.raises(output_map.OutputMapError, match=r"deg.*rad.*'m'"):
        replay(host, read_log(quad_log), quad_log, maps)


def test_output_map_config_is_checked() -> None:
    with pytest.raises(output_map.OutputMapError) as err:
        output_map.from_dict({"thresholds": {"max_theil": -1},
                              "signals": {"roll_rad": {"log": "roll_rad", "scle": 2}, "x": {"scale": 1.0}}},
                             "fixed_wing", "map.toml")
    text = str(err.value)
    assert "map.toml" in text and "max_theil = -1" in text and "scle" in text and "'log'" in text
    extra = output_map.from_dict({"signals_extra": {"altitude_m": {"log": "BARO.Alt", "log_unit": "cm"}}},
                                 "quadrotor")
    assert [m.fmu for m in extra] == [m.fmu for m in output_map.QUADROTOR]  # replaced in place
    alt = next(m for m in extra if m.fmu == "altitude_m")
    np.testing.assert_allclose(alt.convert(np.array([250.0]), "m", {}), [2.5])


def test_fmu_errors_become_messages(tmp_path: Path) -> None:
    bad = tmp_path / "broken.fmu"
    bad.write_bytes(b"not a zip")
    with pytest.raises(FmuRunError, match=r"broken\.fmu"):
        FmuHost(bad)
    with pytest.raises(FmuRunError, match="not found"):
        FmuHost(tmp_path / "absent.fmu")


def test_a_simulation_names_a_start_value_input_or_output_the_fmu_does_not_have(quadrotor_fmu: Path) -> None:
    """FMPy, not validating, skips an unknown start value without a word: the host refuses it by name, and the
    same instance goes on."""
    t = np.arange(3) * 0.01
    with FmuHost(quadrotor_fmu) as host:
        with pytest.raises(FmuRunError, match="'init_pos_dwn_m'"):
            host.simulate(t, {}, ["altitude_m"], {"init_pos_dwn_m": -10.0})
        with pytest.raises(FmuRunError, match="'pwm_9_us'"):
            host.simulate(t, {"pwm_9_us": np.full(3, 1500.0)}, ["altitude_m"])
        with pytest.raises(FmuRunError, match="'altitude'"):
            host.simulate(t, {}, ["altitude"])
        res = host.simulate(t, {}, ["altitude_m"], {"init_pos_down_m": -10.0})
        np.testing.assert_allclose(res["altitude_m"][0], 10.0)


def test_fmu_error_mid_run_is_reported(quadrotor_fmu: Path, quad_log: Path) -> None:
    """A log whose motor PWM leaves the FMU's input range makes the FMU return fmi2Error: a message naming the
    input, and the host stays usable."""
    log = read_log(quad_log)
    sig = log.signal("motor_1_pwm_us")
    sig.values[200:] = 2600.0  # the FMU accepts 0..2500 us
    with FmuHost(quadrotor_fmu) as host:
        with pytest.raises(FmuRunError, match="pwm_1_us"):
            replay(host, log, quad_log, output_map.QUADROTOR, window_s=None)
        log.signal("motor_1_pwm_us").values[200:] = 1500.0
        res = replay(host, log, quad_log, output_map.QUADROTOR, window_s=2.0)  # the same instance goes on
        assert res.overall["altitude_m"].rmse < 5.0


def test_log_state_angles_and_rotation() -> None:
    import casadi as ca

    from fmu_models.common.rigid_body import quat_from_euler, quat_to_dcm
    from identification.logs.flightlog import Signal
    from identification.logs.log_state import _euler_dcm, resample_angle

    for r, p, y in [(0.3, -0.2, 1.1), (-1.0, 0.5, -2.5)]:
        np.testing.assert_allclose(_euler_dcm(r, p, y), np.asarray(ca.DM(quat_to_dcm(quat_from_euler(r, p, y)))),
                                   atol=1e-12)
    # a log's yaw wrapping from 359 deg to 1 deg: halfway between is 0, not 180 deg
    yaw = Signal("yaw_rad", np.array([0.0, 1.0]), np.radians([359.0, 1.0]), "rad")
    np.testing.assert_allclose(resample_angle(yaw, np.array([0.5])), [0.0], atol=1e-12)


@pytest.fixture(scope="module")
def lagged_log(quadrotor_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The climb with a yaw step of ``quad_log``, flown by the FMU with a 50 ms motor lag (CSV at 50 Hz)."""
    ap = QuadrotorAutopilot(lambda t: 0.0 if t < 1 else 6.0, published_thrust_inverse(), gravity_m_s2=9.8069,
                            yaw_rad=lambda t: 0.3 if t > 5 else 0.0)
    rec = fly(quadrotor_fmu, ap, 12.0, 0.02, start_values={"tau_motor_s": LAG_S})
    path = tmp_path_factory.mktemp("val") / "lagged.csv"
    return synthetic.write_csv_log(path, rec.t_s, synthetic.recording_signals(rec))


LAG_S = 0.05


def test_restarts_begin_with_the_motors_where_they_lag(quadrotor_fmu: Path, lagged_log: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A model with a motor lag replaying its own log from restarts every 0.5 s: with each restart's motors at
    the thrust they lag at there it reproduces the log; restarted at the commanded thrust it does not."""
    from identification.validation import replay as replay_module

    log = read_log(lagged_log)
    with FmuHost(quadrotor_fmu) as host:
        res = replay(host, log, lagged_log, output_map.QUADROTOR, window_s=0.5, start_values={"tau_motor_s": LAG_S})
        monkeypatch.setattr(replay_module, "lagged_thrust", lambda *a: {})
        cold = replay(host, log, lagged_log, output_map.QUADROTOR, window_s=0.5, start_values={"tau_motor_s": LAG_S})
    for name in ("rate_body_z_rad_s", "yaw_rad", "altitude_m"):  # measured: 1e-6 against 5e-4..3e-3
        assert cold.overall[name].rmse > 1e-4, name
        assert res.overall[name].rmse < 0.01 * cold.overall[name].rmse, name


def test_lagged_thrust_is_the_first_order_lag_of_the_commands(quadrotor_fmu: Path, lagged_log: Path) -> None:
    """``lagged_thrust`` against the exact discretisation of ``tau dT/dt = T_cmd - T`` over held commands, the
    commanded thrust read from the same FMU without a lag."""
    from identification.validation.replay import INIT_THRUST, lagged_thrust, log_inputs

    log = read_log(lagged_log)
    t = np.arange(0.0, 8.0, 0.02)
    with FmuHost(quadrotor_fmu) as host:
        inputs = log_inputs("quadrotor", log, t, None)
        inputs["battery_voltage_V"] = np.full(len(t), host.start_value("battery_voltage_V"))
        start = {"tau_motor_s": LAG_S, "init_pos_down_m": -50.0}
        a = 300  # 6 s: after the yaw step, the motors still settling
        got = lagged_thrust(host, t, inputs, a, start)
        cmd = host.simulate(t[:a + 1], {k: v[:a + 1] for k, v in inputs.items()},
                            [f"thrust_{j}_N" for j in range(1, 5)], {"tau_motor_s": 0.0, "init_pos_down_m": -50.0})
        assert lagged_thrust(host, t, inputs, 0, start) == {}  # nothing logged before the first sample
        assert lagged_thrust(host, t, inputs, a, {**start, "tau_motor_s": 0.0}) == {}  # no lag: nothing to carry
    alpha = 1.0 - np.exp(-0.02 / LAG_S)
    for j, name in enumerate(INIT_THRUST, start=1):
        c = np.asarray(cmd[f"thrust_{j}_N"])  # row k + 1: the command held over step k (FMPy samples after it)
        lag = c[0]
        for k in range(a):
            lag += alpha * (c[k + 1] - lag)
        assert got[name] == pytest.approx(lag, rel=1e-4)
        assert abs(got[name] - c[a]) > 1e-3  # the lagged thrust is not the command: the case that matters


def test_commands_faster_than_the_grid_are_named(quad_log: Path) -> None:
    from identification.validation.replay import command_rate_notes

    log = read_log(quad_log)  # motor commands at 50 Hz
    assert command_rate_notes(log, 50.0) == []
    (note,) = command_rate_notes(log, 10.0)
    assert "logged at 50 Hz, replayed on a 10 Hz grid" in note and "--rate-hz 50" in note

"""quadrotor.fmu through FMPy, exactly as an importer uses it: validation, physics, state, errors."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import calloc, extract, free, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.validation import validate_fmu
from scipy.optimize import brentq

from fmu_models.common.simulate import Simulator
from fmu_models.quadrotor.model import QuadrotorModel


class Instance:
    """A small FMU2Slave driver that captures the FMU's log messages.

    The logger callback lives as long as this object and ``close()`` always frees the instance (FMPy's
    ``simulate_fmu`` leaves an instance holding a dead logger when a step fails: don't use it for that).
    """

    def __init__(self, fmu: Path, unzip: Path | None = None, **start: float) -> None:
        self.md = read_model_description(str(fmu))
        self.dir = str(unzip) if unzip else extract(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.messages: list[tuple[int, str]] = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._on_log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="test")
        self.s.instantiate(callbacks=self.callbacks, loggingOn=False)
        self.start(**start)

    def _on_log(self, env, name, status, category, message) -> None:
        self.messages.append((int(status), message.decode() if isinstance(message, bytes) else str(message)))

    def __enter__(self) -> Instance:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def text(self) -> str:
        return "\n".join(m for _, m in self.messages)

    def start(self, **start: float) -> None:
        self.messages.clear()
        self.s.setupExperiment(startTime=0.0)
        if start:
            self.set(**start)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()
        self.t = 0.0

    def set(self, **values: float) -> None:
        self.s.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, *names: str) -> list[float]:
        return self.s.getReal([self.vr[n] for n in names])

    def step(self, h: float, n: int = 1) -> None:
        for _ in range(n):
            self.s.doStep(self.t, h)
            self.t += h

    def close(self) -> None:
        self.s.terminate()
        self.s.freeInstance()


def hover_pwm(g: float, mass: float = 1.14) -> float:
    amap = QuadrotorModel().defaults.thrust_map
    return brentq(lambda x: amap.evaluate([np.array([x])])[0] - mass * g, 6000.0, 6217.3, xtol=1e-12) / 4


def test_validator_reports_no_problems(quadrotor_fmu: Path) -> None:
    assert validate_fmu(str(quadrotor_fmu)) == []


def test_every_variable_has_unit_and_description(quadrotor_fmu: Path) -> None:
    md = read_model_description(str(quadrotor_fmu))
    units = {u.name for u in md.unitDefinitions}
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.unit in units, v.name
    assert md.defaultExperiment is not None and float(md.defaultExperiment.stopTime) > 0
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate


def test_every_physical_parameter_is_tunable_and_the_initial_state_fixed(quadrotor_fmu: Path) -> None:
    md = read_model_description(str(quadrotor_fmu))
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    for name in ("mass_kg", "Jx_kg_m2", "arm_length_m", "k_thrust_N_s2", "anfis_mean_1_us", "anfis_cons_6_N",
                 "step_internal_s"):
        assert params[name].variability == "tunable"
    # read only when the initial state is computed: a change while stepping could not take effect
    for name in ("init_pos_down_m", "init_yaw_rad", "home_lat_deg", "home_height_m"):
        assert params[name].variability == "fixed"


def test_hover_within_1_cm_for_10_s(quadrotor_fmu: Path) -> None:
    fmu = Instance(quadrotor_fmu, init_pos_down_m=-10.0)
    g = fmu.get("gravity_m_s2")[0]
    pwm = hover_pwm(g)
    fmu.set(pwm_1_us=pwm, pwm_2_us=pwm, pwm_3_us=pwm, pwm_4_us=pwm)
    heights = []
    for _ in range(1000):
        fmu.step(0.01)
        heights.append(fmu.get("pos_down_m")[0])
    fmu.close()
    assert np.max(np.abs(np.array(heights) + 10.0)) < 0.01


def test_simulate_fmu_matches_python_physics(quadrotor_fmu: Path) -> None:
    sim = Simulator(QuadrotorModel())
    t_in = np.array([0.0, 1.0, 1.0, 3.0])  # a repeated time is a step change in FMPy's input
    pwm = np.array([[1550.0, 1540.0, 1545.0, 1530.0], [1550.0, 1540.0, 1545.0, 1530.0],
                    [1520.0, 1560.0, 1530.0, 1550.0], [1520.0, 1560.0, 1530.0, 1550.0]])
    dtype = [("time", float)] + [(f"pwm_{i}_us", float) for i in range(1, 5)]
    signals = np.array([(t, *row) for t, row in zip(t_in, pwm, strict=True)], dtype=dtype)
    res = simulate_fmu(str(quadrotor_fmu), stop_time=2.0, output_interval=0.01, input=signals,
                       start_values={"init_pos_down_m": -20.0},
                       output=["pos_north_m", "pos_east_m", "pos_down_m", "roll_rad", "pitch_rad", "yaw_rad"])
    p = sim.params(init_pos_down_m=-20.0)
    t, _X, Y = sim.run(lambda tt: pwm[0] if tt < 1.0 - 1e-9 else pwm[2], p, 2.0, 0.001)
    names = ["pos_north_m", "pos_east_m", "pos_down_m", "roll_rad", "pitch_rad", "yaw_rad"]
    for name in names:
        ref = np.interp(res["time"], t, Y[:, sim.model.outputs.index[name]])
        np.testing.assert_allclose(res[name], ref, atol=1e-6, err_msg=name)
    assert abs(res["roll_rad"][-1]) > 0.01  # the manoeuvre really rolled the vehicle


def test_any_communication_step_size(quadrotor_fmu: Path) -> None:
    finals = []
    for h, n in ((0.001, 1400), (0.01, 140), (0.0175, 80), (0.07, 20), (0.1, 14)):
        fmu = Instance(quadrotor_fmu, init_pos_down_m=-20.0, init_rate_body_x_rad_s=0.5)
        fmu.set(pwm_1_us=1560.0, pwm_2_us=1530.0, pwm_3_us=1545.0, pwm_4_us=1540.0)
        fmu.step(h, n)
        assert fmu.t == pytest.approx(1.4, abs=1e-9)
        finals.append(fmu.get("pos_down_m", "roll_rad", "yaw_rad"))
        fmu.close()
    # internal RK4 steps of at most 1 ms: every communication step gives the same answer
    np.testing.assert_allclose(finals, [finals[0]] * 5, atol=1e-6)


def test_state_get_set_serialize_round_trip_exactly(quadrotor_fmu: Path) -> None:
    fmu = Instance(quadrotor_fmu, init_pos_down_m=-20.0)
    fmu.set(pwm_1_us=1560.0, pwm_2_us=1530.0, pwm_3_us=1545.0, pwm_4_us=1540.0)
    fmu.step(0.01, 50)
    names = ["pos_down_m", "roll_rad", "pitch_rad", "yaw_rad", "vel_north_m_s", "rate_body_x_rad_s"]
    state = fmu.s.getFMUstate()
    blob = fmu.s.serializeFMUstate(state)
    t_saved = fmu.t
    fmu.step(0.01, 30)
    ref = fmu.get(*names)
    fmu.s.setFMUstate(state)
    fmu.t = t_saved
    fmu.step(0.01, 30)
    assert fmu.get(*names) == ref
    other = Instance(quadrotor_fmu)  # a fresh instance takes the serialized state
    other.s.setFMUstate(other.s.deSerializeFMUstate(blob))
    other.t = t_saved
    other.step(0.01, 30)
    assert other.get(*names) == ref
    fmu.s.freeFMUstate(state)
    fmu.close()
    other.close()


def test_nan_input_is_fmi2error_naming_the_variable(quadrotor_fmu: Path) -> None:
    with Instance(quadrotor_fmu) as fmu:
        fmu.set(pwm_3_us=float("nan"))
        with pytest.raises(FMICallException) as err:
            fmu.step(0.01)
        assert err.value.status == 3  # fmi2Error, not fmi2Fatal: the importer may reset or free the instance
        assert "pwm_3_us = nan" in fmu.text()


def test_out_of_range_pwm_is_an_error_and_reset_recovers(quadrotor_fmu: Path) -> None:
    with Instance(quadrotor_fmu) as fmu:
        fmu.set(pwm_1_us=3100.0)
        with pytest.raises(FMICallException) as err:
            fmu.step(0.01)
        assert err.value.status == 3
        # the message names when (the communication point) and what, with the whole allowed range
        assert "t = 0 s: input pwm_1_us = 3100.0 is outside its allowed range [0.0, 2500.0]" in fmu.text()
        fmu.s.reset()
        fmu.start()
        fmu.step(0.01)  # usable again after reset
        assert fmu.get("pos_down_m")[0] == pytest.approx(0.0, abs=1e-3)


def test_diverging_integration_is_an_error_naming_the_state(quadrotor_fmu: Path) -> None:
    # a 50 ms internal step on a 1000 rad/s ground spring: RK4 is unstable and the state blows up
    with Instance(quadrotor_fmu, step_internal_s=0.05, ground_wn_rad_s=1000.0, init_pos_down_m=0.05) as fmu:
        with pytest.raises(FMICallException) as err:
            fmu.step(0.05, 100)
        assert err.value.status == 3
        assert "integration diverged: state" in fmu.text()


def test_parameter_out_of_range_is_reported_at_initialisation(quadrotor_fmu: Path) -> None:
    fmu = Instance(quadrotor_fmu)
    fmu.s.reset()
    with pytest.raises(FMICallException) as err:
        fmu.start(mass_kg=-1.0)  # the native FMU refuses to leave initialisation with a bad parameter
    assert err.value.status == 3
    assert "parameter mass_kg = -1.0 is outside its allowed range [0.05, 50.0]" in fmu.text()
    with pytest.raises(FMICallException) as err:
        fmu.step(0.01)
    assert err.value.status == 3
    fmu.s.reset()  # and stays usable
    fmu.start()
    fmu.step(0.01)
    fmu.close()


def test_reset_restores_initial_state(quadrotor_fmu: Path) -> None:
    fmu = Instance(quadrotor_fmu)
    fmu.set(pwm_1_us=1700.0, pwm_2_us=1700.0, pwm_3_us=1700.0, pwm_4_us=1700.0)
    fmu.step(0.01, 200)
    assert fmu.get("pos_down_m")[0] < -1.0
    fmu.s.reset()
    fmu.start()
    # back on the ground at its contact equilibrium (sunk g / ground_wn^2 = 1 mm), at rest
    assert fmu.get("pos_down_m", "vel_down_m_s") == pytest.approx([9.81 / 100.0**2, 0.0], abs=1e-5)
    fmu.close()


def test_tunable_mass_changed_mid_run_halves_the_specific_force(quadrotor_fmu: Path) -> None:
    with Instance(quadrotor_fmu, init_pos_down_m=-10.0) as fmu:
        fmu.set(pwm_1_us=1530.0, pwm_2_us=1530.0, pwm_3_us=1530.0, pwm_4_us=1530.0)
        fmu.step(0.01, 50)  # flying, thrust lags settled
        before = fmu.get("accel_body_z_m_s2", "thrust_total_N")
        mass = fmu.get("mass_kg")[0]
        fmu.set(mass_kg=2.0 * mass)  # while stepping: the outputs are recomputed at once
        after = fmu.get("accel_body_z_m_s2", "thrust_total_N")
        # same thrust, double mass: half the specific force (accelerometer reading)
        assert after[1] == pytest.approx(before[1], rel=1e-12)
        assert after[0] == pytest.approx(0.5 * before[0], rel=1e-9)
        fmu.step(0.01)
        assert fmu.get("accel_body_z_m_s2")[0] == pytest.approx(0.5 * before[0], rel=1e-2)


def test_out_of_band_warns_once_and_sets_flag(quadrotor_fmu: Path) -> None:
    with Instance(quadrotor_fmu, pwm_1_us=1300.0, pwm_2_us=1300.0, pwm_3_us=1300.0, pwm_4_us=1300.0) as fmu:
        flags = []
        for _ in range(100):
            fmu.step(0.01)
            flags.append(fmu.s.getBoolean([fmu.vr["thrust_map_out_of_range"]])[0])
        assert all(flags)
        assert sum("trained band" in m for _, m in fmu.messages) == 1
        assert 0.0 < fmu.get("thrust_total_N")[0] < 10.0


def test_casadi_fallback_gives_the_same_answer(python_fmus: dict[str, Path], tmp_path: Path) -> None:
    quadrotor_fmu = python_fmus["quadrotor"]  # the pythonfmu backend's fallback when its C library cannot load
    with zipfile.ZipFile(quadrotor_fmu) as z:
        z.extractall(tmp_path / "full")
    shutil.copytree(tmp_path / "full", tmp_path / "nolib")
    (tmp_path / "nolib" / "resources" / "quadrotor_model.so").unlink()
    out = []
    for d in ("full", "nolib"):
        fmu = Instance(quadrotor_fmu, unzip=tmp_path / d, init_pos_down_m=-10.0)
        fmu.set(pwm_1_us=1560.0, pwm_2_us=1530.0, pwm_3_us=1545.0, pwm_4_us=1540.0)
        fmu.step(0.01, 50)
        out.append(fmu.get("pos_down_m", "roll_rad", "yaw_rad"))
        fmu.close()
    np.testing.assert_allclose(out[0], out[1], rtol=0, atol=1e-12)

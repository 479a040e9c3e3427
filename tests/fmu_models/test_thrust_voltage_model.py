"""The quadrotor model's thrust function: the published summed-PWM map unchanged at nominal voltage, the
identified per-motor feature maps zero at idle, monotone, physical outside the band, voltage or equivalent
voltage (battery state) as the FMU input; the FMU's CasADi expression equals the numpy function."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.quadrotor.anfis import AnfisMap, published_map
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import ThrustConstants, constants_of, motor_thrust, thrust_sum


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(QuadrotorModel())


def _thrust(sim: Simulator, pwm: float, volt: float | None, **p: float) -> float:
    u = np.full(4, pwm) if volt is None else np.array([pwm] * 4 + [volt])
    return float(np.sum([float(t) for t in sim.model.commanded_thrust(u, sim.params(**p))]))


def test_nominal_voltage_reproduces_the_published_map(sim: Simulator) -> None:
    amap = published_map()
    for pwm in (1460.0, 1500.0, 1530.0, 1550.0):  # inside the band 5800..6217 us summed
        want = float(amap.evaluate([4 * pwm]))
        assert _thrust(sim, pwm, None) == pytest.approx(want, rel=1e-12)
        assert _thrust(sim, pwm, 11.1) == pytest.approx(want, rel=1e-12)  # input start = battery_nominal_V
    assert sim.model.inputs.variables[4].name == "battery_voltage_V"
    assert sim.model.inputs.variables[4].start == pytest.approx(11.1)


def test_voltage_raises_thrust_like_the_speed_squared(sim: Simulator) -> None:
    low, high = _thrust(sim, 1530.0, 10.0), _thrust(sim, 1530.0, 12.6)
    assert low < _thrust(sim, 1530.0, 11.1) < high
    assert _thrust(sim, 1530.0, 12.6, thrust_voltage_exponent=0.0) == pytest.approx(_thrust(sim, 1530.0, 11.1))
    assert _thrust(sim, 1530.0, 11.1, thrust_scale=0.9) == pytest.approx(0.9 * _thrust(sim, 1530.0, 11.1))


@pytest.mark.parametrize("volt", [0.0, 5.0, 11.1, 16.8])
def test_zero_at_idle_and_monotone_in_command_at_any_voltage(volt: float) -> None:
    amap = published_map()
    lo, hi = amap.input_range[0]
    pwm = np.linspace(900.0, 2200.0, 600)
    t = motor_thrust(amap, pwm, volt, ThrustConstants(1100.0, 2000.0, 11.1, 1.0, 1.0, lo, hi), 4)
    assert np.all(t[pwm <= 1100.0] == 0.0)
    assert np.all(np.isfinite(t)) and np.all(t >= 0.0)
    # monotone outside the band, where the physical extension holds (the published map folds inside)
    x = 4 * (1100.0 + (pwm - 1100.0).clip(0) * max(volt / 11.1, 0.01))
    out = (x < lo) | (x > hi)
    assert np.all(np.diff(t[out & (x < lo)]) >= 0.0) and np.all(np.diff(t[out & (x > hi)]) >= 0.0)
    np.testing.assert_allclose(t * 4, thrust_sum(amap, x, 4400.0, lo, hi))


def _feature_params(input_name: str = "u", features: tuple[str, ...] = ("x2", "x"), exponent: float = 1.0,
                    rules: int = 2) -> QuadrotorParams:
    """A two-rule per-motor map on u in [0.4, 0.8]: T ~ 9 u^2 + 1 u, the second rule a bit steeper."""
    cons = [(9.0, 1.0, 0.5)[: len(features)], (9.5, 0.8, 0.6)[: len(features)]][:rules]
    amap = AnfisMap(inputs=(input_name,), mf_type="gaussian", mf_mean=((0.45, 0.75)[:rules],),
                    mf_sigma=((0.2, 0.2)[:rules],), mf_slope=None, order=1, consequents=tuple(cons),
                    input_range=((0.4, 0.8),), features=features)
    return QuadrotorParams.from_dict({"pwm_idle_us": 1000.0, "pwm_full_us": 2000.0, "battery_nominal_V": 11.1,
                                      "thrust_voltage_exponent": exponent, "thrust_map": amap.to_dict()})


@pytest.mark.parametrize("input_name,features",
                         [("u", ("x2", "x")), ("u", ("x2", "x", "x2_r")), ("u_eff", ("x2", "x"))])
@pytest.mark.parametrize("volt", [9.0, 11.1, 12.6])
def test_feature_map_zero_at_idle_monotone_and_continuous_at_the_band_edges(
    input_name: str, features: tuple[str, ...], volt: float
) -> None:
    p = _feature_params(input_name, features, exponent=0.0 if len(features) == 3 else 1.0)
    c = constants_of(p)
    pwm = np.linspace(800.0, 2300.0, 3001)
    t = np.asarray(motor_thrust(p.thrust_map, pwm, volt, c, 4))
    assert np.all(t[pwm <= 1000.0] == 0.0) and np.all(np.isfinite(t)) and np.all(t >= 0.0)
    assert np.all(np.diff(t) >= -1e-12)  # monotone in the command across the band edges
    # continuous where the band starts and ends (x = u or u r at 0.4 and 0.8)
    r = volt / 11.1 if input_name == "u_eff" else 1.0
    for edge in (0.4, 0.8):
        at = 1000.0 + 1000.0 * edge / r
        lo_side, hi_side = motor_thrust(p.thrust_map, np.array([at - 1e-7, at + 1e-7]), volt, c, 4)
        assert hi_side == pytest.approx(lo_side, abs=1e-6)


def test_no_voltage_map_scales_with_the_equivalent_voltage_and_the_fmu_expression_matches() -> None:
    """A map identified without voltage (exponent 1): battery_voltage_V = V_nom s multiplies thrust by s;
    the CasADi expression the FMU compiles gives the numpy function's numbers."""
    p = _feature_params()
    model = QuadrotorModel(p)
    sim = Simulator(model)
    c = constants_of(p)
    for pwm in (1050.0, 1300.0, 1600.0, 1790.0, 2100.0):
        for s in (0.9, 1.0, 1.07):
            want = 4 * float(motor_thrust(p.thrust_map, pwm, 11.1 * s, c, 4))
            assert _thrust(sim, pwm, 11.1 * s) == pytest.approx(want, rel=1e-12, abs=1e-12)
            assert want == pytest.approx(s * 4 * float(motor_thrust(p.thrust_map, pwm, 11.1, c, 4)), rel=1e-12)
    names = {v.name for v in model.params.variables}
    assert {"anfis_cons_1_x2_N", "anfis_cons_2_x_N", "anfis_band_lo", "anfis_mean_2", "pwm_full_us"} <= names


def fmu_thrust_total(params_file, pwm: np.ndarray, volt: np.ndarray) -> np.ndarray:
    """Build the native quadrotor FMU from ``params_file`` and step it once per row: ``thrust_total_N`` [N]."""
    from fmpy import extract, instantiate_fmu, read_model_description

    from build_fmus import build

    fmu = build(params_file, params_file.parent / "fmu", ["quadrotor"])[0]
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    inst = instantiate_fmu(extract(str(fmu)), md)
    inst.setupExperiment(startTime=0.0)
    inst.enterInitializationMode()
    inst.exitInitializationMode()
    got = []
    refs = [vr[f"pwm_{i}_us"] for i in range(1, N_MOTORS + 1)] + [vr["battery_voltage_V"]]
    for k, (row, v) in enumerate(zip(pwm, volt, strict=True)):
        inst.setReal(refs, [*row, v])
        inst.doStep(currentCommunicationPoint=k * 1e-4, communicationStepSize=1e-4)
        got.append(inst.getReal([vr["thrust_total_N"]])[0])
    inst.terminate()
    inst.freeInstance()
    return np.array(got)


@pytest.mark.slow
@pytest.mark.parametrize("input_name,features,exponent", [("u", ("x2", "x"), 1.0), ("u_eff", ("x2", "x"), 0.0)])
def test_native_fmu_thrust_equals_the_python_function(tmp_path, input_name: str, features: tuple[str, ...],
                                                      exponent: float) -> None:
    """The native FMU built from an identified-style feature map gives the numpy function's thrust."""
    import json

    p = _feature_params(input_name, features, exponent)
    params_file = tmp_path / "params.json"
    params_file.write_text(json.dumps({"quadrotor": p.to_dict()}))
    rng = np.random.default_rng(0)
    pwm = rng.uniform(900.0, 2200.0, (60, N_MOTORS))  # below idle, inside and above the band
    volt = rng.uniform(9.0, 12.6, 60)
    want = np.asarray(motor_thrust(p.thrust_map, pwm, volt[:, None], constants_of(p), N_MOTORS)).sum(axis=1)
    np.testing.assert_allclose(fmu_thrust_total(params_file, pwm, volt), want, rtol=1e-9, atol=1e-9)

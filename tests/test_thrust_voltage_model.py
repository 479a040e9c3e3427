"""The quadrotor model's voltage-aware thrust: published map unchanged at nominal voltage, physics outside."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.quadrotor.anfis import published_map
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.thrust import motor_thrust, thrust_sum


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
    t = motor_thrust(amap, pwm, volt, 1100.0, lo, hi, 11.1, 1.0)
    assert np.all(t[pwm <= 1100.0] == 0.0)
    assert np.all(np.isfinite(t)) and np.all(t >= 0.0)
    # monotone outside the band, where the physical extension holds (the published map folds inside)
    x = 4 * (1100.0 + (pwm - 1100.0).clip(0) * max(volt / 11.1, 0.01))
    out = (x < lo) | (x > hi)
    assert np.all(np.diff(t[out & (x < lo)]) >= 0.0) and np.all(np.diff(t[out & (x > hi)]) >= 0.0)
    np.testing.assert_allclose(t * 4, thrust_sum(amap, x, 4400.0, lo, hi))

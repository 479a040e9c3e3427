"""A model's symbolic functions are traced once per structure and process, and never shared across structures."""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from fmu_models.common import model as model_module
from fmu_models.common.model import derivative_function, fingerprint, init_function, output_function, step_function
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from identification.quadrotor.motor_lag import ExactLagModel


def test_models_of_one_structure_share_their_functions_and_equal_a_fresh_trace() -> None:
    a, b = QuadrotorModel(), QuadrotorModel(QuadrotorParams())
    for fn in (step_function, init_function, derivative_function, output_function):
        assert fn(a) is fn(b), fn.__name__
    fresh = model_module._step_function(a)  # traced anew, no cache
    x, u, p = a.states.starts(), [1600.0] * 4 + [11.1], a.params.starts()
    x[9] = 1.0 if x[6] == 0.0 else x[9]
    for got, want in zip(step_function(a)(x, u, p, 0.004), fresh(x, u, p, 0.004), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    assert step_function(a, "other") is not step_function(a)  # the C name is part of the function
    assert step_function(a, with_outputs=False) is not step_function(a)


def test_another_structure_gets_its_own_functions() -> None:
    """Defaults the equations read as constants (the frame, the arm length under the landing gear) or as start
    values differ: each model gets its own trace, and the step moves it by its own physics."""
    base = QuadrotorModel()
    plus = QuadrotorModel(dataclasses.replace(QuadrotorParams(), frame="+"))
    longer = QuadrotorModel(dataclasses.replace(QuadrotorParams(), arm_length_m=QuadrotorParams().arm_length_m * 1.5))
    assert len({step_function(m) for m in (base, plus, longer)}) == 3
    assert step_function(FixedWingModel()) is not step_function(FixedWingModel(
        dataclasses.replace(FixedWingParams(), mass_kg=FixedWingParams().mass_kg + 1.0)))
    # the frame is read as a constant: the same start values, another motor layout, another step (a PWM split
    # that rolls an x frame pitches and rolls a + frame differently)
    u_split = [1550.0, 1450.0, 1450.0, 1550.0, 11.1]
    steps = []
    for m in (base, plus):
        p = m.params.starts()
        x0, _ = init_function(m)(u_split, p)
        steps.append(np.asarray(step_function(m)(x0, u_split, p, 0.05)[0], float).ravel())
    assert not np.allclose(steps[0][10:13], steps[1][10:13])


def test_exact_lag_keys_carry_its_sample_step_and_a_subclass_with_its_own_constructor_is_not_shared() -> None:
    assert step_function(ExactLagModel(sample_s=0.004)) is step_function(ExactLagModel(sample_s=0.004))
    assert step_function(ExactLagModel(sample_s=0.004)) is not step_function(ExactLagModel(sample_s=0.01))
    assert step_function(ExactLagModel()) is not step_function(QuadrotorModel())

    class Heavier(QuadrotorModel):  # its constructor takes what the defaults do not hold, and it says no key
        def __init__(self, extra_kg: float) -> None:
            super().__init__()
            self.extra_kg = extra_kg

    assert Heavier(1.0).structure_key() is None
    assert step_function(Heavier(1.0)) is not step_function(Heavier(1.0))


def test_fingerprint_tells_floats_apart_to_the_last_bit_and_refuses_what_it_cannot_read() -> None:
    assert fingerprint((0.1, "x", None, [1, 2], {"a": True})) == fingerprint((0.1, "x", None, [1, 2], {"a": True}))
    assert fingerprint(0.1) != fingerprint(math.nextafter(0.1, 1.0))
    assert fingerprint((1, 2)) != fingerprint([1, 2]) and fingerprint(1) != fingerprint(1.0)
    assert fingerprint(QuadrotorParams()) == fingerprint(QuadrotorParams())
    assert fingerprint(np.zeros(3)) is None and fingerprint(object()) is None


def test_the_cache_is_bounded() -> None:
    for i in range(model_module.TRACED_MAX + 5):
        derivative_function(FixedWingModel(dataclasses.replace(FixedWingParams(), mass_kg=10.0 + i)))
    assert len(model_module._TRACED) <= model_module.TRACED_MAX


def test_a_simulators_array_step_equals_its_casadi_step_bit_for_bit_and_returns_fresh_arrays() -> None:
    from fmu_models.common.simulate import Simulator

    sim = Simulator(QuadrotorModel())
    p = sim.params(init_pos_down_m=-10.0)
    u = sim.inputs(**{f"pwm_{k}_us": 1500.0 + 20.0 * k for k in range(1, 5)})
    x, _ = sim.initial(u, p)
    for _ in range(3):  # the kept buffers hold nothing over from one call to the next
        x1, y1 = sim.step(x, u, p, 0.004)
        xa, ya = sim.step_arrays(x, u, p, 0.004)
        np.testing.assert_array_equal(np.asarray(x1).ravel(), xa)
        np.testing.assert_array_equal(np.asarray(y1).ravel(), ya)
        kept = xa.copy()
        xb, _ = sim.step_arrays(xa, u[:4], p, 0.004)  # the battery voltage left out: its start value
        assert not np.array_equal(xb, xa)
        np.testing.assert_array_equal(xa, kept)  # a later call leaves what an earlier one returned as it was
        x = xa
    assert xa.shape == (len(sim.model.states),) and ya.shape == (len(sim.model.outputs),)


def test_a_numeric_call_refuses_an_argument_of_another_size_naming_it() -> None:
    from fmu_models.common.model import NumericCall

    m = QuadrotorModel()
    call = NumericCall(step_function(m))
    x, u, p = m.states.starts(), [1500.0] * 5, m.params.starts()
    with pytest.raises(ValueError, match="argument x has 3 elements, allowed 20"):
        call(x[:3], u, p, 0.004)
    with pytest.raises(ValueError, match="argument dt has 2 elements, allowed 1"):
        call(x, u, p, [0.004, 0.004])
    x[6] = 1.0  # a unit quaternion
    got = call(ca.DM(x), u, p, 0.004)  # CasADi matrices are read as CasADi gives them
    np.testing.assert_array_equal(got[0], call(np.array(x), u, p, 0.004)[0])

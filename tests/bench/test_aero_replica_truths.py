"""The fixed-wing replica's truth families: ``--fixed-spread zeros`` draws the coefficients a factor cannot move
(Aerosonde's zeros among the scaled ones) with the std the tool's consider covariance gives them, and leaves
every other draw as the factor family makes it; ``--fixed-spread consider`` draws every scaled coefficient that is
not a primary so, about its Aerosonde value."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))  # the bench imports its sibling scripts
import aero_replica as bench

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from identification.aero.priors import fixed_sd
from identification.estimation.oem import Manoeuvre


def _aerosonde() -> tuple[FixedWingModel, np.ndarray, list[Manoeuvre]]:
    """The model, Aerosonde's parameters and one manoeuvre starting at 25 m/s (the trim re-balance reads it)."""
    model = FixedWingModel(FixedWingParams())
    x0 = np.zeros(len(model.states))
    x0[model.states.index["vel_body_x_m_s"]] = 25.0
    return (model, np.array(model.params.starts(), dtype=float),
            [Manoeuvre(x0, np.zeros((1, len(model.inputs))), np.zeros((1, 1)), 0.02)])


def test_zeros_are_drawn_with_their_consider_std_and_the_rest_is_the_factor_family() -> None:
    model, p, data = _aerosonde()
    ix = model.params.index
    zeros = [n for n in dict.fromkeys(bench.SCALED) if p[ix[n]] == 0.0]
    assert set(zeros) == {"C_Y_p", "C_Y_r"}
    drawn = np.array([[bench.truth_params(model, p, np.random.default_rng(s), data, fixed_spread="zeros")[ix[n]]
                       for n in zeros] for s in range(400)])
    sd = np.array([fixed_sd(n, 0.0) for n in zeros])
    assert np.all(np.abs(drawn) <= 2.0 * sd + 1e-15)  # clipped at 2 std
    # a normal clipped at 2 std keeps sqrt(erf(sqrt 2) - 4 phi(2) + 4 P(|z| > 2)) = 0.96 of its std
    np.testing.assert_allclose(np.std(drawn, axis=0), 0.96 * sd, rtol=0.1)
    for s in range(5):  # everything else as the factor family draws it, C_m_0's re-balance included ...
        rng_a, rng_b = np.random.default_rng(s), np.random.default_rng(s)
        a = bench.truth_params(model, p, rng_a, data, fixed_spread="factor")
        b = bench.truth_params(model, p, rng_b, data, fixed_spread="zeros")
        other = [i for n, i in ix.items() if n not in zeros]
        np.testing.assert_array_equal(a[other], b[other])
        assert np.all(a[[ix[n] for n in zeros]] == 0.0)
        assert rng_a.normal() == rng_b.normal()  # ... and the noise drawn after the truth


def test_consider_draws_every_scaled_non_primary_with_its_consider_std_and_keeps_the_primaries_factors() -> None:
    model, p, data = _aerosonde()
    ix = model.params.index
    fixed = [n for n in dict.fromkeys(bench.SCALED) if n not in bench.PRIMARY]
    assert {"C_Y_p", "C_Y_r", "C_n_p", "C_L_q"} <= set(fixed)
    nominal = p[[ix[n] for n in fixed]]
    sd = np.array([fixed_sd(n, p[ix[n]]) for n in fixed])
    drawn = np.array([bench.truth_params(model, p, np.random.default_rng(s), data, fixed_spread="consider")
                      [[ix[n] for n in fixed]] for s in range(400)])
    assert np.all(np.abs(drawn - nominal) <= 2.0 * sd + 1e-12)
    assert np.all(np.abs(np.mean(drawn, axis=0) - nominal) <= 0.15 * sd)  # about the value (3 standard errors)
    np.testing.assert_allclose(np.std(drawn, axis=0), 0.96 * sd, rtol=0.1)  # not the factors' 0.29 |value|
    for s in range(5):
        rng_a, rng_b = np.random.default_rng(s), np.random.default_rng(s)
        a = bench.truth_params(model, p, rng_a, data, fixed_spread="factor")
        b = bench.truth_params(model, p, rng_b, data, fixed_spread="consider")
        other = [i for n, i in ix.items() if n not in fixed]
        np.testing.assert_array_equal(a[other], b[other])  # the primaries' factors and C_m_0's re-balance
        assert rng_a.normal() == rng_b.normal()


def test_an_unknown_truth_family_is_refused() -> None:
    import pytest

    model = FixedWingModel(FixedWingParams())
    p = np.array(model.params.starts(), dtype=float)
    with pytest.raises(ValueError, match="fixed_spread 'zero'"):
        bench.truth_params(model, p, np.random.default_rng(0), [], fixed_spread="zero")

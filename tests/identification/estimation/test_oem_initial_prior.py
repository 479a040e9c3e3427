"""The initial-state prior of the output-error estimator (``initial_sd``): a manoeuvre's given x0 treated as a
measurement of its initial state. Its limits are the two fits it sits between (a tiny std: the state held at
the given x0; a huge one: the state free), in between the information adds, and the per-manoeuvre terms the
bootstrap and the segment scatter use carry it."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.estimation.oem import EstimationError, Manoeuvre, OutputErrorEstimator, _linearised
from identification.flights.synthetic import multistep

FREE = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]
OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2"]
SIGMA = np.array([0.005, 0.005, 0.005, 0.05])
STATE = "vel_body_y_m_s"
DT = 0.02
N = 300  # 6 s


@pytest.fixture(scope="module")
def problem() -> tuple[Simulator, np.ndarray, list[Manoeuvre], np.ndarray]:
    """Three noisy manoeuvres whose logged start has the side velocity off by a known amount per manoeuvre."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    plant = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False)
    i_v = sim.model.states.index[STATE]
    rng = np.random.default_rng(11)
    data, offsets = [], np.array([0.4, -0.3, 0.2])
    for j, (va, dv) in enumerate(zip((22.0, 25.0, 28.0), offsets, strict=True)):
        tr = trim(sim.model, p, va)
        t = np.arange(N) * DT
        u = np.tile(tr.u, (N, 1))
        u[:, 0] += multistep(t, 0.5 + 0.3 * j, 0.4, 0.05)
        u[:, 2] += multistep(t, 3.0, 0.4, 0.05)
        x_true = np.array(tr.x, dtype=float)
        x_true[i_v] += dv
        y = plant.simulate(p[plant.i_free], Manoeuvre(x_true, u, np.zeros((N, len(OUTPUTS))), DT),
                           sensitivities=False)[0]
        data.append(Manoeuvre(tr.x, u, y + rng.normal(0.0, SIGMA, y.shape), DT, f"trim {va} m/s"))
    return sim, p, data, offsets


def _fit(problem, sd: float | None):
    sim, p, data, _ = problem
    oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, estimate_states=[STATE], compile=False,
                              initial_sd=None if sd is None else {STATE: sd})
    return oe, oe.estimate(data, weight=np.diag(1.0 / SIGMA ** 2), max_iter=40)


def test_a_tiny_std_holds_the_logged_start_and_a_huge_one_frees_it(problem) -> None:
    sim, p, data, offsets = problem
    fixed = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False).estimate(
        data, weight=np.diag(1.0 / SIGMA ** 2), max_iter=40)
    _, tiny = _fit(problem, 1e-6)
    _, free = _fit(problem, None)
    _, huge = _fit(problem, 1e6)
    logged = np.array([m.x0[sim.model.states.index[STATE]] for m in data])
    ng = len(FREE)
    np.testing.assert_allclose(tiny.values[ng:], logged, atol=1e-5)
    np.testing.assert_allclose(tiny.values[:ng], fixed.values[:ng], rtol=1e-4)
    np.testing.assert_allclose(huge.values, free.values, rtol=1e-5, atol=1e-8)
    # free, the side velocities find the truth's starts (the fixed start biases the fit instead)
    np.testing.assert_allclose(free.values[ng:] - logged, offsets, atol=0.03)


def test_in_between_the_information_adds(problem) -> None:
    sim, _, data, _ = problem
    sd = 0.1
    _, free = _fit(problem, None)
    _, map_ = _fit(problem, sd)
    ng = len(FREE)
    logged = np.array([m.x0[sim.model.states.index[STATE]] for m in data])
    moved, free_moved = map_.values[ng:] - logged, free.values[ng:] - logged
    # pulled toward the logged start, not past it
    assert np.all(np.sign(moved) == np.sign(free_moved)) and np.all(np.abs(moved) < np.abs(free_moved))
    # the posterior information of each start: its data information plus the prior's (white bound, linearised)
    expected = 1.0 / np.sqrt(1.0 / free.crb_std_white[ng:] ** 2 + 1.0 / sd ** 2)
    np.testing.assert_allclose(map_.crb_std_white[ng:], expected, rtol=0.1)


def test_the_per_manoeuvre_terms_carry_the_prior(problem) -> None:
    """The bootstrap's and the segment scatter's per-manoeuvre information: with a tiny std the start is held
    (the model parameters' own block), with a huge one it is profiled out as a free nuisance parameter."""
    sim, p, data, _ = problem
    oe_free, est = _fit(problem, None)
    theta = est.values
    sims = [oe_free.simulate(theta, m, j) for j, m in enumerate(data)]
    res, jacs, W, _ = _linearised(data, sims, np.diag(1.0 / SIGMA ** 2))
    ng = len(FREE)
    free_terms = oe_free._segment_terms(res, jacs, W, theta, data)
    for sd, want in ((1e-9, "held"), (1e9, "free")):
        oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, estimate_states=[STATE], compile=False,
                                  initial_sd={STATE: sd})
        for j, (A, _) in enumerate(oe._segment_terms(res, jacs, W, theta, data)):
            Jw = (np.linalg.cholesky(W).T @ jacs[j]).reshape(-1, jacs[j].shape[2])
            ref = (Jw.T @ Jw)[:ng, :ng] if want == "held" else free_terms[j][0]
            np.testing.assert_allclose(A, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())


def test_bad_initial_stds_are_refused(problem) -> None:
    sim, p, _, _ = problem
    with pytest.raises(EstimationError, match="not an estimated state"):
        OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False, initial_sd={STATE: 0.1})
    for bad in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(EstimationError, match=f"initial-state std of '{STATE}'"):
            OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, estimate_states=[STATE], compile=False,
                                 initial_sd={STATE: bad})

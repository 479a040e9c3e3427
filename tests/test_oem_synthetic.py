"""Output-error estimation on synthetic Aerosonde data: exact recovery without noise, CR-consistent with noise."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.oem import EstimationError, Manoeuvre, OutputError

FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta"]
OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2", "beta_rad"]
DT = 0.02
N = 600  # 12 s


def three_two_one_one(t: np.ndarray, t0: float, unit_s: float, amp: float) -> np.ndarray:
    """The 3-2-1-1 multistep: +3, -2, +1, -1 units long."""
    edges = t0 + unit_s * np.cumsum([0, 3, 2, 1, 1])
    out = np.zeros_like(t)
    for (a, b), s in zip(itertools.pairwise(edges), (1, -1, 1, -1), strict=True):
        out[(t >= a) & (t < b)] = s * amp
    return out


@pytest.fixture(scope="module")
def truth() -> tuple[Simulator, np.ndarray, Manoeuvre]:
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    tr = trim(sim.model, p, 25.0)
    t = np.arange(N) * DT
    u = np.tile(tr.u, (N, 1))
    u[:, 0] += three_two_one_one(t, 1.0, 0.5, 0.05)
    u[:, 2] += three_two_one_one(t, 6.0, 0.5, 0.05)
    x = tr.x.copy()
    ys = []
    for k in range(N):
        x1, y1 = sim.step(x, u[k], p, DT)
        x = np.asarray(x1).ravel()
        ys.append(np.asarray(y1).ravel()[[sim.model.outputs.index[n] for n in OUTPUTS]])
    return sim, p, Manoeuvre(tr.x, u, np.array(ys), DT)


def perturbed(sim: Simulator, p: np.ndarray, frac: float = 0.3) -> np.ndarray:
    rng = np.random.default_rng(7)
    signs = rng.choice([-1.0, 1.0], size=len(FREE))
    return np.array([p[sim.model.params.index[n]] * (1 + s * frac) for n, s in zip(FREE, signs, strict=True)])


def test_noise_free_recovery_to_1e_4(truth) -> None:
    sim, p, m = truth
    oe = OutputError(sim.model, p, FREE, OUTPUTS)
    w = np.diag(1.0 / np.array([1e-2, 1e-2, 1e-2, 1e-1, 1e-2]) ** 2)
    est = oe.estimate([m], theta0=perturbed(sim, p), weight=w, max_iter=40)
    true = np.array([p[sim.model.params.index[n]] for n in FREE])
    np.testing.assert_allclose(est.values, true, rtol=1e-4)
    assert est.history[-1].cost < 1e-12


def test_noisy_estimates_within_3_cramer_rao_std(truth) -> None:
    sim, p, m = truth
    rng = np.random.default_rng(0)
    sigma = np.array([0.005, 0.005, 0.005, 0.05, 0.005])
    noisy = Manoeuvre(m.x0, m.u, m.y + rng.normal(0.0, sigma, m.y.shape), DT)
    oe = OutputError(sim.model, p, FREE, OUTPUTS)
    est = oe.estimate([noisy], theta0=perturbed(sim, p), max_iter=40)
    true = np.array([p[sim.model.params.index[n]] for n in FREE])
    assert np.all(np.abs(est.values - true) <= 3 * est.crb_std), est.table()
    # the ML weighting found the noise level
    np.testing.assert_allclose(np.sqrt(np.diag(est.residual_cov)), sigma, rtol=0.15)


def test_unknown_names_are_rejected(truth) -> None:
    sim, p, _ = truth
    with pytest.raises(EstimationError, match="C_ell_pp"):
        OutputError(sim.model, p, ["C_ell_pp"], OUTPUTS)

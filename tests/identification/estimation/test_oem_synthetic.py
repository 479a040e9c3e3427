"""Output-error estimation on synthetic Aerosonde data: exact recovery without noise, CR-consistent with noise,
exact sensitivities, several manoeuvres with initial states and biases, coloured-residual bounds, constraints."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.estimation.oem import (
    EstimationError,
    Manoeuvre,
    OutputErrorEstimator,
    coloured_covariance,
    segment_corrections,
    student_factor,
)
from identification.flights.synthetic import OEM_FREE, OEM_OUTPUTS, OEM_SIGMA, identification_manoeuvres, multistep

FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta"]
OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2", "beta_rad"]
SIGMA = np.array([0.005, 0.005, 0.005, 0.05, 0.005])
DT = 0.02
N = 600  # 12 s



def lateral_manoeuvre(sim: Simulator, p: np.ndarray, va: float, t_a: float,
                      t_r: float) -> tuple[np.ndarray, np.ndarray]:
    tr = trim(sim.model, p, va)
    t = np.arange(N) * DT
    u = np.tile(tr.u, (N, 1))
    u[:, 0] += multistep(t, t_a, 0.5, 0.05)
    u[:, 2] += multistep(t, t_r, 0.5, 0.05)
    return tr.x, u


@pytest.fixture(scope="module")
def truth() -> tuple[Simulator, np.ndarray, Manoeuvre]:
    """A lateral-directional manoeuvre simulated step by step with the Simulator (independent of the estimator)."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    x0, u = lateral_manoeuvre(sim, p, 25.0, 1.0, 6.0)
    x = x0.copy()
    ys = []
    for k in range(N):
        x1, y1 = sim.step(x, u[k], p, DT)
        x = np.asarray(x1).ravel()
        ys.append(np.asarray(y1).ravel()[[sim.model.outputs.index[n] for n in OUTPUTS]])
    return sim, p, Manoeuvre(x0, u, np.array(ys), DT)


@pytest.fixture(scope="module")
def oe(truth) -> OutputErrorEstimator:
    sim, p, _ = truth
    return OutputErrorEstimator(sim.model, p, FREE, OUTPUTS)


def perturbed(sim: Simulator, p: np.ndarray, frac: float = 0.3) -> np.ndarray:
    rng = np.random.default_rng(7)
    signs = rng.choice([-1.0, 1.0], size=len(FREE))
    return np.array([p[sim.model.params.index[n]] * (1 + s * frac) for n, s in zip(FREE, signs, strict=True)])


def true_values(sim: Simulator, p: np.ndarray) -> np.ndarray:
    return np.array([p[sim.model.params.index[n]] for n in FREE])


def test_noise_free_recovery_to_1e_4(truth, oe) -> None:
    sim, p, m = truth
    est = oe.estimate([m], theta0=perturbed(sim, p), weight=np.diag(1.0 / SIGMA**2), max_iter=40)
    np.testing.assert_allclose(est.values, true_values(sim, p), rtol=1e-4)
    assert est.history[-1].cost < 1e-12
    assert est.converged


def test_noisy_estimates_within_3_cramer_rao_std(truth, oe) -> None:
    sim, p, m = truth
    rng = np.random.default_rng(0)
    noisy = Manoeuvre(m.x0, m.u, m.y + rng.normal(0.0, SIGMA, m.y.shape), DT)
    est = oe.estimate([noisy], theta0=perturbed(sim, p), max_iter=40)
    assert np.all(np.abs(est.values - true_values(sim, p)) <= 3 * est.crb_std), est.table()
    # the ML weighting found the noise level
    np.testing.assert_allclose(np.sqrt(np.diag(est.residual_cov)), SIGMA, rtol=0.15)
    # white residuals: the coloured-residual correction changes the bounds little
    np.testing.assert_allclose(est.crb_std / est.crb_std_white, 1.0, atol=0.3)


def test_coloured_residuals_widen_the_bounds(truth, oe) -> None:
    """Low-pass (AR(1), pole 0.95) noise: the white-noise CRB is optimistic; the corrected one covers the error."""
    sim, p, m = truth
    rng = np.random.default_rng(3)
    white = rng.normal(0.0, 1.0, m.y.shape)
    coloured = lfilter([np.sqrt(1 - 0.95**2)], [1.0, -0.95], white, axis=0) * SIGMA
    est = oe.estimate([Manoeuvre(m.x0, m.u, m.y + coloured, DT)], theta0=perturbed(sim, p), max_iter=40)
    ratio = est.crb_std / est.crb_std_white
    # theory: for a slowly varying sensitivity the factor is sqrt((1+a)/(1-a)) = 6.2; demand at least 2.5
    assert np.median(ratio) > 2.5, ratio
    assert np.all(np.abs(est.values - true_values(sim, p)) <= 3 * est.crb_std), est.table()


def test_sensitivities_match_central_differences(truth) -> None:
    sim, p, m = truth
    oe = OutputErrorEstimator(sim.model, p, FREE[:3], OUTPUTS, estimate_states=["rate_body_x_rad_s", "vel_body_y_m_s"],
                     estimate_biases=["roll_rad"], compile=False)
    short = Manoeuvre(m.x0, m.u[:200], m.y[:200], DT)
    theta = oe._start([short], None) + np.array([0, 0, 0, 0.01, 0.2, 0.0])
    _, J, _ = oe.simulate(theta, short)
    for a in range(len(theta)):
        h = 1e-6 * max(1.0, abs(theta[a]))
        up, dn = theta.copy(), theta.copy()
        up[a] += h
        dn[a] -= h
        fd = (oe.simulate(up, short, sensitivities=False)[0] - oe.simulate(dn, short, sensitivities=False)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, :, a], fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_compiled_and_virtual_machine_agree(truth, oe) -> None:
    sim, p, m = truth
    vm = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False)
    th = perturbed(sim, p)
    y1, J1, _ = oe.simulate(th, m)
    y2, J2, _ = vm.simulate(th, m)
    np.testing.assert_allclose(y1, y2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(J1, J2, rtol=1e-10, atol=1e-10)


def test_several_manoeuvres_with_initial_states_and_biases(truth) -> None:
    """Two manoeuvres from different trims; each starts with an unknown roll rate and has a roll-angle bias."""
    sim, p, _ = truth
    oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, estimate_states=["rate_body_x_rad_s"],
                              estimate_biases=["roll_rad"])
    i_p = sim.model.states.index["rate_body_x_rad_s"]
    true_local = [(0.05, 0.02), (-0.08, -0.03)]  # (initial roll rate rad/s, roll bias rad)
    data = []
    for j, (va, (p0, bias)) in enumerate(zip((22.0, 28.0), true_local, strict=True)):
        x0, u = lateral_manoeuvre(sim, p, va, 1.0 + j, 6.0)
        x_true = x0.copy()
        x_true[i_p] = p0
        y, _, _ = oe.simulate(p[oe.i_free], Manoeuvre(x_true, u, np.zeros((N, len(OUTPUTS))), DT), sensitivities=False)
        y[:, 0] += bias
        data.append(Manoeuvre(x0, u, y, DT, f"trim {va} m/s"))  # x0 has zero roll rate: it must be estimated
    est = oe.estimate(data, theta0=perturbed(sim, p), weight=np.diag(1.0 / SIGMA**2), max_iter=60)
    expected = np.concatenate([true_values(sim, p), np.ravel(true_local)])
    assert est.names[len(FREE):] == ["m0.x0.rate_body_x_rad_s", "m0.bias.roll_rad",
                                     "m1.x0.rate_body_x_rad_s", "m1.bias.roll_rad"]
    np.testing.assert_allclose(est.values, expected, rtol=1e-4, atol=1e-7)


def test_constraint_rejects_steps_and_bounds_hold(truth, oe) -> None:
    sim, p, m = truth
    oe_b = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, bounds={"C_ell_p": (-0.4, -0.35)},
                       constraints=[lambda th: th["C_n_r"] < -0.05], compile=False)
    est = oe_b.estimate([m], theta0=perturbed(sim, p), weight=np.diag(1.0 / SIGMA**2), max_iter=30)
    named = dict(zip(est.names, est.values, strict=True))
    assert -0.4 <= named["C_ell_p"] <= -0.35  # the truth (-0.26) lies outside the bounds
    assert named["C_n_r"] < -0.05


def test_diverging_start_is_refused(truth, oe) -> None:
    sim, p, m = truth
    start = true_values(sim, p)
    start[FREE.index("C_ell_p")] = +50.0  # violently unstable roll damping
    with pytest.raises(EstimationError, match="diverges"):
        oe.estimate([m], theta0=start)


def test_bad_problems_are_rejected(truth, oe) -> None:
    sim, p, m = truth
    with pytest.raises(EstimationError, match="C_ell_pp"):
        OutputErrorEstimator(sim.model, p, ["C_ell_pp"], OUTPUTS)
    with pytest.raises(EstimationError, match="state 'rate_x'"):
        OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, estimate_states=["rate_x"])
    with pytest.raises(EstimationError, match="not free"):
        OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, bounds={"C_L_0": (0, 1)})
    with pytest.raises(EstimationError, match="lateral: outputs must be"):
        oe.estimate([Manoeuvre(m.x0, m.u, m.y[:, :2], DT, "lateral")])
    bad = m.y.copy()
    bad[10, 1] = np.nan
    with pytest.raises(EstimationError, match="NaN"):
        oe.estimate([Manoeuvre(m.x0, m.u, bad, DT)])


def test_coloured_covariance_equals_the_double_sum_over_lags() -> None:
    """The FFT evaluation equals Σ_i Σ_j G_iᵀ w(j-i) R(j-i) G_j written out, R the biased autocorrelation."""
    rng = np.random.default_rng(1)
    n, ny, npar, lags = 40, 3, 4, 7
    G = rng.normal(size=(n, ny, npar))
    r = rng.normal(size=(n, ny))
    expected = np.zeros((npar, npar))
    for i in range(n):
        for j in range(n):
            tau = j - i
            if abs(tau) > lags:
                continue
            R = (r[:n - tau].T @ r[tau:] if tau >= 0 else (r[:n + tau].T @ r[-tau:]).T) / n
            expected += (1 - abs(tau) / (lags + 1)) * G[i].T @ R @ G[j]
    np.testing.assert_allclose(coloured_covariance(G, r, lags), 0.5 * (expected + expected.T), rtol=1e-10)


def test_segment_corrections_are_m_over_m_minus_1_and_m_minus_1_for_equal_segments() -> None:
    """Eight segments of equal information: the textbook factor m/(m-1) and Student's t with m-1 degrees."""
    rng = np.random.default_rng(2)
    B = rng.normal(size=(4, 4))
    factor, dof = segment_corrections(np.stack([B @ B.T] * 8))
    np.testing.assert_allclose(factor, 8 / 7, rtol=1e-9)
    np.testing.assert_allclose(dof, 7.0, rtol=1e-9)
    assert student_factor(7.0) == pytest.approx(2.3646 / 1.9600, rel=1e-3)


def test_segment_corrections_match_the_spread_of_unequal_segments() -> None:
    """A linear model with eight segments of unequal information (one carries most of the first parameter's):
    over 20000 noise draws the spread over segments at the estimate, Σ_j (M⁻¹ ĝ_j)², times the factor has the
    mean of the estimate's actual variance, and 2 mean² / variance of that spread equals the degrees of
    freedom given; both differ from the equal-segment m/(m-1) and m-1."""
    rng = np.random.default_rng(3)
    X = [rng.normal(size=(30, 3)) * np.array([6.0 if j == 0 else 1.0, 1.0, 0.5 + j]) for j in range(8)]
    A = np.stack([x.T @ x for x in X])
    Mi = np.linalg.inv(A.sum(axis=0))
    factor, dof = segment_corrections(A)
    draws = 20000
    spread, est = np.zeros((draws, 3)), np.zeros((draws, 3))
    for k in range(draws):
        g = np.stack([x.T @ rng.normal(size=30) for x in X])
        step = Mi @ g.sum(axis=0)
        est[k] = step
        spread[k] = np.sum((Mi @ (g - A @ step).T) ** 2, axis=1)
    np.testing.assert_allclose(spread.mean(axis=0) * factor, est.var(axis=0), rtol=0.05)
    np.testing.assert_allclose(2 * spread.mean(axis=0) ** 2 / spread.var(axis=0), dof, rtol=0.08)
    assert factor[0] > 1.3 * 8 / 7 and dof[0] < 4.0


@pytest.fixture(scope="module")
def all_axes() -> tuple[OutputErrorEstimator, np.ndarray, list[Manoeuvre]]:
    """The output-error benchmark problem (bench/oem.py), shortened: 25 derivatives of all axes, 3-2-1-1 on all
    surfaces and throttle steps, four 8 s manoeuvres at 50 Hz from trims between 22 and 28 m/s, noise-free."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    oe = OutputErrorEstimator(sim.model, p, OEM_FREE, OEM_OUTPUTS)
    return oe, p, identification_manoeuvres(oe, p, 8.0, 50.0, 4, None)


def test_all_axes_from_30_percent_off(all_axes) -> None:
    oe, p, clean = all_axes
    true = p[oe.i_free]
    start = true * (1 + 0.3 * np.random.default_rng(11).choice([-1.0, 1.0], size=len(true)))
    rng = np.random.default_rng(12)
    noisy = [Manoeuvre(m.x0, m.u, m.y + rng.normal(0.0, OEM_SIGMA, m.y.shape), m.dt_s) for m in clean]
    est = oe.estimate(noisy, theta0=start, max_iter=60, horizon_s=1.0)
    identifiable = est.crb_std < 0.1 * np.abs(true)
    assert identifiable.sum() >= 18, est.table()
    assert np.all(np.abs(est.values - true)[identifiable] <= 3 * est.crb_std[identifiable]), est.table()
    exact = oe.estimate(clean, theta0=start, weight=np.diag(1 / OEM_SIGMA**2), max_iter=80, horizon_s=1.0)
    np.testing.assert_allclose(exact.values[identifiable], true[identifiable], rtol=1e-4)


def test_runaway_sensitivities_mark_the_bounds_not_credible() -> None:
    """A record whose sensitivities dwarf its measured range (a trajectory that runs away) is named."""
    from identification.estimation.oem import SENSITIVITY_GROWTH_MAX, sensitivity_growth

    y = np.column_stack([np.linspace(0.0, 1.0, 50), np.linspace(0.0, 2.0, 50)])
    m = Manoeuvre(np.zeros(1), np.zeros((50, 1)), y, DT, "calm")
    theta = np.array([0.5, -2.0])
    calm = np.ones((50, 2, 2))
    runaway = calm.copy()
    runaway[-1, 1, 0] = 1e30
    assert sensitivity_growth([m], [calm], theta, 2)[0] == pytest.approx(2.0)  # |dy/dθ| |θ| / range = 1 x 2 / 1
    assert sensitivity_growth([m, m], [calm, runaway], theta, 2)[1] > SENSITIVITY_GROWTH_MAX

"""Is the scatter of ``bench/aero_coverage.py``'s 50 seeds the estimator's? The linearised estimate error
under the study's noise, exactly and over many draws (C_ell_r).

One repeat of the coverage study (seed 0, the tool's ``--free auto`` round) gives the final estimator (its
free set) and the output weighting; that estimator is fitted to the noise-free records of the mismatched
plant with that weighting (the noise-free optimum). At it, the estimate's error is linear in the noise:
``δθ = M⁻¹ Σ_j J_jᵀ W n_j`` (``M`` with the priors). Printed per derivative: the exact std of ``δθ`` under the
study's noise (white plus stationary AR(1), per output), its std over 2000 fresh noise draws, and over the
noise of the coverage study's seeds 0..49 (each seed's generator draws the noise first, as the study does).
A ratio of the seeds' std to the exact one far from 1 says that the study's seeds, not the estimator or its
bounds, make its scatter. That the error is linear in the noise is checked by full fits of the first seeds
(the same estimator and weighting, from the noise-free optimum) against the linear prediction.

Run: ``.venv/bin/python bench/aero_seed_scatter.py [--draws 2000] [--seeds 50] [--fits 20]`` (about a
minute). A diagnosis:
it prints and exits 0.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import aero_coverage as ac

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.aero.priors import CONSIDERED, fixed_sd, geometry_priors
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.flights.synthetic import identification_manoeuvres


@dataclass
class LinearMap:
    """The estimator of seed 0's final fit at its noise-free optimum ``theta`` with the weighting ``W``."""

    est: OutputErrorEstimator
    clean: list[Manoeuvre]
    theta: np.ndarray
    W: np.ndarray
    G: list[np.ndarray]  #: per record, the weighted sensitivities ``W J_j`` of the free parameters
    Mi: np.ndarray

    def error(self, noise: list[np.ndarray]) -> np.ndarray:
        """The linearised estimate error for the given noise of each record."""
        return self.Mi @ sum(np.einsum("noa,no->a", g, n) for g, n in zip(self.G, noise, strict=True))


def linear_map(seed: int = 0) -> LinearMap:
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    pp = ac.plant_params(sim.model, p)
    start_values = dict(zip(sim.model.params.index, p, strict=True))
    prior = {n: (v.value, v.sd) for n, v in geometry_priors(start_values).items() if n in ac.FREE}
    oe = OutputErrorEstimator(sim.model, p, ac.FREE, ac.OUTPUTS, prior=prior)
    truth = pp[oe.i_free]
    consider = {n: fixed_sd(n, float(start_values[n])) for n in CONSIDERED if n not in ac.FREE}
    clean = identification_manoeuvres(OutputErrorEstimator(sim.model, pp, ac.FREE, ac.OUTPUTS), pp, 8.0, 50.0, 8,
                                      None)
    rng = np.random.default_rng(seed)
    data = [Manoeuvre(m.x0, m.u, m.y + ac._noise(rng, m.y.shape), m.dt_s, m.name) for m in clean]
    start = truth * (1 + 0.1 * rng.choice([-1.0, 1.0], size=len(ac.FREE)))
    est = ac._auto_fit(oe, data, start, consider, prior, {})
    big = next((e for e in ac._ESTIMATORS.values() if len(e.free) == est.n_global), oe)
    res = [m.y - big.simulate(est.values, m, j, sensitivities=False)[0] for j, m in enumerate(data)]
    W = np.diag(1.0 / np.mean(np.vstack(res) ** 2, axis=0))
    theta = big.estimate(clean, theta0=est.values, weight=W, max_iter=60).values
    ng = len(big.free)
    J = [big.simulate(theta, m, j)[1][:, :, :ng] for j, m in enumerate(clean)]
    G = [np.einsum("o,noa->noa", np.diag(W), j) for j in J]
    M = np.diag(big.prior_information(ng)) + sum(np.einsum("noa,nob->ab", g, j) for g, j in zip(G, J, strict=True))
    return LinearMap(big, clean, theta, W, G, np.linalg.inv(M))


def _fits(lm: LinearMap, seeds: int) -> tuple[np.ndarray, np.ndarray]:
    """Full fits of seeds 0.. (that estimator and weighting, from the noise-free optimum) and their linear
    predictions."""
    ng = len(lm.est.free)
    actual, linear = [], []
    for k in range(seeds):
        rng = np.random.default_rng(k)
        noise = [ac._noise(rng, m.y.shape) for m in lm.clean]
        data = [Manoeuvre(m.x0, m.u, m.y + n, m.dt_s, m.name) for m, n in zip(lm.clean, noise, strict=True)]
        actual.append(lm.est.estimate(data, theta0=lm.theta, weight=lm.W, max_iter=60).values[:ng] - lm.theta[:ng])
        linear.append(lm.error(noise))
    return np.array(actual), np.array(linear)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=2000)
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--fits", type=int, default=20)
    args = parser.parse_args()
    if not (10 <= args.draws <= 100_000 and 2 <= args.seeds <= 1000 and 3 <= args.fits <= 1000):
        parser.error("--draws must be in 10..100000, --seeds in 2..1000 and --fits in 3..1000")
    lm = linear_map()
    n = lm.clean[0].y.shape[0]
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    exact = np.zeros((len(lm.est.free), len(lm.est.free)))
    for o in range(len(ac.OUTPUTS)):
        cov = ac.WHITE[o] ** 2 * np.eye(n) + ac.COLOURED[o] ** 2 * ac.POLE ** lag
        for g in lm.G:
            exact += g[:, o, :].T @ cov @ g[:, o, :]
    exact_sd = np.sqrt(np.diag(lm.Mi @ exact @ lm.Mi))

    def draws(first: int, count: int) -> np.ndarray:
        out = []
        for k in range(first, first + count):
            rng = np.random.default_rng(k)
            out.append(lm.error([ac._noise(rng, m.y.shape) for m in lm.clean]))
        return np.array(out)

    fresh, seeds = draws(1_000_000, args.draws), draws(0, args.seeds)
    actual, linear = _fits(lm, args.fits)
    print(f"linearised estimate error at the noise-free optimum ({len(lm.est.free)} free); std: exact, over "
          f"{args.draws} fresh draws, over the coverage study's seeds 0..{args.seeds - 1}; full fits of seeds "
          f"0..{args.fits - 1} against the linear prediction: correlation and slope")
    print(f"{'parameter':<14} {'exact':>10} {'draws':>10} {'seeds':>10} {'seeds/exact':>12} {'fit corr':>9} "
          f"{'slope':>6}")
    for i, name in enumerate(ac.FREE):
        sd_seeds = seeds[:, i].std(ddof=1)
        corr = np.corrcoef(actual[:, i], linear[:, i])[0, 1]
        slope = np.polyfit(linear[:, i], actual[:, i], 1)[0]
        print(f"{name:<14} {exact_sd[i]:10.3g} {fresh[:, i].std(ddof=1):10.3g} {sd_seeds:10.3g} "
              f"{sd_seeds / exact_sd[i]:12.2f} {corr:9.4f} {slope:6.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

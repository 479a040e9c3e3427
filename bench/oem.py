"""Output-error estimation: ours (LM, exact sensitivities) vs scipy.optimize.least_squares with finite-difference
Jacobians on the same compiled simulator, on one synthetic Aerosonde problem.

Six 10 s manoeuvres at 100 Hz (60 s in all), each from its own trim: 3-2-1-1 multisteps on aileron,
elevator and rudder and a throttle step, seeded sensor noise; 25 free derivatives start perturbed by
+/-30 %. Prints wall times, their ratio, and the final parameter error of each (rms of the error relative to
the truth, and the largest error in Cramér-Rao standard deviations).
Target: ours >= 3x faster at equal or better error (rms relative error over the identifiable
derivatives at most 1.1x scipy's); exit 1 on a miss.

Run: ``.venv/bin/python bench/oem.py [--seconds-each 10] [--count 6] [--rate 100]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.flights.synthetic import OEM_FREE, OEM_OUTPUTS, OEM_SIGMA, identification_manoeuvres


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds-each", type=float, default=10.0)
    parser.add_argument("--count", type=int, default=6, help="number of manoeuvres")
    parser.add_argument("--horizon", type=float, default=2.5, help="first fitted span (s), doubled up to all")
    parser.add_argument("--rate", type=float, default=100.0)
    args = parser.parse_args()
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    oe = OutputErrorEstimator(sim.model, p, OEM_FREE, OEM_OUTPUTS)  # compiles (once, cached) before any timing
    true = p[oe.i_free].copy()
    rng = np.random.default_rng(0)
    data = identification_manoeuvres(oe, p, args.seconds_each, args.rate, args.count, rng, OEM_SIGMA)
    start = true * (1 + 0.3 * rng.choice([-1.0, 1.0], size=len(OEM_FREE)))
    W = np.diag(1 / OEM_SIGMA**2)
    oe.simulate(start, data[0])  # warm the compiled functions

    t0 = time.perf_counter()
    est = oe.estimate(data, theta0=start, weight=W, max_iter=50, horizon_s=args.horizon)
    t_ours = time.perf_counter() - t0

    def residual(theta: np.ndarray, records: list[Manoeuvre]) -> np.ndarray:
        # the same compiled RK4 step as ours, simulated without sensitivities
        return np.concatenate([((m.y - oe.simulate(theta, m, j, sensitivities=False)[0]) / OEM_SIGMA).ravel()
                               for j, m in enumerate(records)])

    t0 = time.perf_counter()
    x, nfev, njev = start, 0, 0
    n_h = round(args.horizon / data[0].dt_s)
    while True:  # the same continuation in record length as ours, then the whole record
        n_h = min(n_h, data[0].u.shape[0])
        records = [Manoeuvre(m.x0, m.u[:n_h], m.y[:n_h], m.dt_s) for m in data]
        last = n_h == data[0].u.shape[0]
        tol = 1e-9 if last else 1e-4  # ours: relative cost change 1e-9, then 1e-4
        ref = least_squares(residual, x, method="trf", jac="2-point", x_scale="jac", xtol=tol, ftol=tol,
                            max_nfev=2000, args=(records,))
        x, nfev, njev = ref.x, nfev + ref.nfev, njev + ref.njev
        if last:
            break
        n_h *= 2
    t_scipy = time.perf_counter() - t0

    def rms_rel(v: np.ndarray) -> float:
        return float(np.linalg.norm((v - true) / np.abs(true)) / np.sqrt(len(true)))

    def max_crb(v: np.ndarray) -> float:
        return float(np.max(np.abs(v - true) / est.crb_std))

    good = est.crb_std < 0.1 * np.abs(true)  # identifiable: Cramér-Rao std under 10 %

    def rms_good(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(((v - true) / true)[good] ** 2)))

    n_samples = sum(m.u.shape[0] for m in data)
    print(f"problem: {len(OEM_FREE)} free parameters, {len(data)} manoeuvres, {n_samples} samples "
          f"({n_samples / args.rate:.0f} s at {args.rate:.0f} Hz), {len(OEM_OUTPUTS)} outputs")
    print(f"ours (LM, exact sensitivities): {t_ours:7.2f} s, {len(est.history)} iterations, rms relative "
          f"error {rms_rel(est.values):.2e} ({rms_good(est.values):.2e} over the {good.sum()} identifiable), "
          f"worst {max_crb(est.values):.2f} CR std")
    print(f"scipy least_squares (FD):       {t_scipy:7.2f} s, {nfev} evaluations + {njev} Jacobians, "
          f"rms relative error {rms_rel(x):.2e} ({rms_good(x):.2e}), worst {max_crb(x):.2f} CR std")
    ratio = t_scipy / t_ours
    # "equal or better": ours no worse than scipy's rms error on the identifiable ones (10 % slack for noise)
    equal = rms_good(est.values) <= 1.1 * rms_good(x) + 1e-12
    ok = ratio >= 3.0 and equal
    print(f"speed ratio scipy/ours: {ratio:.1f}x (target >= 3x at equal or better error) -> "
          f"{'PASS' if ok else 'FAIL'}{'' if equal else ' (error worse than scipy)'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

"""Output-error estimation: ours (LM, exact CasADi sensitivities) vs scipy.optimize.least_squares with
finite-difference Jacobians on the same CasADi simulator, on one synthetic Aerosonde problem.

Doublets (3-2-1-1) on aileron, elevator and rudder plus a throttle step, seeded noise, start perturbed by
+/-30 %. Prints wall times, their ratio, and the final relative parameter error of each.
Target (issue 4): ours >= 3x faster at equal or better error.

Run: ``.venv/bin/python bench/oem.py [--seconds 60] [--rate 100]``.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.oem import Manoeuvre, OutputError

FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_p", "C_n_delta_r",
        "C_n_delta_a", "C_Y_beta", "C_Y_delta_r", "C_m_alpha", "C_m_q", "C_m_delta_e", "C_m_0", "C_L_alpha",
        "C_L_0", "C_L_delta_e", "C_L_q", "C_ell_delta_r", "C_Y_delta_a", "C_D_delta_e", "e_oswald", "Jxz_kg_m2", "C_T0"]
OUTPUTS = ["roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
           "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s", "beta_rad"]


def multistep(t: np.ndarray, t0: float, unit: float, amp: float) -> np.ndarray:
    edges = t0 + unit * np.cumsum([0, 3, 2, 1, 1])
    out = np.zeros_like(t)
    for (a, b), s in zip(itertools.pairwise(edges), (1, -1, 1, -1), strict=True):
        out[(t >= a) & (t < b)] = s * amp
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=100.0)
    args = parser.parse_args()
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    tr = trim(sim.model, p, 25.0)
    dt = 1.0 / args.rate
    n = int(args.seconds * args.rate)
    t = np.arange(n) * dt
    u = np.tile(tr.u, (n, 1))
    u[:, 0] += multistep(t, 2.0, 0.5, 0.05) + multistep(t, 32.0, 0.7, 0.04)
    u[:, 1] += multistep(t, 12.0, 0.5, 0.03) + multistep(t, 42.0, 0.8, 0.02)
    u[:, 2] += multistep(t, 22.0, 0.5, 0.05) + multistep(t, 50.0, 0.6, 0.04)
    u[:, 3] += np.where((t > 27.0) & (t < 37.0), 0.1, 0.0)
    oe = OutputError(sim.model, p, FREE, OUTPUTS)
    true = p[oe.i_free].copy()
    y, _ = oe.simulate(true, Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt))
    rng = np.random.default_rng(0)
    sigma = np.array([0.003, 0.003, 0.005, 0.005, 0.005, 0.05, 0.05, 0.05, 0.1, 0.003])
    data = Manoeuvre(tr.x, u, y + rng.normal(0.0, sigma, y.shape), dt)
    start = true * (1 + 0.3 * rng.choice([-1.0, 1.0], size=len(FREE)))

    t0 = time.perf_counter()
    est = oe.estimate([data], theta0=start, weight=np.diag(1 / sigma**2), max_iter=50)
    t_ours = time.perf_counter() - t0

    sim_only = oe._step.mapaccum("sim", n)

    def residual(theta: np.ndarray) -> np.ndarray:
        pp = p.copy()
        pp[oe.i_free] = theta
        _, yy = sim_only(tr.x, u.T, pp, dt)
        return ((data.y - np.asarray(yy)[oe.i_out].T) / sigma).ravel()

    t0 = time.perf_counter()
    ref = least_squares(residual, start, method="trf", jac="2-point", xtol=1e-10, ftol=1e-10, max_nfev=200)
    t_scipy = time.perf_counter() - t0

    def err(v: np.ndarray) -> float:
        return float(np.linalg.norm((v - true) / np.abs(true)) / np.sqrt(len(true)))

    print(f"problem: {len(FREE)} free parameters, {args.seconds:.0f} s at {args.rate:.0f} Hz, {len(OUTPUTS)} outputs")
    print(f"ours (LM, exact sensitivities): {t_ours:7.2f} s, {len(est.history)} iterations, "
          f"rms relative parameter error {err(est.values):.2e}")
    print(f"scipy least_squares (FD):       {t_scipy:7.2f} s, {ref.nfev} evaluations, "
          f"rms relative parameter error {err(ref.x):.2e}")
    print(f"speed ratio scipy/ours: {t_scipy / t_ours:.1f}x (target >= 3x at equal or better error)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

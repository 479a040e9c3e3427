"""Output-error estimation: ours (LM, exact sensitivities) vs scipy.optimize.least_squares with finite-difference
Jacobians on the same compiled simulator, on one synthetic Aerosonde problem.

Six 10 s manoeuvres at 100 Hz (60 s in all), each from its own trim: 3-2-1-1 multisteps on aileron,
elevator and rudder and a throttle step, seeded sensor noise; 25 free derivatives start perturbed by
+/-30 %. Prints wall times, their ratio, and the final parameter error of each (rms of the error relative to
the truth, and the largest error in Cramér-Rao standard deviations).
Target (issue 4): ours >= 3x faster at equal or better error.

Run: ``.venv/bin/python bench/oem.py [--seconds-each 10] [--count 6] [--rate 100]``.
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
        "C_L_0", "C_L_delta_e", "C_L_q", "C_ell_delta_r", "C_Y_delta_a", "C_D_delta_e", "e_oswald", "Jxz_kg_m2",
        "C_T0"]
OUTPUTS = ["roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
           "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s", "beta_rad"]
SIGMA = np.array([0.003, 0.003, 0.005, 0.005, 0.005, 0.05, 0.05, 0.05, 0.1, 0.003])


def multistep(t: np.ndarray, t0: float, unit: float, amp: float) -> np.ndarray:
    """3-2-1-1 multistep starting at ``t0`` with unit length ``unit`` (s) and amplitude ``amp``."""
    edges = t0 + unit * np.cumsum([0, 3, 2, 1, 1])
    out = np.zeros_like(t)
    for (a, b), s in zip(itertools.pairwise(edges), (1, -1, 1, -1), strict=True):
        out[(t >= a) & (t < b)] = s * amp
    return out


def manoeuvres(sim: Simulator, p: np.ndarray, oe: OutputError, seconds: float, rate: float, count: int,
               rng: np.random.Generator) -> list[Manoeuvre]:
    """``count`` noisy manoeuvres cycling through four designs, from trims between 22 and 28 m/s."""
    dt = 1.0 / rate
    n = int(seconds * rate)
    t = np.arange(n) * dt
    out = []
    for i in range(count):
        j, va = i % 4, float(np.linspace(22.0, 28.0, count)[i])
        tr = trim(sim.model, p, va)
        u = np.tile(tr.u, (n, 1))
        if j in (0, 3):
            u[:, 0] += multistep(t, 1.0, 0.5, 0.05)
            u[:, 2] += multistep(t, 6.0, 0.5, 0.05)
        if j in (1, 3):
            u[:, 1] += multistep(t, 1.0 + 9 * (j == 3), 0.4, 0.03)
        if j == 2:
            u[:, 0] += multistep(t, 1.0, 0.4, 0.04)
            u[:, 1] += multistep(t, 5.0, 0.5, 0.02)
            u[:, 2] += multistep(t, 9.0, 0.4, 0.04)
        u[:, 3] += np.where((t > 0.6 * seconds) & (t < 0.9 * seconds), 0.1, 0.0)
        y, _, _ = oe.simulate(p[oe.i_free], Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt),
                              sensitivities=False)
        out.append(Manoeuvre(tr.x, u, y + rng.normal(0.0, SIGMA, y.shape), dt, f"trim {va:g} m/s"))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds-each", type=float, default=10.0)
    parser.add_argument("--count", type=int, default=6, help="number of manoeuvres")
    parser.add_argument("--horizon", type=float, default=2.5, help="first fitted span (s), doubled up to all")
    parser.add_argument("--rate", type=float, default=100.0)
    args = parser.parse_args()
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    oe = OutputError(sim.model, p, FREE, OUTPUTS)  # compiles (once, cached) before any timing
    true = p[oe.i_free].copy()
    rng = np.random.default_rng(0)
    data = manoeuvres(sim, p, oe, args.seconds_each, args.rate, args.count, rng)
    start = true * (1 + 0.3 * rng.choice([-1.0, 1.0], size=len(FREE)))
    W = np.diag(1 / SIGMA**2)
    oe.simulate(start, data[0])  # warm the compiled functions

    t0 = time.perf_counter()
    est = oe.estimate(data, theta0=start, weight=W, max_iter=50, horizon_s=args.horizon)
    t_ours = time.perf_counter() - t0

    def residual(theta: np.ndarray, records: list[Manoeuvre]) -> np.ndarray:
        # the same compiled RK4 step as ours, simulated without sensitivities
        return np.concatenate([((m.y - oe.simulate(theta, m, j, sensitivities=False)[0]) / SIGMA).ravel()
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
    print(f"problem: {len(FREE)} free parameters, {len(data)} manoeuvres, {n_samples} samples "
          f"({n_samples / args.rate:.0f} s at {args.rate:.0f} Hz), {len(OUTPUTS)} outputs")
    print(f"ours (LM, exact sensitivities): {t_ours:7.2f} s, {len(est.history)} iterations, rms relative "
          f"error {rms_rel(est.values):.2e} ({rms_good(est.values):.2e} over the {good.sum()} identifiable), "
          f"worst {max_crb(est.values):.2f} CR std")
    print(f"scipy least_squares (FD):       {t_scipy:7.2f} s, {nfev} evaluations + {njev} Jacobians, "
          f"rms relative error {rms_rel(x):.2e} ({rms_good(x):.2e}), worst {max_crb(x):.2f} CR std")
    print(f"speed ratio scipy/ours: {t_scipy / t_ours:.1f}x (target >= 3x at equal or better error)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

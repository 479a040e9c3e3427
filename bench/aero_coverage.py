"""Coverage of the 95 % intervals of ``identify aero`` on the demo's synthetic generator (issue 18).

Each repeat: eight 8 s manoeuvres at 50 Hz from ``uavfmu.synthetic.identification_manoeuvres`` (3-2-1-1
multisteps from trims between 22 and 28 m/s), simulated with a slightly wrong plant (model mismatch: C_n_p,
C_L_q, C_D_p of the truth differ from the fitted model's fixed values), plus seeded white noise and coloured
noise (AR(1), pole 0.9) per output. Twelve lateral-directional and pitch derivatives are estimated from a
start 10 % off the truth; an interval covers when |estimate - truth| <= 1.96 std. Printed per parameter: the
coverage of the Cramér-Rao bound with the coloured-residual correction, of the block bootstrap over
manoeuvres, and of the printed bound (the larger of the two), with the mean bound ratio to the actual scatter.

Run: ``.venv/bin/python bench/aero_coverage.py [--repeats 50]``. Target: printed coverage >= 90 % for every
free derivative.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.oem import Manoeuvre, OutputErrorEstimator
from uavfmu.synthetic import identification_manoeuvres

FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_delta_r", "C_Y_beta",
        "C_Y_delta_r", "C_m_alpha", "C_m_q", "C_m_delta_e"]
OUTPUTS = ["roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
           "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s"]
WHITE = np.array([0.003, 0.003, 0.005, 0.005, 0.005, 0.05, 0.05, 0.1])
COLOURED = WHITE  #: std of the AR(1) component, per output
POLE = 0.9
MISMATCH = {"C_L_q": 1.05, "C_D_p": 1.05}  #: truth / model of parameters that stay fixed


@dataclass
class Study:
    names: list[str]
    truth: np.ndarray
    values: np.ndarray  #: repeats x free
    crb: np.ndarray
    boot: np.ndarray
    printed: np.ndarray
    seconds: float

    def coverage(self, std: np.ndarray) -> np.ndarray:
        return np.mean(np.abs(self.values - self.truth) <= 1.96 * std, axis=0)


def _noise(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    white = rng.normal(0.0, 1.0, shape) * WHITE
    drive = rng.normal(0.0, 1.0, shape) * COLOURED * np.sqrt(1 - POLE**2)
    return white + lfilter([1.0], [1.0, -POLE], drive, axis=0)


def run_study(repeats: int, seed: int = 0, count: int = 8, seconds: float = 8.0, rate: float = 50.0) -> Study:
    """The Monte Carlo study: ``repeats`` seeded data sets, one estimate each."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    p_plant = p.copy()
    for n, f in MISMATCH.items():
        p_plant[sim.model.params.index[n]] *= f
    plant = OutputErrorEstimator(sim.model, p_plant, FREE, OUTPUTS)
    oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS)
    truth = p[oe.i_free].copy()
    clean = identification_manoeuvres(plant, p_plant, seconds, rate, count, None)
    vals, crb, boot, printed = [], [], [], []
    t0 = time.perf_counter()
    for k in range(repeats):
        rng = np.random.default_rng(seed + k)
        data = [Manoeuvre(m.x0, m.u, m.y + _noise(rng, m.y.shape), m.dt_s, m.name) for m in clean]
        start = truth * (1 + 0.1 * rng.choice([-1.0, 1.0], size=len(FREE)))
        est = oe.estimate(data, theta0=start, max_iter=30)
        n = est.n_global
        vals.append(est.values[:n])
        crb.append(est.crb_std[:n])
        boot.append(est.bootstrap_std if est.bootstrap_std is not None else np.full(n, np.nan))
        printed.append(est.std[:n])
    return Study(FREE, truth, np.array(vals), np.array(crb), np.array(boot), np.array(printed),
                 time.perf_counter() - t0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if not 1 <= args.repeats <= 1000:
        parser.error("--repeats must be in 1..1000")
    st = run_study(args.repeats, args.seed)
    scatter = np.std(st.values - st.truth, axis=0, ddof=1) if args.repeats > 1 else np.full(len(FREE), np.nan)
    cov_crb, cov_boot, cov_pr = st.coverage(st.crb), st.coverage(st.boot), st.coverage(st.printed)
    print(f"{args.repeats} repeats in {st.seconds:.0f} s; coverage of the 95 % intervals (target >= 0.90)")
    print(f"{'parameter':<14} {'truth':>9} {'bias/sd':>8} {'CR col':>7} {'boot':>7} {'printed':>8} "
          f"{'CR/sd':>7} {'boot/sd':>8}")
    for i, n in enumerate(FREE):
        bias = (np.mean(st.values[:, i]) - st.truth[i]) / scatter[i]
        print(f"{n:<14} {st.truth[i]:9.4f} {bias:8.2f} {cov_crb[i]:7.2f} {cov_boot[i]:7.2f} {cov_pr[i]:8.2f} "
              f"{np.mean(st.crb[:, i]) / scatter[i]:7.2f} {np.nanmean(st.boot[:, i]) / scatter[i]:8.2f}")
    worst = float(np.min(cov_pr))
    print(f"printed bound: max(Cramér-Rao coloured, block bootstrap over manoeuvres); worst coverage {worst:.2f} "
          f"-> {'PASS' if worst >= 0.9 else 'FAIL'}")
    return 0 if worst >= 0.9 else 1


if __name__ == "__main__":
    raise SystemExit(main())

"""Coverage of the thrust map's parameter intervals (``identify thrust``'s ``uncertainty``) on a known motor.

Each repeat: three 60 s synthetic flights at 50 Hz of a quadrotor whose motors follow
``T_i = K (u_i V / V_nom)²`` (the FMU's one-rule map on ``u_eff = u V/V_nom`` with consequents ``(K, 0)``):
hover command with a 3 s swing, a slowly wandering collective (AR(1), pole 0.98) and per-motor sines, the
battery sagging from 12.4 V to 10.6 V; measured thrust = truth + white noise + an AR(1) disturbance of the same
std (pole 0.9 per sample: vibration and gusts). The map is fitted as ``identify thrust`` fits it
(``identification.thrust.model.fit``, one rule on ``u_eff``) and its consequents' covariance taken from
``identification.thrust.model.covariance`` (what the parameter file stores); the lag-1 inflation used before
2026-11-28 is computed on the same fits for comparison. An interval covers when |estimate - truth| <= 1.96 std.

Printed per coefficient: coverage of the 95 % intervals and the median half-width over the actual scatter (RMS
of estimate - truth). Target: coverage >= 0.90 and half-width <= 2 x the scatter; exit 1 on a miss.

Run: ``.venv/bin/python bench/thrust_coverage.py [--repeats 200] [--seed 0]`` (about 10 s).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.units import G0_M_S2
from identification.thrust.model import Fit, FlightData, ModelSpec, covariance, fit

K_N = 9.0  #: thrust at full command and nominal voltage, per motor [N]
NOMINAL_V = 11.1
MASS_KG = 1.2
RATE_HZ = 50.0
NOISE_N = 0.4  #: std of the white part and of the AR(1) part of the thrust measurement [N]
POLE = 0.9
SPEC = ModelSpec(1000.0, 2000.0, NOMINAL_V, True, "u_eff", ("x2", "x"), 1)
TRUTH = np.array([K_N, 0.0])
NAMES = ("x2 (K)", "x")
MIN_COVERAGE = 0.90
MAX_WIDTH = 2.0


def flight(rng: np.random.Generator, name: str, seconds: float = 60.0) -> FlightData:
    """One synthetic flight of the known motor, with white + AR(1) thrust noise."""
    t = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    volt = np.linspace(12.4, 10.6, t.size)
    u_hover = np.sqrt(MASS_KG * G0_M_S2 / 4 / K_N) * NOMINAL_V / volt
    wander = lfilter([np.sqrt(1 - 0.98**2)], [1.0, -0.98], rng.normal(size=t.size)) * 0.05
    swing = 0.08 * np.sin(2 * np.pi * t / 3.0) + wander
    diff = 0.06 * np.sin(2 * np.pi * t[:, None] / np.array([1.1, 1.7, 2.3, 2.9]))
    u = np.clip(u_hover[:, None] + swing[:, None] + diff, 0.08, 0.95)
    truth = (K_N * (u * volt[:, None] / NOMINAL_V) ** 2).sum(axis=1)
    drive = rng.normal(size=t.size) * NOISE_N * np.sqrt(1 - POLE**2)
    noise = rng.normal(size=t.size) * NOISE_N + lfilter([1.0], [1.0, -POLE], drive)
    return FlightData(name, 1000.0 + 1000.0 * u, volt, np.ones(t.size, bool), t, truth + noise,
                      MASS_KG * G0_M_S2, 1.0 / RATE_HZ)


def lag1_covariance(fitted: Fit) -> np.ndarray:
    """The covariance ``identify thrust`` stored before 2026-11-28: ``s² (AᵀA)⁻¹ (1 + ρ)/(1 - ρ)``, ``ρ`` the
    residuals' lag-1 autocorrelation (clipped to [0, 0.95])."""
    a, e = fitted.design, fitted.residual_N
    n, k = a.shape
    rho = float(np.clip(np.corrcoef(e[:-1], e[1:])[0, 1], 0.0, 0.95))
    return float(e @ e) / (n - k) * (1.0 + rho) / (1.0 - rho) * np.linalg.pinv(a.T @ a)


@dataclass
class ThrustStudy:
    values: np.ndarray  #: repeats x 2
    std: np.ndarray  #: ``identification.thrust.model.covariance``
    std_lag1: np.ndarray  #: the lag-1 inflation of before

    def coverage(self, std: np.ndarray) -> np.ndarray:
        return np.mean(np.abs(self.values - TRUTH) <= 1.96 * std, axis=0)

    def width_ratio(self, std: np.ndarray) -> np.ndarray:
        """Median 95 % half-width over the RMS of estimate - truth."""
        return np.median(1.96 * std, axis=0) / np.sqrt(np.mean((self.values - TRUTH) ** 2, axis=0))


def run_study(repeats: int, seed: int = 0) -> ThrustStudy:
    values, std, lag1 = [], [], []
    for k in range(repeats):
        rng = np.random.default_rng(seed + k)
        fitted = fit([flight(rng, f"f{j}") for j in range(3)], SPEC, 1, 5.0, "thrust coverage")
        values.append(np.concatenate([np.asarray(r) for r in fitted.params.thrust_map.consequents]))
        std.append(np.sqrt(np.diag(covariance(fitted))))
        lag1.append(np.sqrt(np.diag(lag1_covariance(fitted))))
    return ThrustStudy(np.array(values), np.array(std), np.array(lag1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if not 2 <= args.repeats <= 5000:
        parser.error("--repeats must be in 2..5000")
    st = run_study(args.repeats, args.seed)
    cov, wid = st.coverage(st.std), st.width_ratio(st.std)
    cov1, wid1 = st.coverage(st.std_lag1), st.width_ratio(st.std_lag1)
    print(f"{args.repeats} repeats, seed {args.seed}; 95 % intervals of the thrust map's consequents; 'hw/rms': "
          "median half-width over the RMS of estimate - truth")
    print(f"{'coefficient':<12} {'truth':>7} {'coverage':>9} {'hw/rms':>7}   {'lag-1 (before)':>14} {'hw/rms':>7}")
    for i, n in enumerate(NAMES):
        print(f"{n:<12} {TRUTH[i]:7.3f} {cov[i]:9.2f} {wid[i]:7.2f}   {cov1[i]:14.2f} {wid1[i]:7.2f}")
    ok = bool(np.all(cov >= MIN_COVERAGE) and np.all(wid <= MAX_WIDTH))
    print(f"targets coverage >= {MIN_COVERAGE:.2f}, half-width <= {MAX_WIDTH:g} x scatter -> "
          f"{'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

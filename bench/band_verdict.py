"""How often ``validate --mc``'s band verdict calls a finding, on replays whose truth is known.

Each replay: ``--windows`` windows of 50 samples whose standardised residual z is AR(1) with correlation phi from one
sample to the next (independent between windows: each window restarts from the log), scored against the band
|z| < h. The band's true coverage is set by h: a right 90 % band (h = 1.645), one on the threshold of "wide"
(98 %, h = 2.326), and wrong ones covering 60 %, 68 % and 99.7 %. Per case the share of replays whose verdict is
a finding (``identification.validation.mc_bands.coverage_bounds``: the coverage's one-sided 95 % bound past 80 %
or 98 %) is printed beside the share the point figure alone would call one.

Targets: a right band is a finding in at most 5 % of replays and a band on the threshold is called wide in at
most 5 % (the bound's level), for every window count and correlation; a band covering 60 % is shown below 80 %
in at least 90 % of replays from 20 windows of correlation 0.9 or less. Exit 1 on a miss.

Run: ``.venv/bin/python bench/band_verdict.py [--replays 1000] [--seed 0]`` (about 25 s).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identification.validation.mc_bands import (
    MAX_COVERAGE,
    MIN_COVERAGE,
    band_position,
    coverage_bounds,
)

SAMPLES = 50
WINDOWS = (6, 20, 60)
PHIS = (0.5, 0.9, 0.98)
#: (name, half-width h of the band |z| < h, true coverage)
CASES = (("right 90 %", 1.645), ("on 98 %", 2.326), ("covers 60 %", 0.842), ("covers 68 %", 1.0),
         ("covers 99.7 %", 3.0))
MAX_REPLAYS = 100_000


def replays(rng: np.random.Generator, count: int, windows: int, phi: float) -> np.ndarray:
    """Standard normal AR(1) residuals, count x windows x ``SAMPLES``."""
    z = np.empty((count, windows, SAMPLES))
    z[..., 0] = rng.standard_normal((count, windows))
    kick = rng.standard_normal(z.shape) * np.sqrt(1.0 - phi**2)
    for j in range(1, SAMPLES):
        z[..., j] = phi * z[..., j - 1] + kick[..., j]
    return z


def findings(z: np.ndarray, half: float) -> tuple[float, float, float]:
    """Shares of replays shown below ``MIN_COVERAGE``, shown above ``MAX_COVERAGE``, and past either by the point
    figure alone."""
    low = wide = point = 0
    win = np.repeat(np.arange(z.shape[1]), z.shape[2])
    edge = np.full(z.shape[1] * z.shape[2], half)
    for rep in z:
        flat = rep.ravel()
        inside = np.abs(flat) < half
        b, c = coverage_bounds(inside, win, band_position(flat, -edge, edge)), float(inside.mean())
        low += c < MIN_COVERAGE and b.upper < MIN_COVERAGE
        wide += c > MAX_COVERAGE and b.lower > MAX_COVERAGE
        point += not MIN_COVERAGE <= c <= MAX_COVERAGE
    return low / len(z), wide / len(z), point / len(z)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replays", type=int, default=1000, help=f"replays per case (1..{MAX_REPLAYS})")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    if not 1 <= a.replays <= MAX_REPLAYS:
        ap.error(f"--replays = {a.replays}: allowed 1..{MAX_REPLAYS}")
    rng = np.random.default_rng(a.seed)
    misses = []
    print(f"{a.replays} replays per case, windows of {SAMPLES} samples; shares of replays called a finding "
          "(shown below 80 % / shown above 98 %) and, for comparison, past either by the point figure alone")
    print(f"{'band':14s} {'windows':>7s} {'phi':>5s} {'low':>6s} {'wide':>6s} {'point':>6s}")
    for name, half in CASES:
        for m in WINDOWS:
            for phi in PHIS:
                low, wide, point = findings(replays(rng, a.replays, m, phi), half)
                print(f"{name:14s} {m:7d} {phi:5.2f} {low:6.3f} {wide:6.3f} {point:6.3f}")
                if name == "right 90 %" and low + wide > 0.05:
                    misses.append(f"right band a finding in {low + wide:.1%} ({m} windows, phi {phi})")
                if name == "on 98 %" and wide > 0.05:
                    misses.append(f"band on the threshold called wide in {wide:.1%} ({m} windows, phi {phi})")
                if name == "covers 60 %" and m >= 20 and phi <= 0.9 and low < 0.90:
                    misses.append(f"band covering 60 % shown in only {low:.1%} ({m} windows, phi {phi})")
    print("MISS: " + "; ".join(misses) if misses else "every target met")
    return 1 if misses else 0


if __name__ == "__main__":
    raise SystemExit(main())

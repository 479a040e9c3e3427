"""Where the bias of the output-error estimate comes from (C_ell_r in ``bench/aero_coverage.py``).

Three sources are separated on the coverage study's generator (eight 8 s manoeuvres at 50 Hz from
``identification.flights.synthetic.identification_manoeuvres``, the same twelve free derivatives and outputs):

1. ``mismatch``: the plant's FIXED coefficients differ (``aero_coverage.MISMATCH``), NO noise, the tool's
   ``--free auto`` round (``aero_coverage._auto_fit``): the error left is what the fixed coefficients leak
   into the free ones after auto-freeing.
2. ``white``: no mismatch, white noise only (``aero_coverage.WHITE``), the same seeds from two starts
   (truth x 0.98 and x 1.02): equal estimates from both show the solver converged, so an error pattern is
   the estimator's, not the stopping rule's.
3. ``coloured``: no mismatch, the study's white + AR(1) noise.

Printed per parameter: mean error over the coloured Cramér-Rao std, its standard error over the repeats, and
the scatter over the Cramér-Rao std (near 1 when the bound is right).
Exit 1 when any mean error exceeds 3 standard errors (a bias the repeats resolve).

Run: ``.venv/bin/python bench/aero_bias.py [--repeats 6]`` (about 15 s per fit on 2 shared cores).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import aero_coverage as ac

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.aero.priors import CONSIDERED, fixed_sd
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.flights.synthetic import identification_manoeuvres


def _mismatch_error(sim: Simulator, p: np.ndarray) -> np.ndarray:
    pp = ac.plant_params(sim.model, p)
    oe = OutputErrorEstimator(sim.model, p, ac.FREE, ac.OUTPUTS)
    truth = pp[oe.i_free]
    clean = identification_manoeuvres(OutputErrorEstimator(sim.model, pp, ac.FREE, ac.OUTPUTS), pp, 8.0, 50.0, 8,
                                      None)
    start = dict(zip(sim.model.params.index, p, strict=True))
    consider = {n: fixed_sd(n, float(start[n])) for n in CONSIDERED if n not in ac.FREE}
    est = ac._auto_fit(oe, clean, truth * 1.05, consider, {}, {})
    return (est.values[:len(ac.FREE)] - truth) / np.abs(truth)


def _noise(rng: np.random.Generator, shape: tuple[int, int], coloured: bool) -> np.ndarray:
    return ac._noise(rng, shape) if coloured else rng.normal(0.0, 1.0, shape) * ac.WHITE


def _noise_errors(sim: Simulator, p: np.ndarray, repeats: int, coloured: bool, start: float) -> np.ndarray:
    oe = OutputErrorEstimator(sim.model, p, ac.FREE, ac.OUTPUTS)
    truth = p[oe.i_free]
    clean = identification_manoeuvres(oe, p, 8.0, 50.0, 8, None)
    rows = []
    for k in range(repeats):
        rng = np.random.default_rng(k)
        data = [Manoeuvre(m.x0, m.u, m.y + _noise(rng, m.y.shape, coloured), m.dt_s, m.name) for m in clean]
        est = oe.estimate(data, theta0=truth * start, max_iter=60)
        rows.append((est.values[:len(ac.FREE)] - truth) / est.crb_std[:len(ac.FREE)])
    return np.array(rows)


def _table(title: str, err: np.ndarray) -> bool:
    mean, se = err.mean(axis=0), err.std(axis=0, ddof=1) / np.sqrt(len(err))
    print(f"{title}: mean error / CR std (standard error), scatter / CR std; {len(err)} repeats")
    for n, m, s, sd in zip(ac.FREE, mean, se, err.std(axis=0, ddof=1), strict=True):
        print(f"  {n:<14} {m:+6.2f} ({s:.2f}) {sd:5.2f}{'  <- bias' if abs(m) > 3 * s else ''}")
    return bool(np.any(np.abs(mean) > 3 * se))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=6)
    args = parser.parse_args()
    if not 2 <= args.repeats <= 200:
        parser.error("--repeats must be in 2..200")
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    rel = _mismatch_error(sim, p)
    print("mismatch, no noise, after the --free auto round: relative error "
          + ", ".join(f"{n} {e:+.1e}" for n, e in zip(ac.FREE, rel, strict=True)))
    lo, hi = (_noise_errors(sim, p, args.repeats, False, s) for s in (0.98, 1.02))
    print(f"white noise, starts x0.98 and x1.02: largest difference {np.max(np.abs(lo - hi)):.2e} CR std")
    biased = _table("white noise, no mismatch", hi)
    biased |= _table("white + AR(1) noise, no mismatch", _noise_errors(sim, p, args.repeats, True, 1.02))
    return 1 if biased else 0


if __name__ == "__main__":
    raise SystemExit(main())

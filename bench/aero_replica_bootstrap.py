"""Why the small-sample bound fires on the excitation-log replica: the segment bootstrap taken apart on one draw.

One draw of ``bench/aero_replica.py`` (its truth, noise and options) is identified as ``identify aero`` does;
then, per primary derivative, in units of its AR coloured Cramér-Rao std (``Estimate.crb_std``):

- ``boot``: the segment bootstrap ``identify aero`` computed (``OutputErrorEstimator.segment_bootstrap_std``:
  each resample re-solves with its own information ``sum w_j A_j + P``; IQR / 1.349; leverage factor);
- ``fixed-M``: the same resamples with the information held at the full sample's (the linear statistic
  ``M⁻¹ sum w_j g_j`` that the leverage factor and the degrees of freedom of ``oem.segment_corrections`` describe);
- ``cluster``: its analytic value, ``sqrt(factor x sum_j (bᵀ g_j)²)``;
- the bootstrap's degrees of freedom and each fit segment's share of the derivative's information
  (``bᵀ A_j b / bᵀ sum A b``, ``b = M⁻¹ e_i``), and whether the small-sample bound enters with each spread
  (``oem.small_sample_needed``).

Exit 1 when the bound enters for a derivative where the fixed-information spread would not call for it (the
re-solved information alone decides), 0 otherwise; exit 2 when the log is absent.

Run: ``.venv/bin/python bench/aero_replica_bootstrap.py [--seed 0] [--start-state logged|exact] [--resamples
2000]`` (one identify run: 20-60 s on 2 cores).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from aero_replica import LOG, replica_fit  # the replica draw itself

from identification.aero.identify import PRIMARY
from identification.estimation.oem import small_sample_needed


def _iqr_std(x: np.ndarray) -> np.ndarray:
    q75, q25 = np.percentile(x, [75, 25], axis=0)
    return (q75 - q25) / 1.349


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--start-state", choices=("logged", "exact"), default="logged")
    parser.add_argument("--resamples", type=int, default=2000)
    args = parser.parse_args()
    if not 100 <= args.resamples <= 20000:
        parser.error("--resamples must be in 100..20000")
    if not LOG.exists():
        print(f"{LOG} is absent; nothing to replicate")
        return 2
    _, _, _, result, _ = replica_fit(args.seed, exact_start=args.start_state == "exact")
    est, oe, data = result.fit.estimate, result.fit.oe, result.fit.data
    theta = est.values
    sims = [oe.simulate(theta, m, j) for j, m in enumerate(data)]
    res = [m.y - s[0] for m, s in zip(data, sims, strict=True)]
    jacs = [s[1] for s in sims]
    W = np.diag(1.0 / np.maximum(np.mean(np.vstack(res) ** 2, axis=0), 1e-300))  # as the fit weighs (sigma unset)
    terms = oe._segment_terms(res, jacs, W)
    A, g = np.stack([t[0] for t in terms]), np.stack([t[1] for t in terms])
    ng = len(oe.free)
    P = np.diag(oe.prior_information(ng))
    gp = P @ (oe.prior_mean - theta[:ng])
    got = oe.segment_bootstrap_std(res, jacs, W, theta=theta)
    if got is None:
        print("fewer segments than the bootstrap needs")
        return 2
    boot, factor, dof = got
    Mi = np.linalg.pinv(A.sum(axis=0) + P)
    rng = np.random.default_rng(args.seed)
    m = len(data)
    w = np.stack([np.bincount(rng.integers(0, m, m), minlength=m).astype(float) for _ in range(args.resamples)])
    fixed = _iqr_std((w @ g + gp) @ Mi.T) * np.sqrt(factor)
    cluster = np.array([np.sqrt(factor[i] * np.sum((g @ Mi[:, i]) ** 2)) for i in range(ng)])
    crb = est.crb_std[:ng]
    fires, fires_fixed = small_sample_needed(crb, boot, dof), small_sample_needed(crb, fixed, dof)
    print(f"draw {args.seed}, segment starts {args.start_state}: {m} fit segments ({', '.join(d.name for d in data)})")
    print(f"{'derivative':<14} {'boot':>6} {'fixed-M':>7} {'cluster':>7} {'dof':>5} {'bound enters':>12} "
          f"{'with fixed-M':>12}  information share per segment")
    decided = []
    for n in PRIMARY:
        i = oe.free.index(n)
        b = Mi[:, i]
        share = np.array([b @ Aj @ b for Aj in A])
        share /= share.sum()
        if fires[i] and not fires_fixed[i]:
            decided.append(n)
        print(f"{n:<14} {boot[i] / crb[i]:6.2f} {fixed[i] / crb[i]:7.2f} {cluster[i] / crb[i]:7.2f} {dof[i]:5.1f} "
              f"{'yes' if fires[i] else 'no':>12} {'yes' if fires_fixed[i] else 'no':>12}  "
              + " ".join(f"{x:.2f}" for x in share))
    print(f"the re-solved information alone brings in the small-sample bound for: {', '.join(decided) or 'none'}")
    return 1 if decided else 0


if __name__ == "__main__":
    raise SystemExit(main())

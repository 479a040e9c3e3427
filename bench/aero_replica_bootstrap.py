"""Why the small-sample bound fires on the excitation-log replica: the segment bootstrap taken apart on one draw.

One draw of ``bench/aero_replica.py`` (its truth, noise and options) is identified as ``identify aero`` does;
then, per primary derivative, in units of its AR coloured Cramér-Rao std (``Estimate.crb_std``):

- ``re-solved``: the segment bootstrap as ``identify aero`` computed it until 2026-11-29 (each resample re-solved
  with its own information ``sum w_j A_j + P``; IQR / 1.349; leverage factor), recomputed here;
- ``fixed-M``: the same resamples with the information held at the full sample's (the linear statistic
  ``M⁻¹ sum w_j g_j`` that the leverage factor and the degrees of freedom of ``oem.segment_corrections`` describe);
- ``tool``: what ``OutputErrorEstimator.segment_bootstrap_std`` computes now (fixed information, plain std);
- ``cluster``: its analytic value, ``sqrt(factor x sum_j (bᵀ g_j)²)``;
- the bootstrap's degrees of freedom, the segments' excess scatter pooled over the parameters and its degrees of
  freedom (``oem.segment_scatter``), each fit segment's share of the derivative's information
  (``bᵀ A_j b / bᵀ sum A b``, ``b = M⁻¹ e_i``), and whether the small-sample bound enters by the rule of before
  (re-solved spread, own degrees of freedom) and by the tool's now (``oem.small_sample_needed`` with the pooled
  scatter).

Exit 1 when the tool's spread is not the fixed-information one (more than 10 % from it for a primary), 0
otherwise; exit 2 when the log is absent.

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
from identification.estimation.oem import segment_scatter, small_sample_needed


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
    tool, factor, dof = got
    Mi = np.linalg.pinv(A.sum(axis=0) + P)
    rng = np.random.default_rng(args.seed)
    m = len(data)
    w = np.stack([np.bincount(rng.integers(0, m, m), minlength=m).astype(float) for _ in range(args.resamples)])
    resolved = _iqr_std(np.array([np.linalg.lstsq(np.einsum("j,jab->ab", wk, A) + P, wk @ g + gp, rcond=None)[0]
                                  for wk in w])) * np.sqrt(factor)
    fixed = _iqr_std((w @ g + gp) @ Mi.T) * np.sqrt(factor)
    cluster = np.array([np.sqrt(factor[i] * np.sum((g @ Mi[:, i]) ** 2)) for i in range(ng)])
    crb = est.crb_std[:ng]
    scatter = segment_scatter(A, g, P, crb)
    before, now = small_sample_needed(crb, resolved, dof), small_sample_needed(crb, tool, dof, scatter)
    ratio, pooled_dof = scatter
    print(f"draw {args.seed}, segment starts {args.start_state}: {m} fit segments ({', '.join(d.name for d in data)})")
    print("spreads in AR coloured Cramér-Rao std; 'pooled': the excess scatter (variance ratio) pooled over the "
          f"{ng} parameters and its degrees of freedom")
    print(f"{'derivative':<14} {'re-solved':>9} {'fixed-M':>7} {'tool':>6} {'cluster':>7} {'dof':>5} {'pooled':>6} "
          f"{'dof':>5} {'enters before':>13} {'now':>4}  information share per segment")
    off = []
    for n in PRIMARY:
        i = oe.free.index(n)
        b = Mi[:, i]
        share = np.array([b @ Aj @ b for Aj in A])
        share /= share.sum()
        if abs(tool[i] / cluster[i] - 1.0) > 0.1:
            off.append(n)
        print(f"{n:<14} {resolved[i] / crb[i]:9.2f} {fixed[i] / crb[i]:7.2f} {tool[i] / crb[i]:6.2f} "
              f"{cluster[i] / crb[i]:7.2f} {dof[i]:5.1f} {ratio[i]:6.2f} {pooled_dof[i]:5.1f} "
              f"{'yes' if before[i] else 'no':>13} {'yes' if now[i] else 'no':>4}  "
              + " ".join(f"{x:.2f}" for x in share))
    count = [sum(x[oe.free.index(n)] for n in PRIMARY) for x in (before, now)]
    print(f"small-sample bound: before for {count[0]} primaries, now for {count[1]}; the tool's spread off the "
          f"fixed-information one: {', '.join(off) or 'none'}")
    return 1 if off else 0


if __name__ == "__main__":
    raise SystemExit(main())

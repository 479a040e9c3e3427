"""Why a printed interval of the coverage study is short: every component of the data bound against the actual
scatter, on the fits of ``bench/aero_coverage.py`` (C_ell_r).

Per repeat the final fit's bootstrap inputs are kept (each manoeuvre's information ``A_j`` and score ``g_j``
with the nuisance parameters profiled out, the resamples), and per derivative over the repeats are printed,
as fractions of the actual scatter of the estimates: the coloured Cramér-Rao bound; the bootstrap spread as
IQR/1.349 and as a plain std (both without any small-sample factor); the analytic cluster sandwich
``M⁻¹ Σ ĝ_j ĝ_jᵀ M⁻¹`` and the linearised leave-one-manoeuvre-out jackknife (both steps from the same
``A_j, g_j``); the largest leverage of one manoeuvre on the derivative (``diag(A_j M⁻¹)``, the share of
its information that manoeuvre carries, 1/m for equal manoeuvres; correlations can take it outside 0..1); the
leverage factor and degrees of freedom of ``oem.segment_corrections``; and the coverage of the data bound
with the bootstrap scaled by the equal-segment ``sqrt(m/(m-1)) t(m-1)/z`` against the same spread scaled by
``sqrt(factor) t(dof)/z``, alone ("data") and with the consider share in quadrature ("printed").

``--equal-segments`` runs the fits with the equal-segment corrections in the tool (as before 2026-11-26: they
also decide what ``--free auto`` frees, which compares the consider share with the data bound), so the two
coverage columns compare the bounds on the fits of the previous code.

Run: ``.venv/bin/python bench/aero_bound_diag.py [--repeats 50] [--priors on|off] [--equal-segments]`` (about
2 s per repeat). A diagnosis: it prints and exits 0.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import aero_coverage as ac

import identification.estimation.oem as oem

_KEPT: list[dict[str, np.ndarray]] = []
_LAST: dict[str, np.ndarray] = {}


def _keep_bootstrap(A: np.ndarray, g: np.ndarray, P: np.ndarray, gp: np.ndarray, repeats: int, seed: int,
                    **kw: object) -> np.ndarray:
    """``oem.bootstrap_repeats``, keeping its inputs and resamples."""
    reps = _ORIGINAL_BOOTSTRAP(A, g, P, gp, repeats, seed, **kw)
    _LAST.update(A=A.copy(), g=g.copy(), P=P.copy(), reps=reps.copy())
    return reps


def _keep_fit(*args: object, **kw: object) -> oem.Estimate:
    """``aero_coverage._auto_fit``, keeping the bootstrap inputs of its final fit."""
    est = _ORIGINAL_FIT(*args, **kw)
    _KEPT.append(dict(_LAST))  # the last bootstrap of a repeat is its final fit's
    return est


def _equal_segments(A: np.ndarray, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The corrections before 2026-11-26: m/(m-1) and m-1 degrees of freedom for every parameter."""
    m, n = A.shape[0], A.shape[1]
    return np.full(n, m / (m - 1.0)), np.full(n, m - 1.0)


_ORIGINAL_BOOTSTRAP, _ORIGINAL_FIT, _CORRECTIONS = oem.bootstrap_repeats, ac._auto_fit, oem.segment_corrections


def _row(kept: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    A, g, P, reps = kept["A"], kept["g"], kept["P"], kept["reps"]
    m = A.shape[0]
    Mi = np.linalg.inv(A.sum(axis=0) + P)
    q75, q25 = np.percentile(reps, [75, 25], axis=0)
    jack = np.array([np.linalg.solve(A.sum(axis=0) + P - A[j], -g[j]) for j in range(m)])
    factor, dof = _CORRECTIONS(A, P)
    return {"iqr": ((q75 - q25) / 1.349)[:n], "std": reps.std(axis=0)[:n],
            "sandwich": np.sqrt(np.diag(Mi @ (g.T @ g) @ Mi))[:n],
            "jackknife": np.sqrt((m - 1) / m * np.sum((jack - jack.mean(axis=0)) ** 2, axis=0))[:n],
            "share": np.max([np.diag(A[j] @ Mi) for j in range(m)], axis=0)[:n], "factor": factor[:n],
            "dof": dof[:n]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--priors", choices=("on", "off"), default="on")
    parser.add_argument("--equal-segments", action="store_true", help="fit with the equal-segment corrections")
    args = parser.parse_args()
    if not 2 <= args.repeats <= 1000:
        parser.error("--repeats must be in 2..1000")
    oem.bootstrap_repeats, ac._auto_fit = _keep_bootstrap, _keep_fit
    if args.equal_segments:
        oem.segment_corrections = _equal_segments
    st = ac.run_study(args.repeats, priors=args.priors == "on")
    n, m = len(ac.FREE), st.segments
    rows = [_row(k, n) for k in _KEPT]
    col = {key: np.array([r[key] for r in rows]) for key in rows[0]}
    err = np.abs(st.values - st.truth)
    sd = np.std(st.values - st.truth, axis=0, ddof=1)
    equal = col["iqr"] * np.sqrt(m / (m - 1.0)) * oem.student_factor(m - 1.0)
    corrected = col["iqr"] * np.sqrt(col["factor"]) * oem.student_factor(col["dof"])
    consider = np.sqrt(np.maximum(st.printed ** 2 - st.data ** 2, 0.0))
    kind = "equal-segment" if args.equal_segments else "leverage"
    print(f"priors {args.priors}, {len(rows)} repeats, fits with the {kind} corrections: bounds as a fraction of "
          "the actual scatter (means over the repeats), largest "
          "one-manoeuvre leverage, leverage factor and degrees of freedom, coverage of max(CR coloured, "
          "bootstrap x equal-segment / leverage correction), alone (data) and with the consider share (printed)")
    print(f"{'parameter':<14} {'CR col':>6} {'IQR':>5} {'std':>5} {'sandw':>6} {'jack':>5} {'lever':>6} "
          f"{'factor':>6} {'dof':>4} {'data m-1':>9} {'data dof':>9} {'printed m-1':>12} {'printed dof':>12}")
    for i, name in enumerate(ac.FREE):
        frac = {k: np.mean(col[k][:, i]) / sd[i] for k in ("iqr", "std", "sandwich", "jackknife")}
        data = [np.maximum(st.crb[:, i], b[:, i]) for b in (equal, corrected)]
        cover = [np.mean(err[:, i] <= 1.96 * d) for d in data]
        cover += [np.mean(err[:, i] <= 1.96 * np.hypot(d, consider[:, i])) for d in data]
        print(f"{name:<14} {np.mean(st.crb[:, i]) / sd[i]:6.2f} {frac['iqr']:5.2f} {frac['std']:5.2f} "
              f"{frac['sandwich']:6.2f} {frac['jackknife']:5.2f} {np.mean(col['share'][:, i]):6.2f} "
              f"{np.mean(col['factor'][:, i]):6.2f} {np.mean(col['dof'][:, i]):4.1f} {cover[0]:9.2f} {cover[1]:9.2f} "
              f"{cover[2]:12.2f} {cover[3]:12.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Identifiability of an output-error problem, before and after the solve (Klein & Morelli ch. 5; Jategaonkar).

From the information matrix ``M = Σ Jᵀ W J`` of the weighted output sensitivities ``J``:

- the condition number of the column-normalised sensitivity matrix (``sqrt(cond(D M D))``, ``D = diag(M)^-1/2``):
  above ~100 the data hardly separate the free parameters;
- the parameter correlation matrix from ``M⁻¹``; pairs above |r| = 0.9 are named;
- the least identifiable combination (eigenvector of the smallest eigenvalue of ``D M D``);
- the excitation of each input axis over the records (std of the input about each record's mean);
- what would fix each problem: fix one of a correlated pair, or add a manoeuvre exciting its axis.

:func:`select_free` picks a well-conditioned free set greedily (a library helper; ``identify aero --free auto``
starts from the primary derivatives with priors instead, see ``identification/aero/readme.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: |correlation| above which a pair is named
CORRELATION_LIMIT = 0.9
#: condition number of the normalised sensitivity matrix above which the set is called ill-conditioned
CONDITION_LIMIT = 100.0
#: input std (rad or throttle fraction) below which an axis counts as not excited
EXCITATION_MIN = {"aileron_rad": 0.005, "elevator_rad": 0.005, "rudder_rad": 0.005, "throttle": 0.01}
#: the input axis that moves each derivative family (for advice)
AXIS_OF = {"C_ell": "aileron_rad", "C_n": "rudder_rad", "C_Y": "rudder_rad", "C_m": "elevator_rad",
           "C_L": "elevator_rad", "C_D": "throttle"}
#: candidates of ``--free auto``, primary derivatives first (order = priority)
AUTO_CANDIDATES = ("C_ell_p", "C_ell_delta_a", "C_m_q", "C_m_delta_e", "C_m_alpha", "C_n_r", "C_n_delta_r",
                   "C_n_beta", "C_Y_beta", "C_ell_beta", "C_ell_r", "C_Y_delta_r", "C_ell_delta_r", "C_n_p",
                   "C_n_delta_a", "C_Y_p", "C_Y_r", "C_L_alpha", "C_L_0", "C_m_0", "C_L_delta_e", "C_L_q")


def axis_of(name: str) -> str | None:
    """The input axis that excites parameter ``name`` (its control surface, or its moment's surface)."""
    for s, axis in (("delta_a", "aileron_rad"), ("delta_e", "elevator_rad"), ("delta_r", "rudder_rad")):
        if s in name:
            return axis
    return next((a for k, a in AXIS_OF.items() if name.startswith(k + "_")), None)


@dataclass
class Identifiability:
    """Condition number, correlations and advice for one free set and data set."""

    names: list[str]
    condition_number: float
    correlation: np.ndarray
    pairs: list[tuple[str, str, float]]
    weakest: list[tuple[str, float]]
    excitation: dict[str, float] = field(default_factory=dict)
    advice: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.condition_number <= CONDITION_LIMIT and not self.pairs

    def as_dict(self) -> dict[str, Any]:
        return {"condition_number": _finite(self.condition_number), "condition_limit": CONDITION_LIMIT,
                "correlation_limit": CORRELATION_LIMIT, "names": self.names,
                "correlated_pairs": [{"a": a, "b": b, "r": round(r, 4)} for a, b, r in self.pairs],
                "weakest_combination": {n: round(c, 4) for n, c in self.weakest},
                "input_excitation_std": self.excitation, "advice": self.advice, "well_conditioned": self.ok}

    def lines(self) -> list[str]:
        out = [f"condition number (normalised sensitivities) {self.condition_number:.3g} "
               f"({'ok' if self.condition_number <= CONDITION_LIMIT else f'above {CONDITION_LIMIT:g}'})"]
        out += [f"correlated: {a} ~ {b} (r = {r:+.3f})" for a, b, r in self.pairs]
        if self.excitation:
            out.append("input excitation (std): " + ", ".join(f"{k} {v:.3g}" for k, v in self.excitation.items()))
        out += [f"advice: {a}" for a in self.advice]
        return out


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def normalised(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(D M D, D)`` with ``D = diag(M)^-1/2`` (zero columns kept at zero)."""
    d = np.sqrt(np.maximum(np.diag(M), 0.0))
    dinv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    return M * np.outer(dinv, dinv), dinv


def condition_number(M: np.ndarray) -> float:
    """Condition number of the column-normalised sensitivity matrix: ``sqrt(λmax / λmin)`` of ``D M D``."""
    if M.size == 0:
        return 1.0
    Ms, _ = normalised(M)
    ev = np.linalg.eigvalsh(0.5 * (Ms + Ms.T))
    return float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 1e-300 else float("inf")


def correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance; entries of zero-variance parameters are 0 (never NaN)."""
    d = np.sqrt(np.maximum(np.diag(cov), 0.0))
    ok = d > 1e-150
    dd = np.where(ok, d, 1.0)
    out = cov / np.outer(dd, dd)
    out[~ok, :] = 0.0
    out[:, ~ok] = 0.0
    out[np.diag_indices_from(out)] = np.where(ok, 1.0, 0.0)
    return np.clip(out, -1.0, 1.0)


def input_excitation(inputs: Sequence[np.ndarray], names: Sequence[str]) -> dict[str, float]:
    """RMS over records of each input's std about the record's own mean."""
    var = np.mean([np.var(u, axis=0) for u in inputs], axis=0)
    return {n: float(np.sqrt(v)) for n, v in zip(names, var, strict=True)}


def analyse(M: np.ndarray, names: Sequence[str], n_global: int, excitation: dict[str, float] | None = None,
            cov: np.ndarray | None = None) -> Identifiability:
    """Identifiability of the first ``n_global`` parameters (the derivatives) given the information matrix ``M``
    of all estimated quantities (nuisance parameters included: they are what they are correlated with)."""
    names = list(names)
    cov = np.linalg.pinv(M) if cov is None else cov
    corr = correlation(cov)
    # condition of the derivatives after the nuisance parameters are profiled out (Schur complement)
    g = slice(0, n_global)
    if len(names) > n_global:
        Ml = M[n_global:, n_global:]
        Mg = M[g, g] - M[g, n_global:] @ np.linalg.pinv(Ml) @ M[n_global:, g]
    else:
        Mg = M[g, g]
    cond = condition_number(Mg)
    pairs = [(names[i], names[k], float(corr[i, k])) for i in range(n_global) for k in range(i + 1, len(names))
             if abs(corr[i, k]) > CORRELATION_LIMIT]
    weakest: list[tuple[str, float]] = []
    if n_global:
        Ms, _ = normalised(Mg)
        _, vec = np.linalg.eigh(0.5 * (Ms + Ms.T))
        v = vec[:, 0]
        order = np.argsort(-np.abs(v))
        weakest = [(names[i], float(v[i])) for i in order if abs(v[i]) > 0.3]
    exc = dict(excitation or {})
    return Identifiability(names[:n_global] + names[n_global:], cond, corr, pairs, weakest, exc,
                           advice(pairs, cond, weakest, exc))


def advice(pairs: Sequence[tuple[str, str, float]], cond: float, weakest: Sequence[tuple[str, float]],
           excitation: dict[str, float]) -> list[str]:
    """What would make the set identifiable: fix one of each correlated pair, excite the weak axes."""
    out = []
    for a, b, r in pairs:
        fixed = b if "." not in b else a
        axis = axis_of(a) or axis_of(b)
        hint = f" or add a manoeuvre that moves {axis} independently (3-2-1-1 or doublet, open loop)" if axis else ""
        out.append(f"{a} and {b} are not separable (r = {r:+.2f}): fix {fixed} at a prior value{hint}")
    if cond > CONDITION_LIMIT and weakest:
        combo = " + ".join(f"{c:+.2f} {n}" for n, c in weakest)
        out.append(f"least identifiable combination: {combo}; fix one of {', '.join(n for n, _ in weakest)}")
    for axis, std in excitation.items():
        lim = EXCITATION_MIN.get(axis)
        if lim is not None and std < lim:
            out.append(f"{axis} hardly moves (std {std:.3g} < {lim:g}): derivatives of its axis are not "
                       "identifiable from these records; add a manoeuvre exciting it")
    return out


def select_free(M: np.ndarray, names: Sequence[str], candidates: Sequence[str] = AUTO_CANDIDATES,
                max_relative_std: float = 0.1, theta: np.ndarray | None = None, margin: float = 0.85) -> list[str]:
    """Greedy well-conditioned free set: walk ``candidates`` in priority order and keep one if the set stays
    below :data:`CONDITION_LIMIT` / 3, no pair exceeds ``margin`` (below :data:`CORRELATION_LIMIT`: the
    start is not the estimate, correlations grow as the fit moves), and its Cramér-Rao std (white) is under
    ``max_relative_std`` of ``|theta|`` (``M`` and ``theta`` over ``names``)."""
    idx = {n: i for i, n in enumerate(names)}
    chosen: list[int] = []
    for name in candidates:
        if name not in idx:
            continue
        trial = [*chosen, idx[name]]
        sub = M[np.ix_(trial, trial)]
        if condition_number(sub) > CONDITION_LIMIT / 3.0:
            continue
        cov = np.linalg.pinv(sub)
        corr = correlation(cov)
        if np.any(np.abs(corr[-1, :-1]) > margin):
            continue
        if theta is not None:
            std = np.sqrt(max(cov[-1, -1], 0.0))
            if std > max_relative_std * max(abs(float(theta[idx[name]])), 1e-6):
                continue
        chosen = trial
    return [names[i] for i in chosen]

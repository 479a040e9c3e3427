"""Commands of the loops a log did not record, estimated from the response they caused.

An autopilot that logs its servo outputs every second loop (ArduPlane: ``RCOU`` from a 25 Hz task, the loop at
50 Hz; ``identification.logs.sensor_chain``) leaves one loop in two unseen. A held command changes at most once
per loop, so an unlogged loop's command lies between its logged neighbours: ``u = before + w (after - before)``,
``0 <= w <= 1``. Their mean (``w = 1/2``) is right on average but not per step: a pilot's or a script's step that
falls in an unlogged loop is seen as half a step one loop early or late, and all steps of one block share the
log task's phase, so on the fastest mode (roll, time constant ~50 ms) the error does not average out within a
flight (the replica bench ``bench/aero_chain_replica.py``: roll derivatives up to 18 % off with the mean alone).

:func:`refine_unlogged` estimates each such ``w`` at a given model estimate: the outputs are linear in one loop's
command over one loop, so with ``d_k`` the change of the simulated outputs per unit ``w_k`` (one simulation per
unlogged loop whose neighbours differ), coordinate descent on the weighted residual ``sum (r - sum_k dw_k d_k)^T W
(r - ...)`` gives each ``w_k`` in closed form, clipped to [0, 1]. :func:`fit_with_unlogged` estimates them with
the parameters, the usual treatment of unknown inputs as nuisance parameters of an output-error fit (Jategaonkar
2015, ch. 5: input errors estimated with the system parameters), by Gauss-Newton steps of the parameters with the
commands profiled out (:func:`profiled_step`, variable projection).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from identification.estimation.oem import Estimate, Manoeuvre, OutputErrorEstimator

#: neighbours closer than this (model input units: rad, throttle 0..1) leave nothing to estimate
MIN_GAP = 1e-6
#: an estimated command within this share of its bracket from a neighbour's value counts as on it
PIN_TOL = 1e-6
#: coordinate-descent passes over the unlogged loops per refinement
SWEEPS = 10


@dataclass(frozen=True)
class Unlogged:
    """The bracket of every loop's command in one manoeuvre (N x nu each): ``before``/``after`` the logged
    neighbours and ``logged`` (True where the loop's own command was logged: it stays as it is)."""

    before: np.ndarray
    after: np.ndarray
    logged: np.ndarray

    def pinned(self, u: np.ndarray) -> Unlogged:
        """This bracket with every unlogged command of ``u`` (N x nu, estimated) that sits on one of its
        neighbours' values counted as logged: the bound holds it there, and only the commands strictly inside
        their brackets are free nuisance parameters (:func:`profiled_std` of the result profiles out those)."""
        gap = self.after - self.before
        w = np.divide(u - self.before, gap, out=np.zeros_like(gap), where=np.abs(gap) > MIN_GAP)
        inside = ~self.logged & (np.abs(gap) > MIN_GAP) & (w > PIN_TOL) & (w < 1.0 - PIN_TOL)
        return Unlogged(self.before, self.after, ~inside)

    def free(self) -> list[tuple[int, int]]:
        """(loop, input) pairs whose command is unknown and not pinned by equal neighbours."""
        mask = ~self.logged & (np.abs(self.after - self.before) > MIN_GAP)
        return [(int(k), int(c)) for k, c in zip(*np.nonzero(mask), strict=True)]


def residual_weight(oe: OutputErrorEstimator, theta: np.ndarray, data: Sequence[Manoeuvre]) -> np.ndarray:
    """Inverse covariance of the output residuals at ``theta`` (the maximum-likelihood weighting)."""
    res = np.vstack([m.y - oe.simulate(theta, m, j, sensitivities=False)[0] for j, m in enumerate(data)])
    return np.linalg.pinv(np.atleast_2d(np.cov(res[np.all(np.isfinite(res), axis=1)].T)))


def refine_unlogged(oe: OutputErrorEstimator, theta: np.ndarray, data: Sequence[Manoeuvre],
                    brackets: Sequence[Unlogged], weight: np.ndarray | None = None) -> list[Manoeuvre]:
    """The manoeuvres with each unlogged loop's command moved, within its bracket, to the value that fits the
    outputs best at ``theta`` (see the module docstring); ``weight`` the ny x ny output weighting (None: the
    inverse residual covariance at ``theta``)."""
    if weight is None:
        weight = residual_weight(oe, theta, data)
    return _refine(oe, theta, data, brackets, weight)[0]


def _refine(oe: OutputErrorEstimator, theta: np.ndarray, data: Sequence[Manoeuvre], brackets: Sequence[Unlogged],
            weight: np.ndarray) -> tuple[list[Manoeuvre], list[np.ndarray], float]:
    """:func:`refine_unlogged`, and per manoeuvre the output change per unit ``w`` of each command left inside its
    bracket (N x ny x n_inside: the columns the profiled step projects out), and the weighted cost (with the
    prior's) of the refined manoeuvres."""
    out, dirs, cost = [], [], oe.prior_cost(theta, data)
    for j, (m, br) in enumerate(zip(data, brackets, strict=True)):
        pairs = br.free()
        ny = m.y.shape[1]
        if not pairs:
            out.append(m)
            dirs.append(np.zeros((*m.y.shape, 0)))
            r = m.y - oe.simulate(theta, m, j, sensitivities=False)[0]
            cost += 0.5 * float(np.einsum("ti,ij,tj->", r, weight, r))
            continue
        u = m.u.copy()
        y0, _, _ = oe.simulate(theta, m, j, sensitivities=False)
        r = m.y - y0
        gap = np.array([br.after[k, c] - br.before[k, c] for k, c in pairs])
        w = np.array([(u[k, c] - br.before[k, c]) / g for (k, c), g in zip(pairs, gap, strict=True)])
        d = []
        for (k, c), g in zip(pairs, gap, strict=True):  # change of the outputs per unit w of this loop
            step = 0.5 * g
            up = u.copy()
            up[k, c] += step
            y1, _, _ = oe.simulate(theta, dataclasses.replace(m, u=up), j, sensitivities=False)
            d.append((y1 - y0) / 0.5)
        if not np.all(np.isfinite(r)) or not all(np.all(np.isfinite(x)) for x in d):
            out.append(m)
            dirs.append(np.zeros((*m.y.shape, 0)))
            cost += np.inf
            continue
        for _ in range(SWEEPS):
            for i, di in enumerate(d):
                den = float(np.einsum("ti,ij,tj->", di, weight, di))
                if den <= 0:
                    continue
                new = float(np.clip(w[i] + np.einsum("ti,ij,tj->", di, weight, r) / den, 0.0, 1.0))
                r -= (new - w[i]) * di
                w[i] = new
        for (k, c), g, wi in zip(pairs, gap, w, strict=True):
            u[k, c] = br.before[k, c] + wi * g
        refined = dataclasses.replace(m, u=u)
        out.append(refined)
        inside = [di for di, wi in zip(d, w, strict=True) if 0.0 < wi < 1.0]
        dirs.append(np.stack(inside, axis=2) if inside else np.zeros((m.y.shape[0], ny, 0)))
        r = m.y - oe.simulate(theta, refined, j, sensitivities=False)[0]
        cost += 0.5 * float(np.einsum("ti,ij,tj->", r, weight, r))
    return out, dirs, cost


def profiled_step(oe: OutputErrorEstimator, theta: np.ndarray, data: Sequence[Manoeuvre], dirs: Sequence[np.ndarray],
                  weight: np.ndarray) -> np.ndarray:
    """Gauss-Newton step of the whole parameter vector ``theta`` with the commands inside their brackets profiled
    out (variable projection, Golub & Pereyra 1973): each manoeuvre's weighted sensitivities and residuals are
    projected onto the complement of its commands' output directions ``dirs`` (from :func:`_refine`), so the
    step accounts for how the best commands move with the parameters. Alternating command and parameter fits
    instead converges linearly (each round's parameter fit is pulled back towards the commands it was given):
    noise-free, 4 rounds left derivatives up to 2.6 % off where the true commands give 0.05 %
    (``bench/aero_chain_bias.py``)."""
    L = np.linalg.cholesky(weight).T
    n_total = len(theta)
    M, g = np.zeros((n_total, n_total)), np.zeros(n_total)
    for j, (m, D) in enumerate(zip(data, dirs, strict=True)):
        y, J, _ = oe.simulate(theta, m, j)
        idx = oe._local_index(j)
        Jw = np.matmul(L, J).reshape(-1, J.shape[2])
        rw = ((m.y - y) @ L.T).ravel()
        if D.shape[2]:
            Dw = np.matmul(L, D).reshape(-1, D.shape[2])
            Jw = Jw - Dw @ np.linalg.lstsq(Dw, Jw, rcond=None)[0]
            rw = rw - Dw @ np.linalg.lstsq(Dw, rw, rcond=None)[0]
        M[np.ix_(idx, idx)] += Jw.T @ Jw
        g[idx] += Jw.T @ rw
    oe._add_prior(M, g, theta, data)
    return np.linalg.lstsq(M, g, rcond=None)[0]


def profiled_std(oe: OutputErrorEstimator, theta: np.ndarray, data: Sequence[Manoeuvre],
                 brackets: Sequence[Unlogged], weight: np.ndarray | None = None) -> np.ndarray:
    """Cramer-Rao std of the free parameters with the unlogged commands as nuisance parameters profiled out
    (Schur complement of their block in the information matrix, white residuals): the bound of a fit whose
    inputs were estimated from the same outputs. Compare with the same bound without them for the inflation."""
    if weight is None:
        weight = residual_weight(oe, theta, data)
    blocks = []
    nth, nl = len(oe.free), oe.n_local
    n_par = nth + len(data) * nl
    for j, (m, br) in enumerate(zip(data, brackets, strict=True)):
        _, jac_j, _ = oe.simulate(theta, m, j, sensitivities=True)
        jac = np.zeros((*jac_j.shape[:2], n_par))  # this manoeuvre's local parameters in their place
        jac[:, :, :nth] = jac_j[:, :, :nth]
        jac[:, :, nth + j * nl:nth + (j + 1) * nl] = jac_j[:, :, nth:]
        y0, _, _ = oe.simulate(theta, m, j, sensitivities=False)
        d = []
        for k, c in br.free():
            up = m.u.copy()
            up[k, c] += 0.5 * (br.after[k, c] - br.before[k, c])
            d.append((oe.simulate(theta, dataclasses.replace(m, u=up), j, sensitivities=False)[0] - y0) / 0.5)
        blocks.append((jac, d))
    info = np.zeros((n_par, n_par))
    for jac, d in blocks:
        m_tt = np.einsum("tia,ij,tjb->ab", jac, weight, jac)
        info += m_tt
        if d:
            dw = np.stack(d, axis=2)  # N x ny x nw
            m_tw = np.einsum("tia,ij,tjb->ab", jac, weight, dw)
            m_ww = np.einsum("tia,ij,tjb->ab", dw, weight, dw)
            info -= m_tw @ np.linalg.pinv(m_ww) @ m_tw.T
    return np.sqrt(np.clip(np.diag(np.linalg.pinv(info)), 0.0, None))[:nth]


#: the profiled iterations stop when no model parameter moves by more than this share of its Cramér-Rao std
STEP_TOL = 0.02
#: step halvings tried when a profiled step does not lower the cost
HALVINGS = 4


def fit_with_unlogged(oe: OutputErrorEstimator, data: Sequence[Manoeuvre], brackets: Sequence[Unlogged],
                      weight: np.ndarray | None, rounds: int = 8, start: Estimate | None = None, **kw: object
                      ) -> tuple[Estimate, list[Manoeuvre]]:
    """Fit (or take ``start``, a fit of ``data``), then at most ``rounds`` Gauss-Newton steps of the parameters
    with the unlogged commands profiled out (:func:`profiled_step`; after each, the commands re-estimated at the
    new parameters, the step halved until the cost falls), until no model parameter moves by more than
    :data:`STEP_TOL` of its Cramér-Rao std; a last warm fit on the final commands gives the estimate and its
    bounds. Returns that estimate and the manoeuvres with the commands it was fitted on. ``kw`` go to
    ``oe.estimate``."""
    est = start if start is not None else oe.estimate(data, weight=weight, **kw)  # type: ignore[arg-type]
    theta = est.values.copy()
    W = weight if weight is not None else residual_weight(oe, theta, data)
    scale = np.maximum(est.crb_std[:len(oe.free)], 1e-300)
    cur, dirs, cost = _refine(oe, theta, data, brackets, W)
    bounds = (np.concatenate([oe.lower, np.full(len(theta) - len(oe.free), -np.inf)]),
              np.concatenate([oe.upper, np.full(len(theta) - len(oe.free), np.inf)]))
    for _ in range(rounds):
        step = profiled_step(oe, theta, cur, dirs, W)
        for _ in range(HALVINGS):
            trial = np.clip(theta + step, *bounds)
            named = dict(zip(oe.free, trial[:len(oe.free)], strict=True))
            if all(c(named) for c in oe.constraints):
                got = _refine(oe, trial, cur, brackets, W)
                if got[2] <= cost:
                    break
            step = step / 2
        else:
            break  # no step lowers the cost: converged as far as the linearisation sees
        moved = float(np.max(np.abs(trial - theta)[:len(oe.free)] / scale))
        theta, (cur, dirs, cost) = trial, got
        if moved < STEP_TOL:
            break
    warm = {**kw, "horizon_s": None}
    est = oe.estimate(cur, theta0=theta, weight=weight, **warm)  # type: ignore[arg-type]
    return est, cur


__all__ = ["Unlogged", "fit_with_unlogged", "profiled_std", "profiled_step", "refine_unlogged", "residual_weight"]

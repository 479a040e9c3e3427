"""Output-error estimation of model parameters (Maine & Iliff, NASA RP-1168; Jategaonkar; Morelli's ``oe.m``).

The model is simulated with the recorded inputs over each manoeuvre, and its outputs are fitted to the
measured ones by Gauss-Newton with Levenberg-Marquardt damping. Output sensitivities are exact derivatives,
by CasADi, of the same model equations the FMU compiles: the classical RK4 scheme applied to the state and
to its forward-sensitivity equations, which for an explicit Runge-Kutta method is exactly the derivative of
the discrete step the FMU takes. No second copy of the physics, no finite differences. The weighting is the
inverse residual covariance re-estimated every iteration (maximum likelihood) or a given matrix B (paper 001
eq. 9). Cramér-Rao bounds carry Morelli & Klein's correction for coloured residuals.

Parameter vector: the free model parameters, then per manoeuvre the estimated initial states and output
biases (``m<j>.x0.<state>``, ``m<j>.bias.<output>``).

A-priori values with standard deviations turn the fit into a maximum-a-posteriori estimate: the prior enters
the cost as ``1/2 Σ ((θ - θ_p)/σ_p)²`` (a priori information as in Klein & Morelli 2006 and Jategaonkar 2015),
and the bounds include it (its information enters the sandwich beside the coloured-residual term). An estimated
initial state can have one too (``initial_sd``): each manoeuvre's given x0 as a measurement of it, which belongs to
that manoeuvre and so enters its nuisance block wherever the nuisance is profiled out per manoeuvre.
Parameters kept fixed at uncertain values enter the bounds as a consider covariance
(:func:`consider_covariance`).

Longer than 700 lines because the cost, its exact gradient, the Gauss-Newton steps, priors and the three bounds
(coloured-residual Cramer-Rao, consider covariance, segment bootstrap) share one compiled CasADi problem.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from tqdm import tqdm

from fmu_models.common.model import BoundedCache, VehicleModel, step_function, traced
from fmu_models.fmi.jit import compiled, jit_context
from identification.estimation.identifiability import Identifiability, analyse, correlation, input_excitation

log = logging.getLogger(__name__)

#: |correlation| above which two estimates are reported as not separable by the data
CORRELATION_WARN = 0.9
#: Cramér-Rao std above this fraction of |estimate| is reported as poorly identified
RELATIVE_STD_WARN = 0.5


class EstimationError(ValueError):
    """The problem is ill-posed (unknown names, mismatched shapes, a diverging start)."""


class HorizonDivergedError(EstimationError):
    """A continuation step to a longer record diverged; ``last_ok_s`` is the longest span fitted without."""

    def __init__(self, message: str, last_ok_s: float) -> None:
        super().__init__(message)
        self.last_ok_s = last_ok_s


@dataclass(frozen=True)
class Manoeuvre:
    """One record at a fixed sample time: initial state x0 (nx), inputs u (N x nu), measured outputs y (N x ny).

    ``y[k]`` is the measurement at ``t0 + (k+1) dt_s``, after the input ``u[k]`` has acted for one step.
    """

    x0: np.ndarray
    u: np.ndarray
    y: np.ndarray
    dt_s: float
    name: str = ""


@dataclass(frozen=True)
class Iteration:
    cost: float
    step_norm: float
    damping: float


@dataclass
class Estimate:
    """Result: estimates, bounds, correlations, identifiability, convergence history.

    ``values``/``crb_std``/... cover the whole parameter vector: the ``n_global`` model parameters first, then
    the per-manoeuvre nuisance parameters (``m<j>.x0.<state>``, ``m<j>.bias.<output>``). ``std`` is the
    printed 1-sigma bound of each and ``bound_method`` says which it is (see :data:`BOUND_METHODS`).
    """

    names: list[str]
    values: np.ndarray
    crb_std: np.ndarray
    crb_std_white: np.ndarray
    correlation: np.ndarray
    residual_cov: np.ndarray
    history: list[Iteration] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    converged: bool = False
    n_global: int = -1
    bootstrap_std: np.ndarray | None = None
    bound_method: str = "cramer-rao-coloured"
    identifiability: Identifiability | None = None
    prior_sd: np.ndarray | None = None  #: a-priori std of each model parameter (inf: no prior)
    consider_cov: np.ndarray | None = None  #: covariance from parameters held fixed (consider covariance)
    considered: dict[str, float] = field(default_factory=dict)  #: fixed parameter -> the std it was given
    covariance: np.ndarray | None = None  #: covariance of the model parameters behind the printed bound
    n_segments: int = 0  #: manoeuvres the bootstrap resampled
    #: per model parameter, the degrees of freedom of the bootstrap spread (:func:`segment_corrections`); None:
    #: ``n_segments - 1``
    bootstrap_dof: np.ndarray | None = None
    #: per model parameter, the leverage factor the bootstrap variance was multiplied by (:func:`segment_corrections`)
    bootstrap_factor: np.ndarray | None = None
    #: manoeuvres whose output sensitivities exceed :data:`SENSITIVITY_GROWTH_MAX`: the fitted model diverges
    #: there, and the linearised bounds (Cramér-Rao, bootstrap, consider) are not credible
    unbounded: list[str] = field(default_factory=list)
    #: fewest bootstrap degrees of freedom for the bootstrap to enter a parameter's printed bound; below it the
    #: spread is itself too uncertain (its relative std is about 1/sqrt(2 dof)) and only the coloured Cramér-Rao
    #: bound is printed (0: the bootstrap always enters)
    bootstrap_min_dof: float = 0.0
    #: per fitted output, the order of its autoregressive residual model (bound "ar" only)
    ar_orders: list[int] | None = None
    #: per model parameter, the segments' scatter over the residual model's as a variance ratio and its degrees of
    #: freedom, pooled over the parameters (:func:`segment_scatter`); the small-sample test and bound of bound "ar"
    #: use it (None: each parameter's own bootstrap spread, the rule before 2026-11-29)
    scatter: tuple[np.ndarray, np.ndarray] | None = None
    #: consider covariance of the model parameters from the error of the given (logged) manoeuvre starts
    #: (:func:`start_consider_covariance`); it enters the data bound in quadrature and the small-sample test expects
    #: its share of the segments' scatter (:func:`data_bound`); None: the starts count as exact
    start_cov: np.ndarray | None = None
    #: per manoeuvre, the information and score of the model parameters at the estimate and the prior's
    #: information (:func:`segment_scatter`'s ``A, g, P``), kept so the scatter can be taken again with the
    #: start errors' share (:meth:`add_start`); None without the scatter
    segment_terms: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None
    #: :attr:`scatter` expects each segment's own start-error share (:meth:`add_start`)
    scatter_start: bool = False

    def __post_init__(self) -> None:
        if self.n_global < 0:
            self.n_global = len(self.names)

    @property
    def consider_std(self) -> np.ndarray | None:
        return None if self.consider_cov is None else np.sqrt(np.maximum(np.diag(self.consider_cov), 0.0))

    @property
    def std(self) -> np.ndarray:
        """The printed 1-sigma bound: the larger of the coloured-residual Cramér-Rao bound and the block
        bootstrap over manoeuvres scaled by :func:`student_factor` of its degrees of freedom (derivatives;
        nuisance parameters keep the Cramér-Rao bound), with the consider share of the parameters held fixed
        added in quadrature."""
        out = self.crb_std.copy()
        out[:self.n_global] = self.data_std
        if self.consider_std is not None:
            out[:self.n_global] = np.hypot(out[:self.n_global], self.consider_std)
        return out

    @property
    def data_std(self) -> np.ndarray:
        """The posterior std from the data and the prior (coloured Cramér-Rao or bootstrap), without the
        consider share of the parameters held fixed (:func:`data_bound`; with :attr:`bootstrap_min_dof`, the
        segment bootstrap enters only where it has that many degrees of freedom)."""
        out = data_bound(self.crb_std[:self.n_global], self.bootstrap_std, self.bootstrap_dof, self.n_segments,
                         self.bound_method, self.scatter, self.start_var, self.scatter_start)
        if self.bound_method == BOUND_METHODS[1]:
            out = np.where(self.bootstrap_in_bound(), out,
                           data_bound(self.crb_std[:self.n_global], None, None, 0, self.bound_method,
                                      None, self.start_var))
        return out

    def add_start(self, shifts: np.ndarray) -> None:
        """Put the errors of the manoeuvres' given starts into the bounds: ``shifts`` (m x n x n,
        :func:`start_consider_terms`) per manoeuvre the covariance of the estimate's shift its start error gives.
        Their sum is :attr:`start_cov`; with :attr:`segment_terms` the scatter is taken again expecting each
        segment's own share (:func:`segment_scatter`), else the small-sample test scales each parameter's ratio by
        its share (:func:`small_sample_needed`)."""
        shifts = np.asarray(shifts, float)
        total = shifts.sum(axis=0)
        self.start_cov = 0.5 * (total + total.T)
        if self.segment_terms is not None and self.scatter is not None and len(shifts) == len(self.segment_terms[0]):
            A, g, P = self.segment_terms
            self.scatter = segment_scatter(A, g, P, self.crb_std[:self.n_global], shifts)
            self.scatter_start = True

    @property
    def start_var(self) -> np.ndarray | None:
        """Per model parameter, the variance the start errors give it (:attr:`start_cov`), None without."""
        return None if self.start_cov is None else np.maximum(np.diag(self.start_cov), 0.0)

    def small_sample(self) -> list[str]:
        """Model parameters whose printed bound is the small-sample bound (bound "ar": the segments scatter
        more than the residual model explains, :func:`data_bound`)."""
        if self.bound_method != BOUND_METHODS[2] or self.bootstrap_std is None:
            return []
        use = small_sample_needed(self.crb_std[:self.n_global], self.bootstrap_std, self.bootstrap_dofs(),
                                  self.scatter, self.start_var, self.scatter_start)
        return [n for n, u in zip(self.names, use, strict=False) if u]

    def segment_scatter(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Per model parameter, the segments' scatter over the residual model's as a variance ratio and its degrees
        of freedom (:attr:`scatter`, else the parameter's own bootstrap spread; bound "ar" with a bootstrap only,
        else None)."""
        if self.bound_method != BOUND_METHODS[2] or self.bootstrap_std is None:
            return None
        return _scatter(self.crb_std[:self.n_global], self.bootstrap_std, self.bootstrap_dofs(), self.scatter)

    def segments_to_tighten(self) -> int:
        """Segments of the same kind that would bring Student's factor of the small-sample bound to
        :data:`TIGHT_STUDENT` for every parameter that has it (0: none has it)."""
        use = [self.names.index(n) for n in self.small_sample()]
        scatter = self.segment_scatter()
        if not use or scatter is None:
            return 0
        per_segment = float(np.min(scatter[1][use])) / max(self.n_segments, 1)
        return int(np.ceil(tight_dof() / max(per_segment, 1e-9)))

    def bootstrap_dofs(self) -> np.ndarray:
        """Per model parameter, the degrees of freedom of its bootstrap spread."""
        dof = self.bootstrap_dof if self.bootstrap_dof is not None else self.n_segments - 1.0
        return np.broadcast_to(np.asarray(dof, dtype=float), (self.n_global,))

    def bootstrap_in_bound(self) -> np.ndarray:
        """Per model parameter, whether the bootstrap enters the printed bound (it was computed and has at least
        :attr:`bootstrap_min_dof` degrees of freedom)."""
        if self.bootstrap_std is None or not self.bound_method.startswith("max("):
            return np.zeros(self.n_global, dtype=bool)
        return self.bootstrap_dofs() >= self.bootstrap_min_dof

    def dominance(self) -> list[str]:
        """Per model parameter: "fixed" when the consider share of the parameters held fixed exceeds the data's
        std; else "data" when the posterior std (data and prior, without the consider share) is below half the
        prior's, "prior" when above 0.8 of it, "data+prior" between, "data (no prior)" without a prior."""
        out = []
        std, cons = self.data_std, self.consider_std
        for i in range(self.n_global):
            sp = np.inf if self.prior_sd is None else self.prior_sd[i]
            if cons is not None and cons[i] > std[i]:
                out.append("fixed")  # the values held fixed move it more than the data pin it down
            elif not np.isfinite(sp):
                out.append("data (no prior)")
            else:
                ratio = std[i] / sp
                out.append("data" if ratio < 0.5 else "prior" if ratio > 0.8 else "data+prior")
        return out

    def prior_dominated(self) -> list[str]:
        """Model parameters that only the prior determines (posterior std above 0.8 of the prior's)."""
        return [n for n, d in zip(self.names, self.dominance(), strict=False) if d == "prior"]

    def not_data_dominated(self) -> list[str]:
        """Model parameters the prior determines alone or with the data (posterior std above half the
        prior's: the data carry at most three times the prior's information), or that the values held fixed
        (their priors) move more than the data pin them down."""
        return [n for n, d in zip(self.names, self.dominance(), strict=False)
                if d in ("prior", "data+prior", "fixed")]

    def covariance_printed(self) -> np.ndarray:
        """Covariance of the model parameters whose diagonal is the printed bound squared: the data's
        (coloured Cramér-Rao correlations, scaled up where the bootstrap is wider) plus the consider term."""
        data_std = self.data_std
        cov = np.diag(data_std ** 2) if self.covariance is None else (
            self.covariance if self.start_cov is None else self.covariance + self.start_cov)
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        scale = data_std / d
        out = cov * np.outer(scale, scale)
        return out + self.consider_cov if self.consider_cov is not None else out

    def derivatives(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names[:self.n_global], self.values[:self.n_global], strict=True)}

    def nuisance(self) -> dict[str, dict[str, float]]:
        return {n: {"value": float(v), "crb_std": float(s)} for n, v, s in
                zip(self.names[self.n_global:], self.values[self.n_global:], self.crb_std[self.n_global:],
                    strict=True)}

    def table(self) -> str:
        """The derivatives: value, printed bound, its method, the other bounds, correlation warnings."""
        boot = self.bootstrap_std if self.bootstrap_std is not None else np.full(self.n_global, np.nan)
        cons = self.consider_std if self.consider_std is not None else np.zeros(self.n_global)
        prior = self.prior_sd if self.prior_sd is not None else np.full(self.n_global, np.inf)
        rows = [f"{'parameter':<16} {'estimate':>11} {'95% interval':>23} {'bound(1s)':>9} {'CR col':>9} "
                f"{'CR white':>9} {'bootstrap':>9} {'consider':>9} {'prior sd':>9} {'%':>6}  {'determined by':<15} "
                "correlated with (|r| > 0.9)"]
        std, dom = self.std, self.dominance()
        for i in range(self.n_global):
            n, v = self.names[i], self.values[i]
            corr = [f"{self.names[k]} {self.correlation[i, k]:+.2f}" for k in range(len(self.names))
                    if k != i and abs(self.correlation[i, k]) > 0.9]
            ci = f"[{v - 1.96 * std[i]:.4g}, {v + 1.96 * std[i]:.4g}]"
            rows.append(f"{n:<16} {v:11.5g} {ci:>23} {std[i]:9.3g} {self.crb_std[i]:9.3g} "
                        f"{self.crb_std_white[i]:9.3g} {boot[i]:9.3g} {cons[i]:9.3g} {prior[i]:9.3g} "
                        f"{100 * std[i] / max(abs(v), 1e-12):6.1f}  {dom[i]:<15} {', '.join(corr) or '-'}")
        rows.append(f"bound: {self.bound_method}")
        small = self.small_sample()
        if small:
            how = ("the coloured bound x the segments' excess scatter, pooled over the parameters, x Student's t at "
                   "its degrees of freedom" if self.scatter is not None
                   else "bootstrap x Student's t at its degrees of freedom")
            rows.append(f"small-sample bound (the {self.n_segments} segments scatter more than the residual model "
                        f"explains: {how}) for {', '.join(small)}; "
                        f"about {self.segments_to_tighten()} segments like these would tighten it")
        if self.start_var is not None and np.any(self.start_var > 0.0):
            share = np.sqrt(self.start_var) / np.maximum(self.crb_std[:self.n_global], 1e-300)
            rows.append(f"start states read from the log: their noise enters the data bound in quadrature (its "
                        f"share over the coloured bound {share.min():.2g}-{share.max():.2g}), and the small-sample "
                        "test expects the scatter it brings")
        if len(self.names) > self.n_global:
            rows.append(f"{len(self.names) - self.n_global} nuisance parameters (initial states, biases) estimated "
                        "per manoeuvre: see 'nuisance' in the metrics JSON")
        return "\n".join(rows)

    def as_dict(self) -> dict[str, Any]:
        std = self.std
        boot = self.bootstrap_std
        scatter = self.segment_scatter()
        params = {}
        for i, n in enumerate(self.names[:self.n_global]):
            params[n] = {"value": float(self.values[i]), "std": float(std[i]), "bound_method": self.bound_method,
                         "crb_std": float(self.crb_std[i]), "crb_std_white": float(self.crb_std_white[i]),
                         "bootstrap_std": None if boot is None or not np.isfinite(boot[i]) else float(boot[i]),
                         "bootstrap_dof": None if boot is None or self.bootstrap_dof is None
                         else float(self.bootstrap_dof[i]),
                         "bootstrap_in_bound": bool(self.bootstrap_in_bound()[i]),
                         "segment_scatter_ratio": None if scatter is None or not np.isfinite(scatter[0][i])
                         else float(scatter[0][i]),
                         "segment_scatter_dof": None if scatter is None else float(scatter[1][i]),
                         "consider_std": None if self.consider_std is None else float(self.consider_std[i]),
                         "start_state_std": None if self.start_var is None else float(np.sqrt(self.start_var[i])),
                         "prior_sd": None if self.prior_sd is None or not np.isfinite(self.prior_sd[i])
                         else float(self.prior_sd[i]),
                         "determined_by": self.dominance()[i],
                         "ci95": [float(self.values[i] - 1.96 * std[i]), float(self.values[i] + 1.96 * std[i])]}
        return {
            "parameters": params,
            "nuisance": self.nuisance(),
            "bound_method": self.bound_method,
            "small_sample_bound": self.small_sample(),
            "segments_to_tighten": self.segments_to_tighten(),
            "ar_orders": self.ar_orders,
            "names": self.names,
            "correlation": np.round(self.correlation, 6).tolist(),
            "identifiability": self.identifiability.as_dict() if self.identifiability else None,
            "iterations": [vars(h) for h in self.history],
            "converged": self.converged,
            "warnings": self.warnings,
            "prior_dominated": self.prior_dominated(),
            "not_data_dominated": self.not_data_dominated(),
        }


#: how the printed bound is made (``Estimate.bound_method``)
#: bootstrap resamples per task of ``identification.common.parallel`` (fixed: the draws never depend on the worker
#: count)
BOOTSTRAP_CHUNK = 50


def bootstrap_task(task: dict[str, Any]) -> dict[str, Any]:
    """Resamples ``task["first"]..`` of the block bootstrap: manoeuvre weights from the task's own generator
    (``identification.common.parallel.task_rng``), one linearised Gauss-Newton step each with the information held
    at the full sample's, ``M⁻¹ (Σ w_j g_j + g_prior)`` with ``M = Σ A_j + P``; plain arrays in and out.

    The information is held fixed because the leverage factor and the degrees of freedom of
    :func:`segment_corrections` describe that linear statistic. Re-solving each resample with its own information
    ``Σ w_j A_j + P`` (until 2026-11-29) let a resample that drops one of the two segments carrying a parameter halve
    its information and double its step: on the excitation-log replica that spread came out 2.0-3.9 coloured
    Cramér-Rao std where the fixed-information one gave 1.4-2.4, matching its analytic value
    (``bench/aero_replica_bootstrap.py``)."""
    from identification.common.parallel import task_rng

    A, g, P, gp = (np.asarray(task[k], float) for k in ("A", "g", "P", "gp"))
    m = A.shape[0]
    Mi = np.linalg.pinv(A.sum(axis=0) + P, hermitian=True)
    rng = task_rng(task["seed"], task["index"])
    count = int(task["count"])
    picks = rng.integers(0, m, (count, m)) + m * np.arange(count)[:, None]  # the same draws as row by row
    w = np.bincount(picks.ravel(), minlength=count * m).reshape(count, m).astype(float)
    return {"reps": (w @ g + gp) @ Mi.T}


def bootstrap_repeats(A: np.ndarray, g: np.ndarray, P: np.ndarray, gp: np.ndarray, repeats: int, seed: int,
                      workers: int = 0, scheduler: str | None = None) -> np.ndarray:
    """``repeats`` bootstrap steps (rows) as tasks of ``identification.common.parallel``, in task order: in this
    process by
    default (a few hundred small solves do not repay a cluster start-up), the same bits on any cluster."""
    from identification.common.parallel import map_tasks

    firsts = range(0, repeats, BOOTSTRAP_CHUNK)
    tasks = [{"A": A, "g": g, "P": P, "gp": gp, "seed": seed, "index": i,
              "count": min(BOOTSTRAP_CHUNK, repeats - first)} for i, first in enumerate(firsts)]
    run = map_tasks(bootstrap_task, tasks, workers=workers, scheduler=scheduler, progress=False, desc="bootstrap")
    if run.failures:
        raise RuntimeError("bootstrap: " + "; ".join(run.failure_lines()))
    return np.concatenate([got["reps"] for _, got in run.results() if got is not None])


BOUND_METHODS = ("cramer-rao-coloured", "max(cramer-rao-coloured, segment-bootstrap x t(dof)/z)",
                 "cramer-rao-coloured-ar (small-sample bound where the segments scatter more)")
#: the bound an :class:`OutputErrorEstimator` prints: "bootstrap" (``BOUND_METHODS[0]`` or ``[1]``) or "ar"
#: (``BOUND_METHODS[2]``)
BOUNDS = ("bootstrap", "ar")
#: Student's factor t/z the small-sample bound would come down to with more segments (``segments_to_tighten``)
TIGHT_STUDENT = 1.1


def tight_dof() -> float:
    """Degrees of freedom at which :func:`student_factor` reaches :data:`TIGHT_STUDENT` (13.3)."""
    from scipy.optimize import brentq

    return float(brentq(lambda d: student_factor(d) - TIGHT_STUDENT, 1.0, 1e4))


def segment_scatter(A: np.ndarray, g: np.ndarray, P: np.ndarray | None, crb: np.ndarray,
                    start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per model parameter, how much more the segments scatter than the residual model explains, as a variance
    ratio (1: as the model says) with its degrees of freedom: ``(ratio, dof)``. ``A`` (m x n x n) and ``g``
    (m x n) are each segment's information and score at the estimate (nuisance profiled out), ``P`` the prior's
    information, ``crb`` the coloured Cramér-Rao std (1 sigma) of the residual model.

    Each parameter ``k``'s score in segment ``j``, ``s_kj = b_kᵀ g_j`` (``b_k = M⁻¹ e_k``), has under the working
    model of :func:`segment_corrections` the expectation ``E s_kj² = c_kk,jj`` times the residual model's scale
    ``crb_k² / b_kᵀ(Σ A)b_k``. Per segment, the ratios ``z_kj`` of ``s_kj²`` to it are pooled over the parameters
    into one excess ``κ_j = Σ_k π_kj² z_kj / Σ_k π_kj²`` (``π_kj``: segment ``j``'s share of parameter ``k``'s
    spread), and each parameter gets the mean of the segments' excesses weighted by its own shares,
    ``Σ_j π_ij κ_j``: a segment that scatters (a disturbance, a wrong start) widens every parameter it informs, in
    proportion to how much it informs it. That pooled ratio is then moderated with the parameter's own ratio
    ``Σ_j z_ij c_ii,jj / Σ_j c_ii,jj`` (its own leverage-corrected spread), each weighted by its degrees of freedom
    as Smyth's (2004) moderated variances: a parameter whose own segments scatter more than their other
    parameters' keeps part of that evidence. Every ratio here is a weighted sum of squared scores, so its degrees
    of freedom are Satterthwaite's for that quadratic form of Gaussian scores (their covariances ``c_kk',jl`` from
    :func:`segment_spread`): the correlation of parameters informed by the same segments, and of the own ratio
    with the pooled one, is counted.

    Why pooled: a parameter whose information sits in two segments has a spread of 1-2 degrees of freedom of its
    own, from which no excess can be told from chance (Student's factor 2-5; the small-sample bound of before
    widened such parameters 2-10 times on the excitation-log replica where the residual model was right), while
    the same two segments' scores of all parameters tell how much those segments scatter with many more.

    ``start`` (m x n x n, :func:`start_consider_terms`): per segment ``V_j``, the covariance of the estimate's shift
    its start's error gives. The start errors scatter the segments too, each its own: segment ``j``'s pull
    ``M⁻¹ ĝ_j`` carries ``(I - L_j) δ_j - L_j Σ_{l≠j} δ_l`` of them (``L_j = M⁻¹ A_j``, ``δ_j`` the shift of
    covariance ``V_j``), of variance ``e_kj = [V_j - L_j V_j - V_j L_jᵀ + L_j (Σ_l V_l) L_jᵀ]_kk``; each ``z_kj``
    is then divided by its expectation ``1 + e_kj / (c_kk,jj x scale_k)``, so a ratio of 1 means the segments
    scatter as the residual model and the start errors together say (one scale per parameter for all segments, the
    rule this replaced, read a segment with a noisy start as excess scatter and let a quiet one hide some)."""
    m, n = A.shape[0], A.shape[1]
    _, _, T = _score_covariances(A, P)
    if T is None:
        raise ValueError(f"segment_scatter: {m} segments x {n} parameters need {(m * n) ** 2:.3g} score "
                         f"covariances, more than SCORE_COV_MAX_ELEMENTS = {SCORE_COV_MAX_ELEMENTS:.3g}")
    Mi = np.linalg.pinv(A.sum(axis=0) + (np.zeros((n, n)) if P is None else P))
    E = np.einsum("jjkk->kj", T)  # (n, m): c_kk,jj
    total = E.sum(axis=1)
    crb = np.asarray(crb, float)
    ratio, dof = np.ones(n), np.full(n, max(m - 1.0, 1.0))
    ok = (total > 0.0) & (crb > 0.0) & np.isfinite(crb)
    if not ok.any():
        return ratio, dof
    S = A.sum(axis=0)
    true_var = np.einsum("ik,kl,li->i", Mi, S, Mi)  # bᵀ(Σ A)b
    share = np.where(ok[:, None], E / np.where(total > 0.0, total, 1.0)[:, None], 0.0)  # π_kj
    norm = np.sum(share ** 2, axis=0)  # Σ_k π_kj²
    gamma = np.where(norm > 0.0, share / np.where(norm > 0.0, norm, 1.0)[None, :], 0.0) \
        / np.where(total > 0.0, total, 1.0)[:, None]  # weights on s_kj² / scale_k
    scale = np.where(ok, crb ** 2 / np.where(true_var > 0.0, true_var, 1.0), 1.0)
    s2 = (g @ Mi) ** 2  # (m, n): s_kj²
    z = s2 / scale[None, :]  # (m, n): squared scores in units of the residual model's scale
    if start is not None:
        z = z / (1.0 + start_score_variance(A, Mi, start) / np.maximum(E.T * scale[None, :], 1e-300))
    # each parameter's weights w on z as one row, (k, j) flattened; the degrees of freedom of a weighted sum are
    # 1 / wᵀ Q w with Q[(k, j), (l, m)] = T[j, m, k, l]² (Satterthwaite, for Gaussian scores)
    Q = (T ** 2).transpose(2, 0, 3, 1).reshape(n * m, n * m)
    rows = np.flatnonzero(ok)
    pooled = (share[rows][:, None, :] * gamma[None]).reshape(len(rows), n * m)  # Σ_j π_ij κ_j
    own = np.zeros((len(rows), n, m))
    own[np.arange(len(rows)), rows] = (1.0 / total[rows])[:, None]  # own spread, Σ_j z_ji / Σ_j c_ii,jj
    own = own.reshape(len(rows), n * m)

    def inverse_variance(w: np.ndarray) -> np.ndarray:
        return 1.0 / np.maximum(np.einsum("ra,ab,rb->r", w, Q, w), 1e-12)

    d_pool, d_own = inverse_variance(pooled)[:, None], inverse_variance(own)[:, None]
    weights = (d_own * own + d_pool * pooled) / (d_own + d_pool)
    ratio[rows] = weights @ z.T.ravel()
    dof[rows] = np.maximum(inverse_variance(weights), 1.0)
    return ratio, dof


def start_score_variance(A: np.ndarray, Mi: np.ndarray, start: np.ndarray) -> np.ndarray:
    """(m, n): the variance the start errors give each segment's pull at the estimate, per model parameter,
    ``e_kj`` of :func:`segment_scatter` (``A`` the segments' information, ``Mi`` the inverse of their sum and the
    prior's, ``start`` the per-segment shift covariances ``V_j``)."""
    V = np.asarray(start, float)
    if V.shape != A.shape:
        raise ValueError(f"segment_scatter: start shifts of shape {V.shape} for segment information {A.shape}")
    L = np.einsum("ab,jbc->jac", Mi, A)  # L_j = M⁻¹ A_j
    LV = np.einsum("jab,jbc->jac", L, V)
    total = V.sum(axis=0)
    e = (np.einsum("jkk->jk", V) - 2.0 * np.einsum("jkk->jk", LV)
         + np.einsum("jka,ab,jkb->jk", L, total, L))
    return np.maximum(e, 0.0)


def small_sample_needed(crb: np.ndarray, boot: np.ndarray, dof: np.ndarray,
                        scatter: tuple[np.ndarray, np.ndarray] | None = None,
                        start_var: np.ndarray | None = None, start_in_scatter: bool = False) -> np.ndarray:
    """Per parameter: the segments scatter more than the residual model explains (record-to-record disturbances
    or mismatch), by more than the scatter's own sampling spread allows (one-sided 95 %: ``ratio > χ²_{0.95}(d) /
    d``), with ``ratio, d`` from ``scatter`` (:func:`segment_scatter`, pooled over the parameters) or, without it,
    ``boot² / crb²`` of the parameter alone at its bootstrap's degrees of freedom (the test before 2026-11-29).
    ``start_var`` (the variance the start errors give each parameter, :func:`start_consider_covariance`): the
    scatter expected is ``crb² + start_var``, not ``crb²`` (the start errors scatter the segments too, in about the
    proportion they move the estimate), so the ratio is taken over that; ``start_in_scatter``: ``scatter`` already
    expects each segment's own share (:func:`segment_scatter` with ``start``), and is taken as it is."""
    from scipy.stats import chi2

    ratio, d = _scatter(crb, boot, dof, scatter)
    if not (start_in_scatter and scatter is not None):
        ratio = ratio * _start_scale(crb, start_var)
    return ratio > chi2.ppf(0.95, d) / d


def _start_scale(crb: np.ndarray, start_var: np.ndarray | None) -> np.ndarray | float:
    """``crb² / (crb² + start_var)``: the scatter the residual model expects over the one it and the start errors
    expect (1 without ``start_var``)."""
    if start_var is None:
        return 1.0
    c2 = np.asarray(crb, float) ** 2
    return c2 / np.maximum(c2 + np.maximum(np.asarray(start_var, float), 0.0), 1e-300)


def _scatter(crb: np.ndarray, boot: np.ndarray, dof: np.ndarray,
             scatter: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """``scatter`` if given, else each parameter's own ``(boot² / crb², dof)``."""
    if scatter is not None:
        return np.asarray(scatter[0], float), np.maximum(np.asarray(scatter[1], float), 1.0)
    crb = np.asarray(crb, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(boot, float) ** 2 / crb ** 2
    return ratio, np.maximum(np.broadcast_to(np.asarray(dof, float), crb.shape), 1.0)


def data_bound(crb: np.ndarray, boot: np.ndarray | None, dof: np.ndarray | None, n_segments: int, method: str,
               scatter: tuple[np.ndarray, np.ndarray] | None = None,
               start_var: np.ndarray | None = None, start_in_scatter: bool = False) -> np.ndarray:
    """The data bound of the model parameters (1 sigma) by ``method`` (:data:`BOUND_METHODS`):

    - ``[0]``: the coloured Cramér-Rao std ``crb``;
    - ``[1]``: ``max(crb, boot x t(dof)/z)`` (the segment bootstrap over few segments, Student's factor);
    - ``[2]``: ``crb`` (with the AR residual model), and the small-sample bound ``crb x sqrt(ratio) x t(d)/z``
      only where :func:`small_sample_needed`, ``ratio, d`` from ``scatter`` (:func:`segment_scatter`); without
      it that is ``boot x t(dof)/z``, the bound before 2026-11-29.

    ``start_var`` (per parameter, the variance the errors of the given starts give it,
    :func:`start_consider_covariance`) adds to ``crb²`` in every method, and the small-sample test of ``[2]``
    expects its share of the scatter (:func:`small_sample_needed`); where that bound enters it already holds it
    (the scatter is measured, start errors and all). ``start_in_scatter``: ``scatter``'s ratio is over the scatter
    the residual model and each segment's start error expect (:func:`segment_scatter` with ``start``), so the
    small-sample bound is ``sqrt(crb² + start_var) x sqrt(ratio) x t(d)/z``.
    """
    out = np.asarray(crb, float).copy()
    base = out if start_var is None else np.sqrt(out ** 2 + np.maximum(np.asarray(start_var, float), 0.0))
    if boot is None or method == BOUND_METHODS[0]:
        return base
    d = np.broadcast_to(np.asarray(dof if dof is not None else n_segments - 1.0, float), out.shape)
    if method == BOUND_METHODS[2]:
        ratio, d_scatter = _scatter(out, boot, d, scatter)
        carried = start_in_scatter and scatter is not None
        with np.errstate(invalid="ignore"):
            wide = np.maximum(base, (base if carried else out) * np.sqrt(np.maximum(ratio, 0.0))
                              * student_factor(d_scatter))
        return np.where(small_sample_needed(out, boot, d, scatter, start_var, carried), wide, base)
    return np.maximum(base, boot * student_factor(d))


def student_factor(dof: float | np.ndarray) -> float | np.ndarray:
    """``t_{0.975, dof} / z_{0.975}``: a std estimated with ``dof`` degrees of freedom gives a 95 % interval
    of Student's width, not the normal one (2.36 / 1.96 = 1.21 for 7, 1.04 for 39); ``dof`` below 1 counts as 1."""
    from scipy.stats import norm, t

    out = t.ppf(0.975, np.maximum(dof, 1.0)) / norm.ppf(0.975)
    return float(out) if np.ndim(out) == 0 else out


def segment_corrections(A: np.ndarray, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Small-sample corrections of a spread over ``m`` segments, per model parameter (Bell & McCaffrey 2002;
    Imbens & Kolesár 2016, who compute them under a working model): ``A`` (m x n x n) is each segment's
    information, ``P`` the prior's (not resampled).

    Working model: segment ``j``'s score at the truth has covariance ``A_j``, so the true variance of the
    estimate is ``M⁻¹ (Σ A_j) M⁻¹`` with ``M = Σ A_j + P``. The spread over segments is made of scores at the
    estimate, ``ĝ_j = g_j - A_j M⁻¹ Σ_k g_k``, whose covariances are ``C_jl = δ_jl A_j - 2 A_j M⁻¹ A_l +
    A_j M⁻¹ (Σ A_k) M⁻¹ A_l``: a segment that carries a large share of a parameter's information (leverage)
    pulls the estimate towards itself and shows a smaller score. Returns

    - ``variance_factor``: true variance over the expected spread, ``bᵀ(Σ A_j)b / Σ_j c_jj`` with ``b = M⁻¹ e_i``
      and ``c_jl = bᵀ C_jl b``; ``m / (m - 1)`` for equal segments without prior;
    - ``dof``: Satterthwaite's degrees of freedom of that spread, ``(Σ_j c_jj)² / Σ_jl c_jl²`` (its variance
      for Gaussian scores is ``2 Σ_jl c_jl²``); ``m - 1`` for equal segments, fewer when a few segments carry
      the information.
    """
    factor, dof, _ = segment_spread(A, P)
    return factor, dof


def segment_spread(A: np.ndarray, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`segment_corrections` (``variance_factor``, ``dof``) and the covariances of the parameters' scores at
    the estimate under the same working model, ``T[j, l, i, k] = b_iᵀ C_jl b_k`` (segments j, l; parameters i,
    k): for Gaussian scores ``Cov(s_ij², s_kl²) = 2 T[j, l, i, k]²``, from which :func:`segment_scatter` takes the
    degrees of freedom of any weighted sum of the squared scores (None when it would hold more than
    :data:`SCORE_COV_MAX_ELEMENTS` values)."""
    return _score_covariances(A, P)


#: largest segment-score covariance array (m² n² float64 values, m segments, n parameters) formed: 4e6 (32 MB).
#: Beyond it the corrections are computed parameter by parameter (m² values each) and the pooled segment scatter
#: is not formed (:meth:`OutputErrorEstimator.segment_scatter` returns None: the per-parameter rule)
SCORE_COV_MAX_ELEMENTS = 4_000_000


def _score_covariances(A: np.ndarray, P: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    m, n = A.shape[0], A.shape[1]
    S = A.sum(axis=0)
    Mi = np.linalg.pinv(S + (np.zeros((n, n)) if P is None else P))
    if m * m * n * n > SCORE_COV_MAX_ELEMENTS:  # bounded before allocating: one parameter at a time
        factor, dof = np.ones(n), np.full(n, max(m - 1.0, 1.0))
        for i in range(n):
            b = Mi[:, i]
            a = A @ b  # (m, n): A_j b
            q = a @ Mi  # (m, n): (M⁻¹ A_j b)ᵀ
            C = q @ S @ q.T - 2.0 * q @ a.T
            C[np.diag_indices(m)] += a @ b
            spread = float(np.trace(C))
            if spread > 0.0:
                factor[i] = float(b @ S @ b) / spread
                dof[i] = spread ** 2 / float(np.sum(C ** 2))
        return factor, dof, None
    X = A @ Mi  # (m, n, n): column i of X_j is A_j b_i
    Y = np.einsum("ab,lbk->lak", Mi @ S @ Mi - 2.0 * Mi, X)
    T = np.tensordot(X, Y, axes=([1], [1])).transpose(0, 2, 1, 3)  # (j, l, i, k): b_iᵀ C_jl b_k
    T[np.arange(m), np.arange(m)] += np.einsum("ai,jak->jik", Mi, X)
    E = np.einsum("jjii->i", T)
    factor, dof = np.ones(n), np.full(n, max(m - 1.0, 1.0))
    ok = E > 0.0
    factor[ok] = np.diag(Mi @ S @ Mi)[ok] / E[ok]
    dof[ok] = E[ok] ** 2 / np.einsum("jlii->i", T ** 2)[ok]
    return factor, dof, T


#: largest credible output change per 100 % change of a model parameter, in units of the output's range over
#: the manoeuvre; beyond it the simulated trajectory runs away (tumbles, spirals) and the sensitivities, hence
#: every linearised bound, are meaningless. Measured: 3-13 on the coverage generator, 2.3-6.7 on the excitation
#: log; 1.3e3-5.4e3 and 1e28 on replica fits whose bounds came out 1e-4 and 1e-26 of the estimate
SENSITIVITY_GROWTH_MAX = 1e3


def sensitivity_growth(data: Sequence[Manoeuvre], jacs: Sequence[np.ndarray], theta: np.ndarray, n_global: int
                       ) -> list[float]:
    """Per manoeuvre: the largest ``|dy/dθ| |θ|`` over samples, outputs and model parameters, over that output's
    measured range (peak to peak)."""
    scale = np.maximum(np.abs(theta[:n_global]), 1e-6)
    out = []
    for m, J in zip(data, jacs, strict=True):
        span = np.maximum(np.ptp(m.y, axis=0), 1e-9)
        out.append(float(np.max(np.abs(J[:, :, :n_global]) * scale[None, None, :] / span[None, :, None])))
    return out


#: fewest manoeuvres for which the block bootstrap over manoeuvres is computed
BOOTSTRAP_MIN_SEGMENTS = 6


def correlation_lags(r: np.ndarray) -> int:
    """Lag window length for :func:`coloured_covariance`: twice the longest lag at which any output's residual
    autocorrelation is still above the 95 % band of white noise (2/sqrt(N)), at most N/2."""
    n = r.shape[0]
    size = 1 << (2 * n - 1).bit_length()
    rf = np.fft.rfft(r - r.mean(axis=0), n=size, axis=0)
    acf = np.fft.irfft(np.abs(rf) ** 2, n=size, axis=0)[:n]
    rho = acf / np.maximum(acf[0], 1e-300)
    below = np.abs(rho) < 2.0 / np.sqrt(n)
    first = [int(np.argmax(below[:, i])) if below[:, i].any() else n for i in range(r.shape[1])]
    return int(min(2 * max(first), n // 2))


def coloured_covariance(G: np.ndarray, r: np.ndarray, lags: int | None = None) -> np.ndarray:
    """One manoeuvre's middle term of Morelli & Klein's (1997) covariance for coloured residuals.

    ``G`` (N x ny x np) holds the weighted sensitivities ``W dy/dθ`` per sample, ``r`` (N x ny) the residuals.
    Returns ``Σ_i Σ_j G_iᵀ R(j-i) G_j`` with the residual autocorrelation ``R`` (biased estimate) tapered by a
    Bartlett window of ``lags`` lags (default :func:`correlation_lags`); the covariance is
    ``M⁻¹ (Σ over manoeuvres) M⁻¹``. The taper keeps the estimate positive semi-definite and stops the
    noisy far lags from shaking the bounds of white residuals. Evaluated in the frequency domain with the
    residual cross-spectrum: O(N log N) instead of O(N L) sums of np x np products.
    """
    n = r.shape[0]
    size = 1 << (2 * n - 1).bit_length()
    return _spectral_middle(G, _tapered_cross_spectrum(r, lags, size), size)


def _tapered_cross_spectrum(r: np.ndarray, lags: int | None, size: int) -> np.ndarray:
    """Cross-spectral density ``(F, ny, ny)`` on an FFT grid of ``size``: the biased autocorrelation
    ``R[τ] = E[r_t r_{t+τ}ᵀ]`` tapered by a Bartlett window of ``lags`` lags (default :func:`correlation_lags`)."""
    n = r.shape[0]
    lags = correlation_lags(r) if lags is None else int(lags)
    rf = np.fft.rfft(r, n=size, axis=0)  # (F, ny)
    R = np.fft.irfft(np.conj(rf)[:, :, None] * rf[:, None, :], n=size, axis=0) / n  # R[τ] = E[r_t r_{t+τ}ᵀ]
    tau = np.minimum(np.arange(size), size - np.arange(size))
    R *= np.clip(1.0 - tau / (lags + 1.0), 0.0, None)[:, None, None]
    return np.fft.rfft(R, axis=0)


def _spectral_middle(G: np.ndarray, P: np.ndarray, size: int) -> np.ndarray:
    """``Σ_i Σ_j G_iᵀ R(j-i) G_j`` from the residual cross-spectrum ``P`` on an FFT grid of ``size``."""
    Gf = np.fft.rfft(G, n=size, axis=0)  # (F, ny, np)
    w = np.full(P.shape[0], 2.0)  # rfft bins other than DC and Nyquist stand for a conjugate pair
    w[0] = 1.0
    if size % 2 == 0:
        w[-1] = 1.0
    S = np.einsum("f,fya,fyz,fzb->ab", w, Gf, P, np.conj(Gf), optimize=True).real / size
    return 0.5 * (S + S.T)



#: largest order of the autoregressive residual model of the AR-prewhitened bound, per output
AR_ORDER_MAX = 30


def ar_polynomial(records: Sequence[np.ndarray], order_max: int = AR_ORDER_MAX) -> np.ndarray:
    """Whitening filter ``[1, c_1, ..., c_p]`` (``e_t = x_t + Σ c_k x_{t-k}``) of an autoregressive model fitted to
    one signal's ``records`` together by Burg's method (forward and backward prediction errors summed over the
    records; always stable, and less biased towards zero than Yule-Walker on short records: over eight records
    of 400 samples of white + AR(1) noise of pole 0.9 it keeps 0.95 of the long-run variance, Yule-Walker 0.90),
    its order ``p <= order_max`` the one of least Akaike criterion ``n ln σ²_p + 2 p``."""
    f = [np.asarray(x, float).copy() for x in records]
    b = [x.copy() for x in f]
    n = sum(len(x) for x in f)
    a = np.ones(1)
    err = sum(float(x @ x) for x in f) / max(n, 1)
    if not err > 0.0:
        return a
    best, best_a = n * np.log(err), a
    for k in range(1, min(order_max, min(len(x) for x in f) - 1) + 1):
        num = sum(float(ff[k:] @ bb[k - 1:-1]) for ff, bb in zip(f, b, strict=True))
        den = sum(float(ff[k:] @ ff[k:] + bb[k - 1:-1] @ bb[k - 1:-1]) for ff, bb in zip(f, b, strict=True))
        if not den > 0.0:
            break
        refl = -2.0 * num / den
        for j, (ff, bb) in enumerate(zip(f, b, strict=True)):
            f[j], b[j] = np.r_[ff[:k], ff[k:] + refl * bb[k - 1:-1]], np.r_[bb[:k], bb[k - 1:-1] + refl * ff[k:]]
        a = np.r_[a, 0.0]
        a = a + refl * a[::-1]
        err *= 1.0 - refl * refl
        aic = n * np.log(max(err, 1e-300)) + 2.0 * k
        if aic < best:
            best, best_a = aic, a
    return best_a


def ar_polynomials(res: Sequence[np.ndarray], order_max: int = AR_ORDER_MAX) -> list[np.ndarray]:
    """Per output column of the records ``res`` (each N_j x ny): :func:`ar_polynomial` over all records (one
    sensor's residual shape; uncentred, as :func:`coloured_covariance`), at most a quarter of the shortest
    record's length in order."""
    order = max(min(order_max, min(r.shape[0] for r in res) // 4), 0)
    return [ar_polynomial([r[:, i] for r in res], order) for i in range(res[0].shape[1])]


def coloured_covariance_ar(G: np.ndarray, r: np.ndarray, polys: Sequence[np.ndarray]) -> np.ndarray:
    """:func:`coloured_covariance` with the residual spectrum from an autoregressive model per output
    (``polys`` from :func:`ar_polynomials`; prewhitening and recolouring, Andrews & Monahan 1992, with the AR
    order chosen by AIC instead of one lag): each output's residual passes its whitening filter, the cross-
    spectrum of the whitened residuals is estimated with the Bartlett taper (little correlation left for it
    to cut), then recoloured by the AR filters. The Bartlett taper alone keeps about 0.76 of the long-run
    variance of white + AR(1) residuals of pole 0.9 over 400 samples; the AR model keeps the slow part."""
    from scipy.signal import lfilter

    n = r.shape[0]
    size = 1 << (4 * n - 1).bit_length()  # room for the AR impulse responses' tails (no circular wrap)
    e = np.column_stack([lfilter(p, [1.0], r[:, i]) for i, p in enumerate(polys)])
    A = np.stack([np.fft.rfft(p, n=size) for p in polys], axis=1)  # (F, ny) whitening filters' responses
    P = _tapered_cross_spectrum(e, None, size) / (np.conj(A)[:, :, None] * A[:, None, :])
    return _spectral_middle(G, P, size)


#: most integration sub-steps per sample an estimator takes
SUBSTEPS_MAX = 64
#: largest ``2 pi fc h`` of a sensor filter of cut-off ``fc`` run at the sub-step ``h`` (:func:`filter_substeps`)
FILTER_STEP_RAD = 0.5


def filter_substeps(cutoff_hz: float, dt_s: float) -> int:
    """Sub-steps per sample of ``dt_s`` [s] for a model output filtered by a sensor low-pass of ``cutoff_hz``
    [Hz] (0: no filter, 1 sub-step): enough that ``2 pi fc h <= FILTER_STEP_RAD`` at the sub-step ``h``.

    Why: the sensor filter runs at the IMU rate on the continuous signal; discretised at the log step it sees the
    output only at the samples (:func:`sensor_lowpass` assumes it linear between them), and the curvature of the
    fastest mode between samples passes the filter. At 50 Hz with a 20 Hz gyro filter (``2 pi fc dt`` = 2.5) that
    biased the roll derivatives of a noise-free replica by +1.0 to +1.8 %; at 5 sub-steps (0.50), by 0.1 % or
    less (``bench/aero_chain_replica.py``, ``identification/aero/readme.md``)."""
    if not cutoff_hz > 0.0:
        return 1
    return int(min(max(np.ceil(2.0 * np.pi * cutoff_hz * dt_s / FILTER_STEP_RAD - 1e-9), 1), SUBSTEPS_MAX))


class _Steps:
    """One output-error problem's plain and sensitivity steps (compiled or not) and their maps over records of
    each length, shared by every estimator of the problem in a process (:func:`fmu_models.common.model.traced`).
    The maps are kept for the :data:`MAPS_MAX` record lengths used last; CasADi evaluates one function from
    several threads with a memory each."""

    MAPS_MAX = 256

    def __init__(self, plain: ca.Function, sens: ca.Function) -> None:
        self.plain, self.sens = plain, sens
        self._maps = BoundedCache(self.MAPS_MAX)

    def over_record(self, kind: str, n: int) -> ca.Function:
        """The ``kind`` ("plain" or "sensitivity") step accumulated over ``n`` samples: ``(x0, u (n columns), p,
        dt) -> (states, outputs)``, one column per step."""
        def make() -> ca.Function:
            step = self.plain if kind == "plain" else self.sens
            acc = step.mapaccum(f"{kind}_{n}_acc", n)
            # wrap so p and dt are single columns (mapaccum maps every non-accumulated input)
            sym = [ca.MX.sym(step.name_in(i), step.size1_in(i), n if i == 1 else 1) for i in range(4)]
            return ca.Function(f"{kind}_{n}", sym, acc(*sym))

        return self._maps.get((kind, n), make)


class OutputErrorEstimator:
    """Output-error problem for ``model``: free parameters ``free`` fitted to the outputs ``outputs``.

    ``estimate_states`` names states whose initial value is estimated per manoeuvre; ``estimate_biases``
    names outputs that get a constant bias per manoeuvre. ``constraints`` are predicates on the dict of
    free parameters; a trial step that breaks one, or makes the simulation diverge, is rejected.
    ``output_filters`` (output -> cut-off [Hz]) pass those outputs through the sensor low-pass before they meet
    the data; ``substeps`` integration steps per sample (default: :func:`filter_substeps`, 1 without filters).
    ``initial_sd`` (estimated state -> std, in the state's unit) treats each manoeuvre's given ``x0`` of those
    states as a measurement of the initial state: a prior at that value with that std enters the cost as the
    model parameters' priors do, so the state can take up the error of a noisy logged start but no more.
    ``compile``: the steps compiled to C (cached per problem; without a C compiler, the CasADi virtual machine on
    the steps with their common subexpressions eliminated); False: the virtual machine at once on the steps as
    built, for a few evaluations (a consider analysis, a dry run): eliminating the subexpressions costs as much as
    tens of simulated records and saves under a tenth of each (measured on the fixed wing's 12 derivatives).
    """

    def __init__(self, model: VehicleModel, p_nominal: Sequence[float], free: Sequence[str],
                 outputs: Sequence[str], bounds: dict[str, tuple[float, float]] | None = None,
                 constraints: Sequence[Callable[[dict[str, float]], bool]] = (),
                 estimate_states: Sequence[str] = (), estimate_biases: Sequence[str] = (),
                 compile: bool = True, prior: dict[str, tuple[float, float]] | None = None,
                 output_filters: dict[str, float] | None = None, bound: str = "bootstrap",
                 substeps: int | None = None, initial_sd: dict[str, float] | None = None) -> None:
        unknown = [f"parameter {n!r}" for n in free if n not in model.params.index]
        unknown += [f"output {n!r}" for n in outputs if n not in model.outputs.index]
        unknown += [f"state {n!r}" for n in estimate_states if n not in model.states.index]
        unknown += [f"biased output {n!r} (not among the fitted outputs)" for n in estimate_biases
                    if n not in outputs]
        unknown += [f"filtered output {n!r} (not among the fitted outputs, or a cut-off that is not > 0)"
                    for n, fc in (output_filters or {}).items() if n not in outputs or not fc > 0]
        unknown += [f"initial-state std of {n!r} = {sd!r} (not an estimated state, or not a finite std > 0)"
                    for n, sd in (initial_sd or {}).items()
                    if n not in estimate_states or not (np.isfinite(sd) and sd > 0)]
        if unknown:
            raise EstimationError(f"not known to the {model.name} model: {', '.join(unknown)}")
        if bound not in BOUNDS:
            raise EstimationError(f"bound {bound!r} is not one of {', '.join(BOUNDS)}")
        if substeps is not None and not 1 <= substeps <= SUBSTEPS_MAX:
            raise EstimationError(f"substeps {substeps} is not in 1..{SUBSTEPS_MAX}")
        #: integration sub-steps per sample (None: :func:`filter_substeps` of the output filters)
        self.substeps = substeps
        #: which bound is printed (:data:`BOUNDS`)
        self.bound = bound
        if len(set(free)) != len(free):
            raise EstimationError(f"free parameters listed twice: {sorted(n for n in free if list(free).count(n) > 1)}")
        bad_bounds = [n for n in (bounds or {}) if n not in free]
        if bad_bounds:
            raise EstimationError(f"bounds given for parameters that are not free: {', '.join(bad_bounds)}")
        self.model = model
        self.p_nominal = np.asarray(p_nominal, dtype=float)
        self.free = list(free)
        self.outputs = list(outputs)
        self.states_est = list(estimate_states)
        self.biases = list(estimate_biases)
        self.i_free = [model.params.index[n] for n in free]
        self.i_out = [model.outputs.index[n] for n in outputs]
        self.i_x0 = [model.states.index[n] for n in estimate_states]
        self.i_bias = [self.outputs.index(n) for n in estimate_biases]
        b = bounds or {}
        self.lower = np.array([b.get(n, (-np.inf, np.inf))[0] for n in free])
        self.upper = np.array([b.get(n, (-np.inf, np.inf))[1] for n in free])
        if np.any(self.lower > self.upper):
            raise EstimationError("a lower bound exceeds its upper bound")
        self.constraints = list(constraints)
        bad_prior = [n for n, (_, sd) in (prior or {}).items() if n not in free or not sd > 0]
        if bad_prior:
            raise EstimationError(f"priors need a free parameter and a positive std: {', '.join(bad_prior)}")
        pr = prior or {}
        self.prior_mean = np.array([pr.get(n, (0.0, np.inf))[0] for n in free], dtype=float)
        self.prior_sd = np.array([pr.get(n, (0.0, np.inf))[1] for n in free], dtype=float)
        #: per estimated initial state, the std of the manoeuvre's given x0 as its measurement (inf: none)
        self.initial_sd = dict(initial_sd or {})
        self.x0_prior_sd = np.array([self.initial_sd.get(n, np.inf) for n in self.states_est], dtype=float)
        self.state_limits = np.asarray(model.state_limits, dtype=float)
        #: sensor low-pass per output [Hz]: the model output passes the same filter before it meets the data
        self.output_filters = dict(output_filters or {})
        # traced once per process for a model structure, free set, estimated states and outputs (an analysis builds
        # estimators of one problem many times: refits, consider analyses, bootstrap)
        problem = (tuple(self.i_free), tuple(self.i_x0), tuple(self.i_out))
        plain = traced("oem_step", model, problem[2:], self._plain_step)

        def sensitivity(eliminate: bool) -> ca.Function:
            return traced("oem_sensitivity", model, (*problem, eliminate),
                          lambda: self._sensitivity_step(eliminate=eliminate))

        if compile:  # the library keyed by the function before its common subexpressions are eliminated (the
            # costly part); the loaded steps and their record maps kept per process like the functions: looking the
            # library up serializes both functions, and every estimator of a problem would map them again
            steps = traced("oem_compiled", model, (*problem, *jit_context()), lambda: _Steps(*compiled(
                [plain, sensitivity(False)], f"oem_{model.name}", build=lambda: [plain, sensitivity(True)])))
        else:
            steps = traced("oem_vm", model, problem, lambda: _Steps(plain, sensitivity(False)))
        self._steps = steps

    # ---------------------------------------------------------------- symbolic functions
    @property
    def n_local(self) -> int:
        """Per-manoeuvre parameters: estimated initial states, then output biases."""
        return len(self.i_x0) + len(self.i_bias)

    def prior_information(self, n_total: int) -> np.ndarray:
        """Diagonal a-priori information ``1/σ_p²`` over the full parameter vector (0 where no prior): the model
        parameters' priors, then per manoeuvre the initial states' (``initial_sd``)."""
        out = np.zeros(n_total)
        nth = len(self.free)
        out[:nth] = 1.0 / self.prior_sd ** 2
        if n_total > nth and self.n_local:
            local = np.concatenate([1.0 / self.x0_prior_sd ** 2, np.zeros(len(self.i_bias))])
            out[nth:] = np.tile(local, (n_total - nth) // self.n_local)
        return out

    def prior_mean_of(self, theta: np.ndarray, data: Sequence[Manoeuvre] | None) -> np.ndarray:
        """The prior's mean over the full parameter vector: the model parameters' prior means, each manoeuvre's
        given x0 for its estimated initial states; ``theta`` itself where there is no prior. ``data`` is needed
        when an initial state has a prior and ``theta`` holds the manoeuvres' parameters."""
        nth = len(self.free)
        mean = theta.astype(float).copy()
        mean[:nth] = np.where(np.isfinite(self.prior_sd), self.prior_mean, theta[:nth])
        if len(theta) > nth and np.any(np.isfinite(self.x0_prior_sd)):
            if data is None:
                raise EstimationError("an initial-state prior needs the manoeuvres (their given x0 is its mean)")
            nxe, has = len(self.i_x0), np.isfinite(self.x0_prior_sd)
            for j, m in enumerate(data):
                i = nth + j * self.n_local + np.arange(nxe)
                mean[i[has]] = np.asarray(m.x0, dtype=float)[self.i_x0][has]
        return mean

    def prior_cost(self, theta: np.ndarray, data: Sequence[Manoeuvre] | None = None) -> float:
        """``1/2 Σ ((θ - θ_p)/σ_p)²`` over the parameters that have a prior (``data``: see :meth:`prior_mean_of`)."""
        info = self.prior_information(len(theta))
        d = theta - self.prior_mean_of(theta, data)
        return 0.5 * float(np.sum(info * d * d))

    def _add_prior(self, M: np.ndarray, g: np.ndarray, theta: np.ndarray,
                   data: Sequence[Manoeuvre] | None = None) -> None:
        """Add the prior's information and gradient in place (Gauss-Newton normal equations)."""
        info = self.prior_information(len(theta))
        M[np.diag_indices_from(M)] += info
        g += info * (self.prior_mean_of(theta, data) - theta)

    def substeps_for(self, dt_s: float) -> int:
        """Integration sub-steps per sample of ``dt_s`` [s]: the given ``substeps``, else 1 without output filters
        and :func:`filter_substeps` of the fastest filter with them."""
        if self.substeps is not None:
            return self.substeps
        return filter_substeps(max(self.output_filters.values(), default=0.0), dt_s)

    def _plain_step(self) -> ca.Function:
        step = step_function(self.model)
        x, u = self.model.states.sym("x"), self.model.inputs.sym("u")
        p, dt = self.model.params.sym("p"), ca.SX.sym("dt")
        x1, y1 = step(x, u, p, dt)
        return ca.Function("oem_step", [x, u, p, dt], [x1, y1[self.i_out]])

    def _sensitivity_step(self, eliminate: bool = True) -> ca.Function:
        """``(xa, u, p, dt) -> (xa_next, [y; vec(dy/dθ)])`` with ``xa = [x; vec(S)]``, ``S = dx/dθ``; its common
        subexpressions eliminated unless ``eliminate`` is False (the same values; the key of its compiled library).

        θ is the free parameters followed by the estimated initial states (whose sensitivity enters only
        through ``S0``). RK4 on ``ẋ = f``, ``Ṡ = f_x S + f_θ`` with shared stages equals the Jacobian of the
        RK4 map, at a fraction of the cost of differentiating the composed step symbolically. The stages get the
        time since the step's start (0, dt/2, dt/2, dt) as ``rk4_step`` gives them to ``step_function``.
        """
        m = self.model
        nx, nth, ns = len(m.states), len(self.free), len(self.free) + len(self.i_x0)
        x, u = m.states.sym("x"), m.inputs.sym("u")
        p, dt = m.params.sym("p"), ca.SX.sym("dt")
        S = ca.SX.sym("S", nx, ns)
        th = ca.vertcat(*[p[i] for i in self.i_free]) if nth else ca.SX(0, 1)
        xs, ts = ca.SX.sym("xs", nx), ca.SX.sym("ts")
        fx = m.derivatives(ts, xs, u, p)  # ts: time since the step's start, as rk4_step passes it
        jac = ca.Function("fjac", [xs, u, p, ts], [fx, ca.jacobian(fx, xs), ca.jacobian(fx, th)])
        pad = ca.SX(nx, ns - nth)

        def stage(xx: Any, SS: Any, tt: Any) -> tuple[Any, Any]:
            k, A, B = jac(xx, u, p, tt)
            return k, A @ SS + ca.horzcat(B, pad)

        k1, K1 = stage(x, S, 0.0)
        k2, K2 = stage(x + dt / 2 * k1, S + dt / 2 * K1, dt / 2)
        k3, K3 = stage(x + dt / 2 * k2, S + dt / 2 * K2, dt / 2)
        k4, K4 = stage(x + dt * k3, S + dt * K3, dt)
        xr = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        Sr = S + dt / 6 * (K1 + 2 * K2 + 2 * K3 + K4)
        post = m.post_step(xs, u, p)
        post_f = ca.Function("post", [xs, u, p], [post, ca.jacobian(post, xs), ca.jacobian(post, th)])
        x1, Px, Pth = post_f(xr, u, p)
        S1 = Px @ Sr + ca.horzcat(Pth, pad)
        y = m.outputs_fn(xs, u, p)[self.i_out]
        out_f = ca.Function("out", [xs, u, p], [y, ca.jacobian(y, xs), ca.jacobian(y, th)])
        y1, Hx, Hth = out_f(x1, u, p)
        dy = Hx @ S1 + ca.horzcat(Hth, ca.SX(len(self.i_out), ns - nth))
        xa1, ya = ca.vertcat(x1, ca.vec(S1)), ca.vertcat(y1, ca.vec(dy))
        if eliminate:
            xa1, ya = ca.cse([xa1, ya])
        return ca.Function("oem_sens", [ca.vertcat(x, ca.vec(S)), u, p, dt], [xa1, ya])

    def _run(self, kind: str, xa0: np.ndarray, u: np.ndarray, p: np.ndarray, dt: float
             ) -> tuple[np.ndarray, np.ndarray]:
        """Evaluate the plain or sensitivity step over the record; returns states and outputs, one row per step.

        CasADi's buffer interface writes straight into numpy arrays: converting a DM result element by
        element costs more than the compiled simulation itself.
        """
        n = u.shape[0]
        f = self._steps.over_record(kind, n)
        # C-order (n, rows) arrays are CasADi's column-major (rows, n) matrices
        args = [np.ascontiguousarray(xa0, dtype=float), np.ascontiguousarray(u, dtype=float),
                np.ascontiguousarray(p, dtype=float), np.array([dt], dtype=float)]
        X = np.empty((n, f.size1_out(0)))
        Y = np.empty((n, f.size1_out(1)))
        buf, evaluate = f.buffer()
        for i, a in enumerate(args):
            buf.set_arg(i, memoryview(a))
        buf.set_res(0, memoryview(X))
        buf.set_res(1, memoryview(Y))
        evaluate()
        return X, Y

    # ---------------------------------------------------------------- simulation
    def names(self, data: Sequence[Manoeuvre]) -> list[str]:
        """Names of all estimated quantities, in the order of the parameter vector."""
        out = list(self.free)
        for j in range(len(data)):
            out += [f"m{j}.x0.{n}" for n in self.states_est]
            out += [f"m{j}.bias.{n}" for n in self.biases]
        return out

    def _split(self, theta: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Model parameters, x0 overrides and biases of manoeuvre ``j`` from the full vector."""
        nth, nl = len(self.free), self.n_local
        if len(theta) == nth:  # model parameters only: the manoeuvre's own x0, no biases
            return theta, np.empty(0), np.zeros(len(self.i_bias))
        local = theta[nth + j * nl: nth + (j + 1) * nl]
        return theta[:nth], local[:len(self.i_x0)], local[len(self.i_x0):]

    def _setup(self, theta: np.ndarray, j: int, m: Manoeuvre) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        glob, x0e, bias = self._split(theta, j)
        p = self.p_nominal.copy()
        p[self.i_free] = glob
        x0 = np.array(m.x0, dtype=float)
        if len(x0e):
            x0[self.i_x0] = x0e
        b = np.zeros(len(self.outputs))
        b[self.i_bias] = bias
        return p, x0, b

    def simulate(self, theta: np.ndarray, m: Manoeuvre, j: int = 0, sensitivities: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | None, bool]:
        """Outputs (N x ny), sensitivities (N x ny x n_global+n_local or None) and a divergence flag.

        Row k is the output after k+1 steps, matched to ``m.y[k]``. ``j`` is the manoeuvre's index in the
        parameter vector (selects its initial states and biases). With :meth:`substeps_for` ``> 1`` each sample
        step is that many RK4 steps with the sample's input held, and the output filters run at the sub-step.
        """
        n, ny = m.u.shape[0], len(self.outputs)
        nth, nxe = len(self.free), len(self.i_x0)
        p, x0, b = self._setup(theta, j, m)
        k = self.substeps_for(m.dt_s)
        u, h = (np.repeat(m.u, k, axis=0), m.dt_s / k) if k > 1 else (m.u, m.dt_s)
        if not sensitivities:
            X, Y = self._run("plain", x0, u, p, h)
            y = self._filtered(Y, h)[k - 1::k] + b
            return y, None, self._diverged(X[k - 1::k], y)
        nx = len(x0)
        S0 = np.zeros((nx, nth + nxe))
        S0[self.i_x0, nth + np.arange(nxe)] = 1.0
        Xa, out = self._run("sens", np.concatenate([x0, S0.ravel(order="F")]), u, p, h)
        # out: N k x (ny + ny*ns), dy/dθ column-major (ny x ns); filtered at the sub-step, then taken at the samples
        y = self._filtered(out[:, :ny], h)[k - 1::k] + b
        dy = self._filtered(out[:, ny:].reshape(n * k, nth + nxe, ny).transpose(0, 2, 1), h)[k - 1::k]
        jac = np.zeros((n, ny, nth + self.n_local))
        jac[:, :, :nth + nxe] = dy
        for q, i in enumerate(self.i_bias):
            jac[:, i, nth + nxe + q] = 1.0
        return y, jac, self._diverged(Xa[k - 1::k, :nx], y)

    def _filtered(self, y: np.ndarray, dt_s: float) -> np.ndarray:
        """``y`` (N x ny or N x ny x ns, time first) with each filtered output column through its sensor low-pass,
        started in steady state at its first sample (linear: the sensitivities pass the same filter)."""
        if not self.output_filters or not np.all(np.isfinite(y)):
            return y
        from scipy.signal import lfilter

        y = y.copy()
        for name, fc in self.output_filters.items():
            bz, az, zi = sensor_lowpass(fc, dt_s)
            i = self.outputs.index(name)
            col = y[:, i]
            y[:, i] = lfilter(bz, az, col, axis=0, zi=np.multiply.outer(zi, col[0]))[0]
        return y

    def _diverged(self, X: np.ndarray, y: np.ndarray) -> bool:
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
            return True
        return bool(np.any(np.abs(X) > self.state_limits))

    def _local_index(self, j: int) -> np.ndarray:
        """Columns of the full parameter vector that manoeuvre ``j``'s sensitivities fill."""
        nth, nl = len(self.free), self.n_local
        return np.concatenate([np.arange(nth), nth + j * nl + np.arange(nl)]).astype(int)

    # ---------------------------------------------------------------- estimation
    def estimate(self, data: Sequence[Manoeuvre], theta0: Sequence[float] | None = None,
                 weight: np.ndarray | None = None, max_iter: int = 30, tol: float = 1e-9,
                 progress: bool = False, horizon_s: float | None = None) -> Estimate:
        """Levenberg-Marquardt on the weighted output error; returns the estimate with its CR bounds.

        ``theta0`` covers the free parameters only (default: their nominal values) or the full vector.
        Initial states start from each manoeuvre's ``x0`` and biases from zero. ``horizon_s`` turns on
        continuation in record length: fit the first ``horizon_s`` seconds of every manoeuvre, then twice
        that, and so on up to the whole record. A start far from the truth makes long records strongly
        nonlinear in the parameters (slow modes drift apart); the short fits walk it into the basin first.
        """
        data = list(data)
        self._check(data, weight)
        names = self.names(data)
        theta = self._start(data, theta0)
        history: list[Iteration] = []
        n_max = max(m.u.shape[0] for m in data)
        horizons = []
        if horizon_s is not None:
            n_h = max(round(horizon_s / data[0].dt_s), 10)
            while n_h < n_max:
                horizons.append(n_h)
                n_h *= 2
        bar = tqdm(desc="output error", unit="it", disable=not progress, leave=False)
        last_ok = 0
        for n_h in horizons:
            short = [Manoeuvre(m.x0, m.u[:n_h], m.y[:n_h], m.dt_s, m.name) for m in data]
            bar.set_description(f"output error, first {n_h * data[0].dt_s:g} s")
            theta = self._horizon_step(short, theta, weight, max_iter, 1e-4, history, bar, last_ok, data[0].dt_s)[0]
            last_ok = n_h
        bar.set_description("output error")
        theta, res, jacs, W, converged = self._horizon_step(data, theta, weight, max_iter, tol, history, bar, last_ok,
                                                            data[0].dt_s)
        bar.close()
        return self._statistics(data, names, theta, res, jacs, W, history, converged)

    def _horizon_step(self, data: list[Manoeuvre], theta: np.ndarray, weight: np.ndarray | None, max_iter: int,
                      tol: float, history: list[Iteration], bar: tqdm, last_ok: int, dt_s: float,
                      ) -> tuple[np.ndarray, list[np.ndarray], list[Any], np.ndarray, bool]:
        """One continuation step; a divergence after a shorter span was fitted raises :class:`HorizonDivergedError`."""
        try:
            return self._solve(data, theta, weight, max_iter, tol, history, bar)
        except EstimationError as err:
            if last_ok == 0:
                raise
            n = max(m.u.shape[0] for m in data)
            raise HorizonDivergedError(f"the model fitted over the first {last_ok * dt_s:g} s diverges over "
                                  f"{n * dt_s:g} s ({err})", last_ok * dt_s) from None

    def _solve(self, data: list[Manoeuvre], theta: np.ndarray, weight: np.ndarray | None, max_iter: int,
               tol: float, history: list[Iteration], bar: tqdm) -> tuple[np.ndarray, list[np.ndarray],
                                                                          list[Any], np.ndarray, bool]:
        """The LM iterations on one set of records; appends to ``history``."""
        sims = [self.simulate(theta, m, j) for j, m in enumerate(data)]
        if any(s[2] for s in sims):
            raise EstimationError("the model diverges at the start values: start closer or fix more parameters")
        res, jacs, W, cost = _linearised(data, sims, weight)
        cost += self.prior_cost(theta, data)
        lam = 1e-3
        converged = False
        n_extra = len(theta) - len(self.free)
        bounds = (np.concatenate([self.lower, np.full(n_extra, -np.inf)]),
                  np.concatenate([self.upper, np.full(n_extra, np.inf)]))
        for _ in range(max_iter):
            M, g = self._normal_equations(res, jacs, W, len(theta))
            self._add_prior(M, g, theta, data)
            trial, cost_t, lam = self._damped_step(data, theta, M, g, W, cost, lam, bounds)
            if trial is None:
                converged = True  # no descent direction left at machine precision: a minimum
                break
            rel = (cost - cost_t) / max(cost, 1e-300)
            step_norm = float(np.linalg.norm(trial - theta) / max(np.linalg.norm(theta), 1e-12))
            theta = trial
            sims = [self.simulate(theta, m, j) for j, m in enumerate(data)]
            # with ML weighting the new cost is N*ny/2 by construction: report the fitted cost
            res, jacs, W, cost = _linearised(data, sims, weight)
            cost += self.prior_cost(theta, data)
            history.append(Iteration(cost_t, step_norm, lam))
            log.info("iteration %d: cost %.6g, relative step %.3g, damping %.1e", len(history), cost_t, step_norm, lam)
            bar.update(1)
            bar.set_postfix(cost=f"{cost_t:.6g}", step=f"{step_norm:.2g}", damping=f"{lam:.0e}")
            lam = max(lam / 10.0, 1e-9)
            # cost settled, or parameters settled (flat valleys of unidentifiable sets crawl on otherwise)
            if rel < tol or step_norm < 1e-8:
                converged = True
                break
        return theta, res, jacs, W, converged

    def _damped_step(self, data: list[Manoeuvre], theta: np.ndarray, M: np.ndarray, g: np.ndarray, W: np.ndarray,
                     cost: float, lam: float, bounds: tuple[np.ndarray, np.ndarray],
                     ) -> tuple[np.ndarray | None, float, float]:
        """Raise the damping ``lam`` tenfold until a bounded, constraint-keeping, non-diverging step lowers the
        cost; returns (trial parameters, their cost, lam), or (None, nan, lam) when none does below 1e12."""
        scale = np.maximum(np.diag(M), 1e-12 * max(np.max(np.diag(M)), 1e-300))
        while lam < 1e12:
            step = np.linalg.solve(M + lam * np.diag(scale), g)
            trial = np.clip(theta + step, *bounds)
            named = dict(zip(self.free, trial[:len(self.free)], strict=True))
            if all(c(named) for c in self.constraints):
                plain = [self.simulate(trial, m, j, sensitivities=False) for j, m in enumerate(data)]
                if not any(s[2] for s in plain):
                    cost_t = _cost([m.y - s[0] for m, s in zip(data, plain, strict=True)], W) + \
                        self.prior_cost(trial, data)
                    if cost_t <= cost:
                        return trial, cost_t, lam
            lam *= 10.0
        return None, float("nan"), lam

    def _check(self, data: list[Manoeuvre], weight: np.ndarray | None) -> None:
        if not data:
            raise EstimationError("no manoeuvres given")
        nu, ny, nx = len(self.model.inputs), len(self.outputs), len(self.model.states)
        for j, m in enumerate(data):
            label = m.name or f"manoeuvre {j}"
            if m.u.ndim != 2 or m.u.shape[1] != nu:
                raise EstimationError(f"{label}: inputs must be N x {nu}, got {m.u.shape}")
            if m.y.shape != (m.u.shape[0], ny):
                raise EstimationError(f"{label}: outputs must be {m.u.shape[0]} x {ny}, got {m.y.shape}")
            if np.shape(m.x0) != (nx,):
                raise EstimationError(f"{label}: x0 must have {nx} states, got {np.shape(m.x0)}")
            if not (np.all(np.isfinite(m.u)) and np.all(np.isfinite(m.y))):
                raise EstimationError(f"{label}: inputs or outputs contain NaN or inf")
            if not m.dt_s > 0:
                raise EstimationError(f"{label}: sample time {m.dt_s} s must be positive")
        if weight is not None and np.shape(weight) != (ny, ny):
            raise EstimationError(f"weight matrix must be {ny} x {ny}, got {np.shape(weight)}")

    def _start(self, data: list[Manoeuvre], theta0: Sequence[float] | None) -> np.ndarray:
        n_total = len(self.free) + len(data) * self.n_local
        if theta0 is not None and len(theta0) == n_total:
            return np.array(theta0, dtype=float)
        glob = np.array(theta0 if theta0 is not None else self.p_nominal[self.i_free], dtype=float)
        if glob.shape != (len(self.free),):
            raise EstimationError(f"theta0 must have {len(self.free)} or {n_total} entries, got {glob.shape}")
        local = [np.concatenate([np.asarray(m.x0, dtype=float)[self.i_x0], np.zeros(len(self.i_bias))])
                 for m in data]
        return np.concatenate([glob, *local]) if local else glob

    def _normal_equations(self, res: list[np.ndarray], jacs: list[Any], W: np.ndarray,
                          n_total: int) -> tuple[np.ndarray, np.ndarray]:
        M = np.zeros((n_total, n_total))
        g = np.zeros(n_total)
        L = np.linalg.cholesky(W).T  # W = Lᵀ L: whiten, then one BLAS product per manoeuvre
        for j, (r, J) in enumerate(zip(res, jacs, strict=True)):
            idx = self._local_index(j)
            Jw = np.matmul(L, J).reshape(-1, J.shape[2])
            M[np.ix_(idx, idx)] += Jw.T @ Jw
            g[idx] += Jw.T @ (r @ L.T).ravel()
        return M, g

    def _segment_terms(self, res: list[np.ndarray], jacs: list[Any], W: np.ndarray,
                       theta: np.ndarray | None = None, data: Sequence[Manoeuvre] | None = None
                       ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per manoeuvre, the information ``A_j`` and gradient ``g_j`` of the model parameters with that
        manoeuvre's nuisance parameters profiled out (Schur complement); its initial states' prior
        (``initial_sd``) belongs to the manoeuvre and enters its nuisance block (its gradient with ``theta`` and
        ``data``)."""
        L = np.linalg.cholesky(W).T
        ng, out = len(self.free), []
        n_total = ng + len(res) * self.n_local
        info = self.prior_information(n_total)
        d = self.prior_mean_of(theta, data) - theta if theta is not None and len(theta) == n_total \
            else np.zeros(n_total)
        for j, (r, J) in enumerate(zip(res, jacs, strict=True)):
            Jw = np.matmul(L, J).reshape(-1, J.shape[2])
            M = Jw.T @ Jw
            g = Jw.T @ (r @ L.T).ravel()
            loc = self._local_index(j)[ng:]
            M[ng:, ng:][np.diag_indices(len(loc))] += info[loc]
            g[ng:] += info[loc] * d[loc]
            if M.shape[0] > ng:
                K = M[:ng, ng:] @ np.linalg.pinv(M[ng:, ng:])
                out.append((M[:ng, :ng] - K @ M[ng:, :ng], g[:ng] - K @ g[ng:]))
            else:
                out.append((M, g))
        return out

    def segment_bootstrap_std(self, res: list[np.ndarray], jacs: list[Any], W: np.ndarray, repeats: int = 400,
                              seed: int = 0, theta: np.ndarray | None = None,
                              data: Sequence[Manoeuvre] | None = None
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Block bootstrap over manoeuvres (one linearised Gauss-Newton step per resample from the estimate with
        the information held at the full sample's, Hu & Kalbfleisch's estimating-function bootstrap): (std,
        variance factor, degrees of freedom) of the model parameters, or None with fewer than
        :data:`BOOTSTRAP_MIN_SEGMENTS` manoeuvres (too few distinct resamples). Whole manoeuvres are resampled, so
        coloured noise, per-record disturbances and model mismatch that vary from record to record show in the
        spread. The std is corrected for the segments' leverage (times the square root of the factor) and the
        degrees of freedom follow from how the information is shared among them (:func:`segment_corrections`)."""
        m = len(res)
        if m < BOOTSTRAP_MIN_SEGMENTS or not self.free:
            return None
        terms = self._segment_terms(res, jacs, W, theta, data)
        A = np.stack([t[0] for t in terms])
        g = np.stack([t[1] for t in terms])
        ng = len(self.free)
        P = np.diag(self.prior_information(ng))  # the prior is not resampled: it is not data
        gp = P @ (self.prior_mean - theta[:ng]) if theta is not None else np.zeros(ng)
        reps = bootstrap_repeats(A, g, P, gp, repeats, seed)
        # the plain std: with the information held fixed no resample takes a wild step (the interquartile range
        # / 1.349 was used while each resample re-solved with its own information), and the variance is the
        # statistic whose expectation segment_corrections describes
        factor, dof = segment_corrections(A, P)
        return np.std(np.array(reps), axis=0) * np.sqrt(factor), factor, dof

    def segment_scatter_terms(self, res: list[np.ndarray], jacs: list[Any], W: np.ndarray, theta: np.ndarray,
                              data: Sequence[Manoeuvre] | None = None
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """:func:`segment_scatter`'s ``A, g, P`` of the model parameters at ``theta`` (None with fewer than
        :data:`BOOTSTRAP_MIN_SEGMENTS` manoeuvres, as the bootstrap, or more score covariances than
        :data:`SCORE_COV_MAX_ELEMENTS`)."""
        if len(res) < BOOTSTRAP_MIN_SEGMENTS or not self.free:
            return None
        ng = len(self.free)
        if (len(res) * ng) ** 2 > SCORE_COV_MAX_ELEMENTS:
            return None
        terms = self._segment_terms(res, jacs, W, theta, data)
        return (np.stack([t[0] for t in terms]), np.stack([t[1] for t in terms]),
                np.diag(self.prior_information(ng)))

    def information(self, data: Sequence[Manoeuvre], theta: np.ndarray | None = None,
                    weight: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
        """Information matrix ``M`` of all estimated quantities at ``theta`` (default: the start), with the
        given weighting or the inverse residual variance; for identifiability before the solve."""
        data = list(data)
        self._check(data, weight)
        th = self._start(data, theta)
        sims = [self.simulate(th, m, j) for j, m in enumerate(data)]
        res = [m.y - s[0] for m, s in zip(data, sims, strict=True)]
        if weight is None:
            var = np.mean(np.vstack(res) ** 2, axis=0)
            weight = np.diag(1.0 / np.maximum(var, 1e-300))
        M, _ = self._normal_equations(res, [s[1] for s in sims], np.asarray(weight, float), len(th))
        return M, self.names(data)

    def identifiability(self, data: Sequence[Manoeuvre], theta: np.ndarray | None = None,
                        weight: np.ndarray | None = None) -> Identifiability:
        """Condition number, correlated pairs, input excitation and advice before the solve."""
        M, names = self.information(data, theta, weight)
        exc = input_excitation([m.u for m in data], list(self.model.inputs.index))
        return analyse(M, names, len(self.free), exc)

    def _statistics(self, data: list[Manoeuvre], names: list[str], theta: np.ndarray, res: list[np.ndarray],
                    jacs: list[Any], W: np.ndarray, history: list[Iteration], converged: bool) -> Estimate:
        """Cramér-Rao bounds (white and coloured-residual), block bootstrap, correlations, identifiability."""
        n_total = len(theta)
        M, _ = self._normal_equations(res, jacs, W, n_total)
        prior_info = self.prior_information(n_total)
        M_inv = scaled_pinv(M + np.diag(prior_info))
        std_white = np.sqrt(np.maximum(np.diag(M_inv), 0.0))
        middle = np.diag(prior_info)  # sandwich: the prior's information beside the data's coloured term
        polys = ar_polynomials(res) if self.bound == "ar" else None
        for j, (r, J) in enumerate(zip(res, jacs, strict=True)):
            idx = self._local_index(j)
            G = np.einsum("ij,kia->kja", W, J)
            middle[np.ix_(idx, idx)] += coloured_covariance(G, r) if polys is None else \
                coloured_covariance_ar(G, r, polys)
        cov = M_inv @ middle @ M_inv
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = correlation(cov)  # zero-variance entries give 0 correlation, never NaN
        got = self.segment_bootstrap_std(res, jacs, W, theta=theta, data=data)
        boot, factor, dof = got if got is not None else (None, None, None)
        terms = (self.segment_scatter_terms(res, jacs, W, theta, data)
                 if polys is not None and got is not None else None)
        scatter = None if terms is None else segment_scatter(*terms, std[:len(self.free)])
        method = BOUND_METHODS[2] if polys is not None else BOUND_METHODS[1] if boot is not None else BOUND_METHODS[0]
        exc = input_excitation([m.u for m in data], list(self.model.inputs.index))
        ident = analyse(M + np.diag(prior_info), names, len(self.free), exc, cov=cov)
        printed = std.copy()
        printed[:len(self.free)] = data_bound(std[:len(self.free)], boot, dof, len(data), method, scatter)
        warnings = []
        for i, n in enumerate(names[:len(self.free)]):
            if printed[i] > RELATIVE_STD_WARN * abs(theta[i]):
                warnings.append(f"{n}: std {printed[i]:.3g} exceeds {RELATIVE_STD_WARN:.0%} of the estimate "
                                f"{theta[i]:.4g} - the data hardly identify it")
            for k in range(i + 1, n_total):
                if abs(corr[i, k]) > CORRELATION_WARN:
                    warnings.append(f"{n} and {names[k]} are correlated ({corr[i, k]:+.3f}): the data cannot "
                                    "separate them")
        growth = sensitivity_growth(data, jacs, theta, len(self.free))
        unbounded = [m.name or f"manoeuvre {j}" for j, (m, g) in enumerate(zip(data, growth, strict=True))
                     if not g <= SENSITIVITY_GROWTH_MAX]
        if unbounded:
            warnings.append(f"the fitted model runs away in {', '.join(unbounded)} (output sensitivities up to "
                            f"{max(growth):.1e} x the measured range): its bounds are not credible")
        warnings += [a for a in ident.advice if a not in warnings]
        for w in warnings:
            log.info(w)  # the caller prints Estimate.warnings once (several fits run per identify call)
        resid_cov = np.cov(np.vstack(res).T, bias=True).reshape(len(self.outputs), len(self.outputs))
        ng = len(self.free)
        return Estimate(names, theta, std, std_white, corr, resid_cov, history, warnings, converged,
                        n_global=ng, bootstrap_std=boot, bound_method=method, identifiability=ident,
                        prior_sd=self.prior_sd.copy(), covariance=cov[:ng, :ng].copy(), n_segments=len(data),
                        bootstrap_dof=dof, bootstrap_factor=factor, unbounded=unbounded,
                        ar_orders=None if polys is None else [len(q) - 1 for q in polys],
                        scatter=scatter, segment_terms=terms)


def scaled_pinv(M: np.ndarray) -> np.ndarray:
    """Pseudo-inverse of a symmetric information matrix after scaling it to unit diagonal: the same matrix for a
    well-posed ``M``, but parameters of very different magnitude (a fan torque constant of 1e-7 N m s^2 beside an
    inertia of 1e-2 kg m^2) no longer push the small singular values of the scaled-out ones below ``pinv``'s
    cut-off, where their variance would come out as 0."""
    d = np.sqrt(np.maximum(np.diag(M), 0.0))
    d = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0)
    return d[:, None] * np.linalg.pinv(d[:, None] * M * d[None, :], hermitian=True) * d[None, :]


def _cost(res: list[np.ndarray], W: np.ndarray) -> float:
    """Output-error cost ``1/2 sum_k r_k^T W r_k`` over every record's residuals."""
    return 0.5 * sum(float(np.sum((r @ W) * r)) for r in res)


def _linearised(data: list[Manoeuvre], sims: list[Any], weight: np.ndarray | None,
                ) -> tuple[list[np.ndarray], list[Any], np.ndarray, float]:
    """Residuals, output sensitivities, weighting (``weight``, else maximum likelihood 1/variance) and cost."""
    res = [m.y - s[0] for m, s in zip(data, sims, strict=True)]
    if weight is not None:
        W = np.asarray(weight, dtype=float)
    else:
        W = np.diag(1.0 / np.maximum(np.mean(np.vstack(res) ** 2, axis=0), 1e-300))
    return res, [s[1] for s in sims], W, _cost(res, W)


@dataclass
class Consider:
    """Parameters held fixed and what their uncertainty does to the estimate (see :func:`consider_covariance`)."""

    names: list[str]
    sd: np.ndarray  #: the std each fixed parameter was given
    cov: np.ndarray  #: consider covariance of the model parameters (n_global x n_global)
    influence: np.ndarray  #: ``A``: shift of each model parameter per unit error of each fixed one
    informed: np.ndarray  #: posterior std / given std of each fixed parameter were it freed (1: data silent)


def sensor_lowpass(cutoff_hz: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A sensor's 2-pole Butterworth low-pass (ArduPilot's ``LowPassFilter2p`` on gyro and accelerometer, PX4's
    ``IMU_GYRO_CUTOFF``/``IMU_ACCEL_CUTOFF``; both run it at the IMU rate, far above the log rate), seen at the
    samples ``dt_s`` apart: the continuous filter ``ωc² / (s² + √2 ωc s + ωc²)`` discretised exactly for an input
    linear between samples (first-order hold). Returns ``(b, a, zi)`` for ``scipy.signal.lfilter``, ``zi`` the
    steady state for a unit input. Cached: the conversion costs about 20 ms (a matrix exponential), more than a
    whole simulated record, and every simulation of a filtered output asks for it."""
    return tuple(x.copy() for x in _sensor_lowpass(float(cutoff_hz), float(dt_s)))  # type: ignore[return-value]


@functools.lru_cache(maxsize=64)
def _sensor_lowpass(cutoff_hz: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from scipy.signal import cont2discrete, lfilter_zi

    w = 2 * np.pi * cutoff_hz
    num, den, _ = cont2discrete(([w * w], [1.0, np.sqrt(2.0) * w, w * w]), dt_s, method="foh")
    bz, az = np.asarray(num, float).ravel(), np.asarray(den, float).ravel()
    bz = bz * az.sum() / bz.sum()  # unit DC gain exactly
    return bz, az, lfilter_zi(bz, az)


def _widened(oe: OutputErrorEstimator, p: np.ndarray, free: list[str], states: list[str],
             compile: bool) -> OutputErrorEstimator:
    """``oe``'s problem (outputs, biases, filters, bound, sub-steps, initial-state priors) with ``free`` model
    parameters and ``states`` estimated per manoeuvre, at the nominal values ``p``: the consider analyses' wider
    problem, whose sensitivities give the shift per unit error of what ``oe`` holds fixed."""
    return OutputErrorEstimator(oe.model, p, free, oe.outputs, estimate_states=states, estimate_biases=oe.biases,
                                compile=compile, output_filters=oe.output_filters, bound=oe.bound,
                                substeps=oe.substeps, initial_sd=oe.initial_sd)


def consider_covariance(oe: OutputErrorEstimator, est: Estimate, data: Sequence[Manoeuvre],
                        consider: dict[str, float], weight: np.ndarray | None = None, compile: bool = False
                        ) -> Consider:
    """Consider covariance of the model parameters from parameters held fixed at values known to ``consider``
    (name -> std) only (Tapley, Schutz & Born 2004, sec. 6.3; Bierman 1977): with ``A = M_θθ⁻¹ M_θc``, the
    linearised shift of the estimate per unit error of the fixed parameters, the covariance is
    ``A diag(σ_c²) Aᵀ``. ``informed`` is each fixed parameter's std, were all of them freed with their std as
    a prior, over that std (white-residual information): below ~0.5 the data could estimate it. ``compile``:
    compile the sensitivity step to C (worth it when the same sets recur, as in a Monte Carlo study)."""
    names = [n for n in consider if n not in oe.free]
    ng = len(oe.free)
    if not names:
        return Consider([], np.zeros(0), np.zeros((ng, ng)), np.zeros((ng, 0)), np.zeros(0))
    p = oe.p_nominal.copy()
    p[oe.i_free] = est.values[:ng]
    # one pass with sensitivities: by default CasADi's virtual machine, not a C compile of a function used once
    big = _widened(oe, p, oe.free + names, oe.states_est, compile)
    nc = len(names)
    theta = np.concatenate([est.values[:ng], p[big.i_free[ng:]], est.values[ng:]])
    sims = [big.simulate(theta, m, j) for j, m in enumerate(data)]
    if any(s[2] for s in sims):
        raise EstimationError("consider covariance: the model diverges at the estimate")
    res, jacs, W, _ = _linearised(list(data), sims, weight)
    M, _ = big._normal_equations(res, jacs, W, len(theta))
    keep = np.r_[np.arange(ng), ng + nc + np.arange(len(theta) - ng - nc)].astype(int)
    cons = ng + np.arange(nc)
    Mtt = M[np.ix_(keep, keep)] + np.diag(oe.prior_information(len(keep)))
    A = np.linalg.lstsq(Mtt, M[np.ix_(keep, cons)], rcond=None)[0][:ng]
    sd = np.array([consider[n] for n in names])
    info = np.zeros(len(theta))
    info[keep] = oe.prior_information(len(keep))
    info[cons] = 1.0 / sd ** 2
    aug = scaled_pinv(M + np.diag(info))
    informed = np.sqrt(np.maximum(np.diag(aug)[cons], 0.0)) / sd
    return Consider(names, sd, (A * sd ** 2) @ A.T, A, informed)



def start_consider_covariance(oe: OutputErrorEstimator, est: Estimate, data: Sequence[Manoeuvre],
                              x0_cov: Sequence[np.ndarray], weight: np.ndarray | None = None) -> np.ndarray:
    """The sum over manoeuvres of :func:`start_consider_terms`: the consider covariance of the model parameters
    (n_global x n_global) from the errors of the manoeuvres' given starts."""
    total = start_consider_terms(oe, est, data, x0_cov, weight).sum(axis=0)
    return 0.5 * (total + total.T)


def start_consider_terms(oe: OutputErrorEstimator, est: Estimate, data: Sequence[Manoeuvre],
                         x0_cov: Sequence[np.ndarray], weight: np.ndarray | None = None) -> np.ndarray:
    """Per manoeuvre (m x n_global x n_global), the covariance of the model parameters' shift from the error of its
    given start ``x0``: ``x0_cov[j]`` (nx x nx, the model's states) is the covariance of manoeuvre ``j``'s ``x0`` about
    the true start (e.g. the logged signals' noise it is read from). The states ``oe`` estimates per manoeuvre take
    their error up and are left out; for the others, as :func:`consider_covariance` does for fixed parameters, with
    ``A_j = (M_θθ⁻¹ M_θx)_j`` the linearised shift of the estimate per unit error of manoeuvre ``j``'s start (its
    nuisance parameters profiled out), ``A_j Σ_j A_jᵀ``; the manoeuvres' start errors are independent, so the
    consider covariance is their sum. Zeros when no state outside the estimated ones has a variance."""
    ng = len(oe.free)
    if len(x0_cov) != len(data):
        raise EstimationError(f"start consider covariance: {len(x0_cov)} start covariances for {len(data)} "
                              "manoeuvres")
    names = list(oe.model.states.index)
    diag = np.array([np.diag(np.asarray(c, float)) for c in x0_cov]).reshape(len(data), len(names))
    extra = [n for i, n in enumerate(names) if n not in oe.states_est and np.any(diag[:, i] > 0.0)]
    if not extra:
        return np.zeros((len(data), ng, ng))
    big = _widened(oe, oe.p_nominal, oe.free, oe.states_est + extra, False)
    ne, nx, nl = len(oe.states_est), len(extra), oe.n_local
    ix = [oe.model.states.index[n] for n in extra]
    theta, keep, cons = list(est.values[:ng]), list(range(ng)), []
    for j, m in enumerate(data):
        loc = est.values[ng + j * nl: ng + (j + 1) * nl]
        base = len(theta)
        theta += [*loc[:ne], *np.asarray(m.x0, float)[ix], *loc[ne:]]
        keep += [*range(base, base + ne), *range(base + ne + nx, base + nl + nx)]
        cons.append(list(range(base + ne, base + ne + nx)))
    th = np.asarray(theta, float)
    sims = [big.simulate(th, m, j) for j, m in enumerate(data)]
    if any(s[2] for s in sims):
        raise EstimationError("start consider covariance: the model diverges at the estimate")
    res, jacs, W, _ = _linearised(list(data), sims, weight)
    M, _ = big._normal_equations(res, jacs, W, len(th))
    Mtt = M[np.ix_(keep, keep)] + np.diag(oe.prior_information(len(keep)))
    flat = [c for cj in cons for c in cj]
    A = np.linalg.lstsq(Mtt, M[np.ix_(keep, flat)], rcond=None)[0][:ng]
    out = np.zeros((len(data), ng, ng))
    for j, c in enumerate(x0_cov):
        Aj = A[:, j * nx:(j + 1) * nx]
        out[j] = Aj @ np.asarray(c, float)[np.ix_(ix, ix)] @ Aj.T
    return 0.5 * (out + out.transpose(0, 2, 1))

#: a fixed parameter is worth freeing when its consider share shifts a free one by more than this many of
#: its data-only std (0.5: the share would widen that bound by 12 % or more; 1 before 2026-11-28, when
#: shares just below it widened the coverage study's pitch bounds 1.3-2.2 times) ...
FREE_IMPACT = 0.5
#: ... and the data would pin it down (its std, were it freed, below this fraction of the std it was given):
#: freed with that std as its prior, its posterior std is below half of it, and the bound of every derivative
#: it moves is narrower than with its consider share, and centred
FREE_INFORMED = 0.5
#: rounds of freeing (each refit from the estimate; a round can make another fixed parameter matter)
FREE_ROUNDS = 3


def fixed_worth_freeing(est: Estimate, con: Consider) -> list[str]:
    """The fixed parameters of ``con`` that matter (shift a free estimate by more than :data:`FREE_IMPACT`
    data-only std) and that the data inform (``informed`` below :data:`FREE_INFORMED`), as ``--free auto``
    frees them."""
    if not con.names:
        return []
    data_std = est.data_std
    impact = np.abs(con.influence) * con.sd[None, :] / np.maximum(data_std[:, None], 1e-300)
    return [c for j, c in enumerate(con.names) if impact[:, j].max() > FREE_IMPACT and con.informed[j] < FREE_INFORMED]

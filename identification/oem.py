"""Output-error estimation of model parameters (Maine & Iliff, NASA RP-1168; Jategaonkar; Morelli's ``oe.m``).

The model is simulated with the recorded inputs over each manoeuvre, and its outputs are fitted to the
measured ones by Gauss-Newton with Levenberg-Marquardt damping. Output sensitivities are CasADi's exact
forward derivatives of the same step function the FMU compiles (``fmu_models.common.model.step_function``),
evaluated over the whole record by one ``mapaccum`` function: no second copy of the physics, no finite
differences. The weighting is the inverse of the residual covariance re-estimated every iteration (the
maximum-likelihood form) or a fixed matrix B (paper 001 eq. 9).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from fmu_models.common.model import VehicleModel, step_function

log = logging.getLogger(__name__)


class EstimationError(ValueError):
    """The problem is ill-posed (unknown names, mismatched shapes, a diverging start)."""


@dataclass(frozen=True)
class Manoeuvre:
    """One record: initial state, inputs (N x nu) and measured outputs (N x ny) at a fixed sample time."""

    x0: np.ndarray
    u: np.ndarray
    y: np.ndarray
    dt_s: float


@dataclass
class Iteration:
    cost: float
    step_norm: float
    damping: float


@dataclass
class Estimate:
    """Result: values of the free parameters, Cramér-Rao bounds, correlations, convergence history."""

    names: list[str]
    values: np.ndarray
    crb_std: np.ndarray
    correlation: np.ndarray
    residual_cov: np.ndarray
    history: list[Iteration] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def table(self) -> str:
        rows = [f"{'parameter':<16} {'estimate':>12} {'CR std':>10} {'std/|est| %':>12}"]
        for n, v, s in zip(self.names, self.values, self.crb_std, strict=True):
            rows.append(f"{n:<16} {v:12.5g} {s:10.3g} {100 * s / max(abs(v), 1e-12):12.2f}")
        return "\n".join(rows)


class OutputError:
    """Output-error problem for ``model`` with free parameters ``free`` and fitted outputs ``outputs``."""

    def __init__(self, model: VehicleModel, p_nominal: Sequence[float], free: Sequence[str],
                 outputs: Sequence[str], bounds: dict[str, tuple[float, float]] | None = None,
                 constraints: Sequence[Callable[[dict[str, float]], bool]] = ()) -> None:
        unknown = [n for n in free if n not in model.params.index]
        unknown += [n for n in outputs if n not in model.outputs.index]
        if unknown:
            raise EstimationError(f"not parameters/outputs of {model.name}: {', '.join(unknown)}")
        self.model = model
        self.p_nominal = np.asarray(p_nominal, dtype=float)
        self.free = list(free)
        self.outputs = list(outputs)
        self.i_free = [model.params.index[n] for n in free]
        self.i_out = [model.outputs.index[n] for n in outputs]
        b = bounds or {}
        self.lower = np.array([b.get(n, (-np.inf, np.inf))[0] for n in free])
        self.upper = np.array([b.get(n, (-np.inf, np.inf))[1] for n in free])
        self.constraints = list(constraints)
        self._step = step_function(model)
        self._funcs: dict[int, ca.Function] = {}

    def _augmented_step(self) -> ca.Function:
        """One step of the state and its forward sensitivity ``S = dx/dtheta`` (SX, built once).

        ``S_{k+1} = (dx_{k+1}/dx_k) S_k + dx_{k+1}/dtheta`` and ``dy/dtheta = (dy/dx) S + dy/dtheta``: the
        forward sensitivity equations of the discrete RK4 map, so the derivatives are exact for the very
        simulation that is fitted.
        """
        nx, nth = len(self.model.states), len(self.free)
        x = ca.SX.sym("x", nx)
        S = ca.SX.sym("S", nx, nth)
        u = ca.SX.sym("u", len(self.model.inputs))
        p = ca.SX.sym("p", len(self.model.params))
        dt = ca.SX.sym("dt")
        x1, y1 = self._step(x, u, p, dt)
        y1 = y1[self.i_out]
        th = ca.vertcat(*[p[i] for i in self.i_free])
        S1 = ca.jacobian(x1, x) @ S + ca.jacobian(x1, th)
        dy = ca.jacobian(y1, x) @ S + ca.jacobian(y1, th)
        xa = ca.vertcat(x, ca.vec(S))
        xa1 = ca.vertcat(x1, ca.vec(S1))
        return ca.Function("aug", [xa, u, p, dt], [xa1, ca.vertcat(y1, ca.vec(dy))])

    def _sim_function(self, n: int) -> ca.Function:
        """``(xa0, U, p, dt) -> (Xa, [Y; dY/dtheta])`` over ``n`` samples, built once per record length."""
        if n not in self._funcs:
            if not hasattr(self, "_aug"):
                self._aug = self._augmented_step()
            self._funcs[n] = self._aug.mapaccum("sens", n)
        return self._funcs[n]

    def simulate(self, theta: np.ndarray, m: Manoeuvre) -> tuple[np.ndarray, np.ndarray]:
        """Model outputs (N x ny) and sensitivities (N*ny x n_free) for manoeuvre ``m``.

        Output row k is the model's output after k+1 steps, so ``m.y[k]`` is the measurement at t_{k+1}.
        """
        n = m.u.shape[0]
        ny, nth = len(self.outputs), len(self.free)
        p = self.p_nominal.copy()
        p[self.i_free] = theta
        xa0 = np.concatenate([np.asarray(m.x0, dtype=float), np.zeros(len(self.model.states) * nth)])
        _, out = self._sim_function(n)(xa0, m.u.T, p, m.dt_s)
        out = np.asarray(out)  # (ny + ny*nth) x n
        y = out[:ny].T
        # dy/dtheta per sample is column-major (ny x nth); stack samples as rows k*ny + i
        jac = out[ny:].T.reshape(n, nth, ny).transpose(0, 2, 1).reshape(n * ny, nth)
        return y, jac

    def _residuals(self, theta: np.ndarray, data: Sequence[Manoeuvre]) -> tuple[np.ndarray, list[np.ndarray]]:
        res, jacs = [], []
        for m in data:
            y, j = self.simulate(theta, m)
            res.append(m.y - y)
            jacs.append(j)
        return np.vstack(res), jacs

    def estimate(self, data: Sequence[Manoeuvre], theta0: Sequence[float] | None = None,
                 weight: np.ndarray | None = None, max_iter: int = 30, tol: float = 1e-9,
                 progress: bool = False) -> Estimate:
        """Levenberg-Marquardt on the weighted output error; returns the estimate with its CR bounds."""
        theta = np.array(theta0 if theta0 is not None else self.p_nominal[self.i_free], dtype=float)
        ny = len(self.outputs)
        r, jacs = self._residuals(theta, data)
        if not np.all(np.isfinite(r)):
            raise EstimationError("the model diverges at the initial parameters; start closer or fix parameters")

        def weight_of(res: np.ndarray) -> np.ndarray:
            if weight is not None:
                return np.asarray(weight, dtype=float)
            cov = np.diag(np.maximum(np.mean(res**2, axis=0), 1e-300))
            return np.linalg.inv(cov)

        W = weight_of(r)
        cost = 0.5 * float(np.sum((r @ W) * r))
        lam = 1e-3
        history: list[Iteration] = []
        for it in range(max_iter):
            M = np.zeros((len(theta), len(theta)))
            g = np.zeros(len(theta))
            row = 0
            for m, j in zip(data, jacs, strict=True):
                n = m.u.shape[0]
                # vec(Y) is column-major over (ny, n): sample k's outputs are rows k*ny .. k*ny+ny-1
                J3 = j.reshape(n, ny, -1)
                rk = r[row:row + n]
                M += np.einsum("kia,ij,kjb->ab", J3, W, J3)
                g += np.einsum("kia,ij,kj->a", J3, W, rk)
                row += n
            accepted = False
            while lam < 1e10:
                step = np.linalg.solve(M + lam * np.diag(np.diag(M)), g)
                trial = np.clip(theta + step, self.lower, self.upper)
                named = dict(zip(self.free, trial, strict=True))
                if all(c(named) for c in self.constraints):
                    r_t, j_t = self._residuals(trial, data)
                    if np.all(np.isfinite(r_t)):
                        cost_t = 0.5 * float(np.sum((r_t @ W) * r_t))
                        if cost_t <= cost:
                            accepted = True
                            break
                lam *= 10.0
            if not accepted:
                break
            rel = abs(cost - cost_t) / max(cost, 1e-300)
            step_norm = float(np.linalg.norm(trial - theta) / max(np.linalg.norm(theta), 1e-12))
            theta, r, jacs, cost = trial, r_t, j_t, cost_t
            W = weight_of(r)
            cost = 0.5 * float(np.sum((r @ W) * r))
            history.append(Iteration(cost, step_norm, lam))
            if progress:
                print(f"  iteration {it + 1:2d}: cost {cost:.6g}  step {step_norm:.3g}  damping {lam:.1e}")
            lam = max(lam / 10.0, 1e-9)
            if rel < tol and step_norm < 1e-8:
                break
        # Cramér-Rao bounds from the information matrix at the solution
        M = np.zeros((len(theta), len(theta)))
        for m, j in zip(data, jacs, strict=True):
            J3 = j.reshape(m.u.shape[0], ny, -1)
            M += np.einsum("kia,ij,kjb->ab", J3, W, J3)
        cov = np.linalg.pinv(M)
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = cov / np.outer(np.maximum(std, 1e-300), np.maximum(std, 1e-300))
        warnings = []
        for i, n in enumerate(self.free):
            if std[i] > 0.5 * abs(theta[i]):
                warnings.append(f"{n}: Cramér-Rao std {std[i]:.3g} exceeds half the estimate - poorly identified")
            for k in range(i + 1, len(self.free)):
                if abs(corr[i, k]) > 0.95:
                    warnings.append(f"{n} and {self.free[k]} are correlated ({corr[i, k]:+.3f})")
        return Estimate(self.free, theta, std, corr, np.linalg.inv(W), history, warnings)

"""ANFIS training by Jang's hybrid learning rule (Jang 1993, IEEE SMC 23(3); paper 000 section 2.1).

Each epoch has a forward pass, where the premise (membership) parameters are fixed and the Takagi-Sugeno
consequents are the linear least-squares solution, and a backward pass, where the premise parameters take
one gradient-descent step on the summed squared error with Jang's normalised step
``eta = kappa / sqrt(sum (dE/dalpha)^2)``; ``kappa`` grows by 10 % after four consecutive error reductions
and shrinks by 10 % after two consecutive up-down alternations (Jang 1993, section V; MATLAB ``anfis``
defaults 0.01 / 0.9 / 1.1). With checking data, the parameters of the epoch with the lowest checking error
are returned (early stopping as in MATLAB ``anfis``); without, those of the lowest training error.

Inputs are scaled internally to [-1, 1] over the training range (summed PWM is ~6000 us, which would make
the gradient step and the least-squares problem badly conditioned); the returned :class:`AnfisMap` is in raw
input units. There is no randomness: grid-partition initialisation and batch least squares make a run
bit-for-bit repeatable. All work is vectorised over samples with numpy; the only Python loops run over
epochs and over the (few) inputs.

The training forward pass works in the log domain (``log w_r = sum_i log mu_ij``, then a softmax) so that
far-away samples cannot underflow every firing strength to zero; ``tests/identification/thrust/test_anfis_train.py``
checks that
it equals :meth:`AnfisMap.evaluate` on the exported map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from fmu_models.common.mathns import NP
from fmu_models.config import bounded, range_problems
from fmu_models.quadrotor.anfis import MF_TYPES, AnfisMap, feature_values

MIN_SIGMA_SCALED = 1e-3  #: floor of an MF width in scaled input units (width 2 = whole training range)
MIN_BELL_SLOPE = 0.5  #: floor of the generalised-bell exponent b (keeps dmu/dm finite at the centre)
INCREASE_AFTER_REDUCTIONS = 4  #: Jang: grow kappa after this many consecutive error reductions
DECREASE_AFTER_ALTERNATIONS = 2  #: Jang: shrink kappa after this many consecutive up-down combinations
LSQ_RCOND = 1e-6  #: relative singular-value cut-off of the consequent least squares


class AnfisTrainingError(ValueError):
    """Training data or configuration cannot produce a map (message names the field and value)."""


@dataclass(frozen=True)
class AnfisTrainConfig:
    """Hyper-parameters of hybrid ANFIS training (all checked at construction).

    ``n_mfs``: MFs per input (one number for all inputs). ``order``: 0 or 1 (Takagi-Sugeno consequents).
    ``step_size``: initial kappa. ``patience``: stop after this many epochs without a new best checking
    error (``None``: run all epochs). ``progress``: show a tqdm bar.
    """

    n_mfs: int = bounded(6, 1, 50)
    mf_type: str = "gaussian"
    order: int = bounded(0, 0, 1)
    epochs: int = bounded(100, 1, 100_000)
    step_size: float = bounded(0.01, 1e-12, 1e3)
    step_increase: float = bounded(1.1, 1.0, 10.0)
    step_decrease: float = bounded(0.9, 1e-6, 1.0)
    patience: int | None = bounded(None, 1, 100_000, optional=True)
    progress: bool = False

    def __post_init__(self) -> None:
        problems = range_problems(self)
        if self.mf_type not in MF_TYPES:
            problems.append(f"mf_type = {self.mf_type!r}; allowed: {', '.join(MF_TYPES)}")
        if problems:
            raise AnfisTrainingError("AnfisTrainConfig: " + "; ".join(problems))


@dataclass(frozen=True)
class TrainResult:
    """Outcome of :func:`train_anfis`: the map (raw units) and its learning history.

    ``train_rmse[e]``/``check_rmse[e]``: RMSE [output units] at epoch e (after that epoch's least-squares
    step, before its gradient step). ``best_epoch`` is 0-based. ``step_sizes[e]``: kappa used at epoch e.
    """

    amap: AnfisMap
    train_rmse: tuple[float, ...]
    check_rmse: tuple[float, ...] | None
    best_epoch: int
    step_sizes: tuple[float, ...] = field(default=())

    @property
    def epochs_run(self) -> int:
        return len(self.train_rmse)


# --------------------------------------------------------------------------- internal state (scaled units)
@dataclass
class _Premise:
    """MF parameters in scaled units, one (n_inputs, n_mfs) array each (grid partition, equal counts)."""

    mean: np.ndarray
    sigma: np.ndarray
    slope: np.ndarray | None

    def copy(self) -> _Premise:
        slope = None if self.slope is None else self.slope.copy()
        return _Premise(self.mean.copy(), self.sigma.copy(), slope)


def _rule_index(n_inputs: int, n_mfs: int) -> np.ndarray:
    """(R, n_inputs) MF index per rule, the last input varying fastest (same order as AnfisMap)."""
    grids = np.meshgrid(*([np.arange(n_mfs)] * n_inputs), indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1)


def _grid_init(n_inputs: int, cfg: AnfisTrainConfig) -> _Premise:
    """Centres evenly over [-1, 1]; neighbouring MFs cross at membership 0.5 (one MF: centred, wide)."""
    if cfg.n_mfs == 1:
        mean = np.zeros((n_inputs, 1))
        half = 1.0
    else:
        mean = np.tile(np.linspace(-1.0, 1.0, cfg.n_mfs), (n_inputs, 1))
        half = 1.0 / (cfg.n_mfs - 1)  # half the centre spacing
    if cfg.mf_type == "gaussian":
        # exp(-(half/sigma)^2) = 0.5
        sigma = np.full_like(mean, half / math.sqrt(math.log(2.0)))
        return _Premise(mean, sigma, None)
    # generalised bell, MATLAB genfis1 style: a = half spacing, b = 2 -> 0.5 at the midpoint
    return _Premise(mean, np.full_like(mean, half), np.full_like(mean, 2.0))


def _log_memberships(z: np.ndarray, prem: _Premise) -> tuple[np.ndarray, np.ndarray]:
    """log mu (N, n_inputs, n_mfs) and u = (z - m)/sigma for scaled inputs ``z`` (N, n_inputs)."""
    u = (z[:, :, None] - prem.mean[None]) / prem.sigma[None]
    if prem.slope is None:
        return -(u * u), u
    return -np.log1p(np.abs(u) ** (2.0 * prem.slope[None])), u


def _normalised_firing(logmu: np.ndarray, rules: np.ndarray) -> np.ndarray:
    """Layer 3+normalisation: wbar (N, R), computed as a softmax of the summed log memberships."""
    n_inputs = rules.shape[1]
    logw = logmu[:, 0, rules[:, 0]]
    for i in range(1, n_inputs):
        logw = logw + logmu[:, i, rules[:, i]]
    logw -= logw.max(axis=1, keepdims=True)
    w = np.exp(logw)
    return w / np.einsum("nr->n", w)[:, None]  # einsum: faster than .sum(axis=1) over a few rules


def _design(wbar: np.ndarray, z: np.ndarray, order: int) -> np.ndarray:
    """Least-squares design matrix, column blocks ``[wbar z_1 | ... | wbar z_n | wbar]`` (order 1).

    Block-major columns (one block per consequent coefficient, rules inside) are faster to build than
    rule-major ones; :func:`_least_squares` transposes the solution back to one row per rule.
    """
    if order == 0:
        return wbar
    return np.concatenate([wbar * z[:, [i]] for i in range(z.shape[1])] + [wbar], axis=1)


def _rule_outputs(cons: np.ndarray, z: np.ndarray, order: int) -> np.ndarray:
    """f_r per sample (N, R); ``cons`` is (R, 1) or (R, n_inputs + 1) in scaled units."""
    if order == 0:
        return np.broadcast_to(cons[:, 0], (z.shape[0], cons.shape[0]))
    f = cons[:, -1] + z[:, [0]] * cons[:, 0]  # broadcasting beats a matmul with an inner size of n_inputs
    for i in range(1, z.shape[1]):
        f = f + z[:, [i]] * cons[:, i]
    return f


def _forward(z: np.ndarray, prem: _Premise, cons: np.ndarray, rules: np.ndarray, order: int) -> np.ndarray:
    logmu, _ = _log_memberships(z, prem)
    wbar = _normalised_firing(logmu, rules)
    return np.einsum("nr,nr->n", wbar, _rule_outputs(cons, z, order))


def _least_squares(wbar: np.ndarray, z: np.ndarray, y: np.ndarray, order: int, n_rules: int) -> np.ndarray:
    """Consequents minimising the squared error for fixed premises (:func:`_lstsq` of the design)."""
    return _lstsq(_design(wbar, z, order), y, n_rules)


def _lstsq(a: np.ndarray, y: np.ndarray, n_rules: int) -> np.ndarray:
    """Least squares ``a theta ~ y``, one row of ``theta`` per rule.

    Truncated-SVD least squares computed from the small Gram matrix of the column-equilibrated design
    (eigenvectors of (AD)^T(AD) are the right singular vectors of AD). Hand-written instead of
    ``np.linalg.lstsq`` because LAPACK's SVD of the tall N x R(n+1) design costs 5-50x more per epoch
    (threaded BLAS on small matrices), which dominates training time. Singular values below
    ``LSQ_RCOND`` times the largest are dropped: a rule that no sample fires gets a minimum-norm
    consequent instead of a huge one.
    """
    gram = a.T @ a
    col = np.sqrt(np.diag(gram)).copy()
    col[col == 0.0] = 1.0
    lam, vec = np.linalg.eigh(gram / np.outer(col, col))
    keep = lam > (LSQ_RCOND**2) * lam[-1]
    proj = vec[:, keep].T @ ((a.T @ y) / col) / lam[keep]
    theta = (vec[:, keep] @ proj) / col
    return theta.reshape(-1, n_rules).T.copy()


def _onehots(rules: np.ndarray, n_mfs: int) -> list[np.ndarray]:
    """Per input, the (R, n_mfs) matrix that is 1 where rule r uses MF j of that input."""
    out = []
    for i in range(rules.shape[1]):
        onehot = np.zeros((rules.shape[0], n_mfs))
        onehot[np.arange(rules.shape[0]), rules[:, i]] = 1.0
        out.append(onehot)
    return out


def _premise_gradient(
    z: np.ndarray,
    y: np.ndarray,
    prem: _Premise,
    cons: np.ndarray,
    order: int,
    onehots: list[np.ndarray],
    u: np.ndarray,
    wbar: np.ndarray,
) -> tuple[list[np.ndarray], float]:
    """dE/d(premise) for E = sum (y - yhat)^2, and E itself.

    yhat = sum_r wbar_r f_r gives dE/dlog w_r = -2 e wbar_r (f_r - yhat); a premise parameter of MF (i, j)
    enters log w_r of every rule using that MF, so its gradient is sum_n dlog mu_ij/dalpha * S_ij with
    S_ij = sum over those rules (a one-hot matrix product, no per-sample loop).
    """
    f = _rule_outputs(cons, z, order)
    yhat = np.einsum("nr,nr->n", wbar, f)
    err = y - yhat
    g_rule = -2.0 * err[:, None] * wbar * (f - yhat[:, None])  # dE/dlog w_r, (N, R)
    n_inputs, n_mfs = prem.mean.shape
    s = np.empty((z.shape[0], n_inputs, n_mfs))
    for i in range(n_inputs):
        s[:, i, :] = g_rule @ onehots[i]
    sig = prem.sigma
    if prem.slope is None:
        # log mu = -u^2, u = (z - m)/sigma: dlog mu/dm = 2u/sigma, dlog mu/dsigma = 2u^2/sigma
        su = s * u
        grads = [2.0 * np.einsum("nij->ij", su) / sig, 2.0 * np.einsum("nij,nij->ij", su, u) / sig]
    else:
        # log mu = -log(1 + |u|^(2b)); q = |u|^(2b), mu = 1/(1+q)
        b = prem.slope[None]
        au = np.abs(u)
        q = au ** (2.0 * b)
        mu = 1.0 / (1.0 + q)
        with np.errstate(divide="ignore", invalid="ignore"):
            q_over_u = np.where(au > 0.0, np.sign(u) * au ** (2.0 * b - 1.0), 0.0)
            log_au = np.where(au > 0.0, np.log(np.where(au > 0.0, au, 1.0)), 0.0)
        smu = s * mu
        grads = [
            2.0 * prem.slope * np.einsum("nij,nij->ij", smu, q_over_u) / sig,
            2.0 * prem.slope * np.einsum("nij,nij->ij", smu, q) / sig,
            -2.0 * np.einsum("nij,nij->ij", smu * q, log_au),
        ]
    return grads, float(err @ err)


def _rmse(yhat: np.ndarray, y: np.ndarray) -> float:
    return float(np.sqrt(np.mean((yhat - y) ** 2)))


def _check_xy(x: np.ndarray, y: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or y.ndim != 1 or x.shape[0] != y.shape[0]:
        raise AnfisTrainingError(
            f"{what}: x must be (N, n_inputs) and y (N,), got x {x.shape} and y {y.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise AnfisTrainingError(f"{what}: x and y must be finite (found NaN or inf)")
    return x, y


class _StepSize:
    """Jang's heuristic update of kappa from the sequence of training errors."""

    def __init__(self, cfg: AnfisTrainConfig) -> None:
        self.kappa = cfg.step_size
        self.cfg = cfg
        self.errors: list[float] = []

    def update(self, error: float) -> None:
        self.errors.append(error)
        e = self.errors
        n_red = INCREASE_AFTER_REDUCTIONS
        if len(e) > n_red and all(e[-k] < e[-k - 1] for k in range(1, n_red + 1)):
            self.kappa *= self.cfg.step_increase
            self.errors = e[-1:]  # start counting afresh
            return
        n_alt = 2 * DECREASE_AFTER_ALTERNATIONS
        if len(e) > n_alt:
            d = np.sign(np.diff(e[-n_alt - 1 :]))
            if np.all(d != 0) and np.all(d[1:] == -d[:-1]):
                self.kappa *= self.cfg.step_decrease
                self.errors = e[-1:]


def train_anfis(
    x: np.ndarray,
    y: np.ndarray,
    config: AnfisTrainConfig | None = None,
    x_check: np.ndarray | None = None,
    y_check: np.ndarray | None = None,
    input_names: tuple[str, ...] = ("pwm_sum_us",),
    output: str = "thrust_N",
    source: str = "",
) -> TrainResult:
    """Train an ANFIS on ``x`` (N, n_inputs) [input units] -> ``y`` (N,) [output units].

    ``x_check``/``y_check``: checking data for early stopping (recommended; the map of the epoch with the
    lowest checking RMSE is returned). The map's ``input_range`` is the training data's range per input.
    """
    cfg = config or AnfisTrainConfig()
    x, y = _check_xy(x, y, "training data")
    lo, hi = _training_band(x, cfg, input_names)
    centre, half_span = (hi + lo) / 2.0, (hi - lo) / 2.0
    check = None
    if x_check is not None and y_check is not None and len(x_check) > 0:
        xc, yc = _check_xy(x_check, y_check, "checking data")
        if xc.shape[1] != x.shape[1]:
            raise AnfisTrainingError(f"checking data has {xc.shape[1]} inputs, training data {x.shape[1]}")
        check = ((xc - centre) / half_span, yc)
    hist = _hybrid_epochs((x - centre) / half_span, y, check, cfg)
    if hist.best_epoch < 0:
        last = hist.train_rmse[-1] if hist.train_rmse else "n/a"
        raise AnfisTrainingError(f"no epoch gave a finite error (last training RMSE {last})")
    amap = _to_map(hist.best_prem, hist.best_cons, centre, half_span, cfg, input_names, (lo, hi), output, source)
    return TrainResult(
        amap=amap,
        train_rmse=tuple(hist.train_rmse),
        check_rmse=tuple(hist.check_rmse) if check is not None else None,
        best_epoch=int(hist.best_epoch),
        step_sizes=tuple(hist.step_sizes),
    )


def _training_band(
    x: np.ndarray, cfg: AnfisTrainConfig, input_names: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Per-input (min, max) of the training data; AnfisTrainingError for a constant input or too few samples."""
    n_samples, n_inputs = x.shape
    if len(input_names) != n_inputs:
        raise AnfisTrainingError(f"input_names has {len(input_names)} names for {n_inputs} input columns")
    lo, hi = x.min(axis=0), x.max(axis=0)
    if np.any(hi <= lo):
        i = int(np.argmax(hi <= lo))
        raise AnfisTrainingError(
            f"training input {input_names[i]!r} is constant ({lo[i]}); an ANFIS needs a spread of values"
        )
    n_rules = cfg.n_mfs**n_inputs
    n_params = n_rules * (1 + (n_inputs if cfg.order == 1 else 0))
    if n_samples < n_params:
        raise AnfisTrainingError(
            f"training data has {n_samples} samples, fewer than the {n_params} consequent parameters of "
            f"{n_rules} rules (order {cfg.order}); use fewer MFs or more data"
        )
    return lo, hi


@dataclass
class _History:
    """Learning history of :func:`_hybrid_epochs` and the kept (best-scoring) parameters, scaled units."""

    best_prem: _Premise
    best_cons: np.ndarray
    best_score: float = math.inf
    best_epoch: int = -1
    train_rmse: list[float] = field(default_factory=list)
    check_rmse: list[float] = field(default_factory=list)
    step_sizes: list[float] = field(default_factory=list)

    def keep_if_best(self, score: float, epoch: int, prem: _Premise, cons: np.ndarray) -> bool:
        """Keep these parameters when ``score`` beats the best so far; True when kept."""
        if not score < self.best_score:
            return False
        self.best_score, self.best_epoch, self.best_prem, self.best_cons = score, epoch, prem.copy(), cons.copy()
        return True


def _hybrid_epochs(
    z: np.ndarray, y: np.ndarray, check: tuple[np.ndarray, np.ndarray] | None, cfg: AnfisTrainConfig
) -> _History:
    """Jang's hybrid learning on scaled inputs ``z``: least squares, score, then one gradient step per epoch."""
    n_inputs = z.shape[1]
    rules = _rule_index(n_inputs, cfg.n_mfs)
    onehots = _onehots(rules, cfg.n_mfs)
    prem = _grid_init(n_inputs, cfg)
    step = _StepSize(cfg)
    hist = _History(prem.copy(), np.zeros((rules.shape[0], 1)))
    since_best = 0
    bar = tqdm(range(cfg.epochs), desc="ANFIS hybrid training", unit="epoch", disable=not cfg.progress)
    for epoch in bar:
        logmu, u = _log_memberships(z, prem)
        wbar = _normalised_firing(logmu, rules)
        cons = _least_squares(wbar, z, y, cfg.order, rules.shape[0])
        grads, sse = _premise_gradient(z, y, prem, cons, cfg.order, onehots, u, wbar)
        train_rmse = math.sqrt(sse / y.size)
        hist.train_rmse.append(train_rmse)
        hist.step_sizes.append(step.kappa)
        score = train_rmse
        if check is not None:
            score = _rmse(_forward(check[0], prem, cons, rules, cfg.order), check[1])
            hist.check_rmse.append(score)
        since_best = 0 if hist.keep_if_best(score, epoch, prem, cons) else since_best + 1
        bar.set_postfix(
            train_rmse=f"{train_rmse:.4g}", check_rmse=f"{score:.4g}" if check is not None else "-", refresh=False
        )
        if cfg.patience is not None and since_best >= cfg.patience:
            break
        step.update(sse)
        _premise_step(prem, grads, step.kappa)
    bar.close()
    return hist


def _premise_step(prem: _Premise, grads: list[np.ndarray], kappa: float) -> None:
    """One normalised gradient step ``eta = kappa / |grad|`` on the MF parameters (floors on width, slope)."""
    norm = math.sqrt(sum(float(np.sum(g * g)) for g in grads))
    if norm == 0.0 or not math.isfinite(norm):
        return  # exact fit or degenerate data: nothing to descend
    eta = kappa / norm
    prem.mean = prem.mean - eta * grads[0]
    prem.sigma = np.maximum(prem.sigma - eta * grads[1], MIN_SIGMA_SCALED)
    if prem.slope is not None:
        prem.slope = np.maximum(prem.slope - eta * grads[2], MIN_BELL_SLOPE)


def _to_map(
    prem: _Premise,
    cons: np.ndarray,
    centre: np.ndarray,
    half_span: np.ndarray,
    cfg: AnfisTrainConfig,
    input_names: tuple[str, ...],
    band: tuple[np.ndarray, np.ndarray],
    output: str,
    source: str,
) -> AnfisMap:
    """Convert scaled-unit parameters to an :class:`AnfisMap` in raw input units.

    x = c + s z, so MF mean m_raw = c + s m, width sigma_raw = s sigma (b unchanged); a first-order
    consequent p z + r = (p/s) x + (r - p c / s).
    """
    mean_raw = centre[:, None] + half_span[:, None] * prem.mean
    sigma_raw = half_span[:, None] * prem.sigma
    if cfg.order == 0:
        cons_raw = cons
    else:
        p_raw = cons[:, :-1] / half_span[None, :]
        r_raw = cons[:, -1] - p_raw @ centre
        cons_raw = np.concatenate([p_raw, r_raw[:, None]], axis=1)
    return AnfisMap(
        inputs=tuple(input_names),
        mf_type=cfg.mf_type,
        mf_mean=tuple(tuple(float(v) for v in row) for row in mean_raw),
        mf_sigma=tuple(tuple(float(v) for v in row) for row in sigma_raw),
        mf_slope=None if prem.slope is None else tuple(tuple(float(v) for v in row) for row in prem.slope),
        order=cfg.order,
        consequents=tuple(tuple(float(v) for v in row) for row in cons_raw),
        input_range=tuple((float(a), float(b)) for a, b in zip(band[0], band[1], strict=True)),
        output=output,
        source=source,
    )


def predict(amap: AnfisMap, x: np.ndarray) -> np.ndarray:
    """Evaluate ``amap`` on samples ``x`` (N,) or (N, n_inputs) [raw units] with :meth:`AnfisMap.evaluate`."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    return np.asarray(amap.evaluate([x[:, i] for i in range(x.shape[1])]), dtype=float)


def training_forward(amap: AnfisMap, x: np.ndarray) -> np.ndarray:
    """The trainer's log-domain forward pass applied to a raw-unit map (for the equivalence test)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    n_mfs = set(amap.n_mfs)
    if len(n_mfs) != 1:
        raise AnfisTrainingError(f"training forward pass needs equal MF counts per input, got {amap.n_mfs}")
    prem = _Premise(
        np.array(amap.mf_mean),
        np.array(amap.mf_sigma),
        None if amap.mf_slope is None else np.array(amap.mf_slope),
    )
    rules = _rule_index(amap.n_inputs, n_mfs.pop())
    return _forward(x, prem, np.array(amap.consequents), rules, amap.order)


# --------------------------------------------------------------------------- metrics and baseline
def rmse(y_pred: np.ndarray, y_true: np.ndarray) -> float:
    """Root-mean-square error [units of y]."""
    return _rmse(np.asarray(y_pred, float), np.asarray(y_true, float))


def r_squared(y_pred: np.ndarray, y_true: np.ndarray) -> float:
    """Coefficient of determination 1 - SS_res/SS_tot (can be negative on test data)."""
    y_true = np.asarray(y_true, float)
    ss_res = float(np.sum((y_true - np.asarray(y_pred, float)) ** 2))
    ss_tot = float(np.sum((y_true - y_true.mean()) ** 2))
    return 1.0 - ss_res / ss_tot if ss_tot > 0.0 else float("nan")


@dataclass(frozen=True)
class PolynomialFit:
    """Least-squares polynomial y(x) (numpy Polynomial, domain-scaled) and its test RMSE."""

    degree: int
    coef: tuple[float, ...]
    domain: tuple[float, float]
    test_rmse: float

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.polynomial.Polynomial(self.coef, domain=self.domain)(np.asarray(x, float))


def polynomial_baselines(
    x_train: np.ndarray,
    y_train: np.ndarray,
    x_test: np.ndarray,
    y_test: np.ndarray,
    degrees: tuple[int, ...] = (1, 2, 3),
) -> list[PolynomialFit]:
    """Least-squares polynomials of each degree fitted on the training split, scored on the test split."""
    out = []
    for deg in degrees:
        p = np.polynomial.Polynomial.fit(np.asarray(x_train, float), np.asarray(y_train, float), deg)
        out.append(
            PolynomialFit(
                degree=deg,
                coef=tuple(float(c) for c in p.coef),
                domain=(float(p.domain[0]), float(p.domain[1])),
                test_rmse=rmse(p(np.asarray(x_test, float)), y_test),
            )
        )
    return out


# --------------------------------------------------------------------------- per-motor feature ANFIS
def _motor_premise_step(prem: _Premise, fw: list, err_scaled: np.ndarray, kappa: float) -> None:
    """One Jang step on the Gaussian centres/widths for ``yhat = sum_i F(z_i)`` (``err_scaled`` = error).

    dE/dlog w_r summed over the motors (each motor's firing enters its own F), then as in
    :func:`_premise_gradient` (one input: one rule per MF).
    """
    g_m = np.zeros(prem.mean.shape[1])
    g_s = np.zeros(prem.mean.shape[1])
    for wbar, f, F, u in fw:
        g_rule = -2.0 * err_scaled[:, None] * wbar * (f - F[:, None])
        g_m += 2.0 * np.einsum("nj,nj->j", g_rule, u) / prem.sigma[0]
        g_s += 2.0 * np.einsum("nj,nj->j", g_rule, u * u) / prem.sigma[0]
    norm = math.sqrt(float(g_m @ g_m + g_s @ g_s))
    if norm == 0.0 or not math.isfinite(norm):
        return
    eta = kappa / norm
    prem.mean = prem.mean - eta * g_m[None]
    prem.sigma = np.maximum(prem.sigma - eta * g_s[None], MIN_SIGMA_SCALED)


def feature_design(x: np.ndarray, r: np.ndarray, wbar: list[np.ndarray] | None,
                   features: tuple[str, ...]) -> np.ndarray:
    """Least-squares design of ``y ~ sum_i sum_r wbar_r(x_i) sum_k c_rk phi_k(x_i, r)``: columns rule-major
    (rule r, then feature k). ``wbar=None``: one rule (the polynomial ``sum_i phi_k(x_i, r)``)."""
    rr = np.asarray(r, float)[:, None]
    phi = feature_values(features, x, rr)  # each (N, n_motors)
    if wbar is None:
        return np.stack([p.sum(axis=1) for p in phi], axis=1)
    cols = [sum(w[:, j] * p[:, i] for i, w in enumerate(wbar)) for j in range(wbar[0].shape[1]) for p in phi]
    return np.stack(cols, axis=1)


def _feature_forward(z: list[np.ndarray], x: np.ndarray, r: np.ndarray, prem: _Premise, cons: np.ndarray,
                     features: tuple[str, ...], rules: np.ndarray) -> list:
    """Per motor (wbar, f, F, u): normalised firing, rule outputs, motor thrust and scaled distance."""
    out = []
    for i, zi in enumerate(z):
        logmu, u = _log_memberships(zi[:, None], prem)
        wbar = _normalised_firing(logmu, rules)
        phi = np.stack(feature_values(features, x[:, i], r), axis=1)  # (N, K)
        f = phi @ cons.T  # (N, R)
        out.append((wbar, f, np.einsum("nr,nr->n", wbar, f), u[:, 0, :]))
    return out


def train_feature_anfis(
    x: np.ndarray,
    r: np.ndarray | None,
    y: np.ndarray,
    features: tuple[str, ...],
    n_rules: int,
    epochs: int = 30,
    check: tuple[np.ndarray, np.ndarray | None, np.ndarray] | None = None,
    input_name: str = "u",
    source: str = "",
) -> TrainResult:
    """Hybrid-train ``G`` so that ``y ~ sum_i G(x_i, r)``: one Gaussian MF per rule on the per-motor input.

    ``x`` (N, n_motors): per-motor input (normalised command, > 0 in the air); ``r`` (N,) battery ratio
    V/V_nom (None: 1). Consequents are first order over ``features`` (:data:`FEATURES`, no constant, so
    ``G(0) = 0``). One rule: the normalised firing is 1 and the single least-squares step IS the polynomial
    ``sum_k c_k sum_i phi_k(x_i)`` (``np.linalg.lstsq``, no gradient step). More rules: per epoch least squares
    for the consequents, then one Jang step on the MF centres and widths; ``check`` = (x, r, y) for early
    stopping (the epoch with the lowest checking RMSE is kept).
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    r = np.ones(len(y)) if r is None else np.asarray(r, float)
    if x.ndim != 2 or y.shape != (x.shape[0],) or r.shape != y.shape or not (
            np.isfinite(x).all() and np.isfinite(y).all() and np.isfinite(r).all()):
        raise AnfisTrainingError(f"training data: x must be finite (N, n_motors), r and y (N,); got {x.shape}, "
                                 f"{r.shape}, {y.shape}")
    lo, hi = float(x.min()), float(x.max())
    if not (hi > lo > 0.0):
        raise AnfisTrainingError(f"per-motor input spans [{lo}, {hi}]; it must lie above idle (> 0) and vary")
    if y.size < n_rules * len(features):
        raise AnfisTrainingError(f"{y.size} samples for {n_rules * len(features)} consequent parameters")
    cfg = AnfisTrainConfig(n_mfs=n_rules, order=1, epochs=epochs)
    centre, half = (hi + lo) / 2.0, (hi - lo) / 2.0
    prem = _grid_init(1, cfg)
    if n_rules == 1:
        cons = np.linalg.lstsq(feature_design(x, r, None, features), y, rcond=None)[0][None, :]
        res = math.sqrt(float(np.mean((feature_design(x, r, None, features) @ cons[0] - y) ** 2)))
        return TrainResult(_feature_map(prem, cons, centre, half, (lo, hi), features, input_name, source),
                           (res,), None, 0)
    hist = _feature_epochs(x, r, y, features, prem, centre, half, cfg, check)
    _, ep, bp, bc, ht, hc = hist
    return TrainResult(_feature_map(bp, bc, centre, half, (lo, hi), features, input_name, source), tuple(ht),
                       tuple(hc) if check is not None else None, int(ep))


def _feature_epochs(x, r, y, features, prem, centre, half, cfg, check) -> tuple:
    """Hybrid epochs of :func:`train_feature_anfis` (scaled premises); the best epoch and the histories."""
    rules = _rule_index(1, cfg.n_mfs)
    step = _StepSize(cfg)
    z = [(x[:, i] - centre) / half for i in range(x.shape[1])]
    zc = None
    if check is not None:
        xc = np.asarray(check[0], float)
        rc = np.ones(len(check[2])) if check[1] is None else np.asarray(check[1], float)
        zc = [(xc[:, i] - centre) / half for i in range(xc.shape[1])]
    best: tuple = (math.inf, -1, prem.copy(), np.zeros((cfg.n_mfs, len(features))))
    hist_t: list[float] = []
    hist_c: list[float] = []
    for epoch in range(cfg.epochs):
        wb = [_normalised_firing(_log_memberships(zi[:, None], prem)[0], rules) for zi in z]
        theta = _lstsq(feature_design(x, r, wb, features), y, 1).ravel()  # Gram route: 5-50x faster than SVD
        cons = theta.reshape(cfg.n_mfs, len(features))
        fw = _feature_forward(z, x, r, prem, cons, features, rules)
        err = y - sum(F for _w, _f, F, _u in fw)
        sse = float(err @ err)
        hist_t.append(math.sqrt(sse / y.size))
        score = hist_t[-1]
        if zc is not None:
            fc = _feature_forward(zc, xc, rc, prem, cons, features, rules)
            score = _rmse(sum(F for _w, _f, F, _u in fc), np.asarray(check[2], float))
            hist_c.append(score)
        if score < best[0]:
            best = (score, epoch, prem.copy(), cons.copy())
        step.update(sse)
        _motor_premise_step(prem, fw, err, step.kappa)
    if best[1] < 0:
        raise AnfisTrainingError(f"no epoch gave a finite error (last training RMSE {hist_t[-1:]})")
    return (*best, hist_t, hist_c)


def _feature_map(prem: _Premise, cons: np.ndarray, centre: float, half: float, band: tuple[float, float],
                 features: tuple[str, ...], input_name: str, source: str) -> AnfisMap:
    """Raw-unit map: MF centres/widths unscaled; consequents are already in raw feature units."""
    return AnfisMap(
        inputs=(input_name,), mf_type="gaussian",
        mf_mean=(tuple(float(centre + half * m) for m in prem.mean[0]),),
        mf_sigma=(tuple(float(half * s) for s in prem.sigma[0]),),
        mf_slope=None, order=1, consequents=tuple(tuple(float(v) for v in row) for row in cons),
        input_range=((band[0], band[1]),), output="thrust_N", source=source, features=tuple(features),
    )


def feature_map_monotone(amap: AnfisMap, r_values: tuple[float, ...] = (1.0,), n_points: int = 400) -> bool:
    """True when the per-motor map ``G(x, r)`` does not decrease on its band for every ``r`` given."""
    lo, hi = amap.input_range[0]
    xs = np.linspace(lo, hi, n_points)
    for rv in r_values:
        g = np.asarray(amap.evaluate([xs], NP, rv), float)
        if not np.all(np.diff(g) >= -1e-9 * max(1.0, float(np.abs(g).max()))):
            return False
    return True


def firing_of(amap: AnfisMap, x: np.ndarray) -> list[np.ndarray]:
    """Per motor, the normalised firing (N, R) of a one-input Gaussian map at raw inputs ``x`` (N, n_motors)."""
    prem = _Premise(np.array(amap.mf_mean), np.array(amap.mf_sigma), None)
    rules = _rule_index(1, amap.n_mfs[0])
    return [_normalised_firing(_log_memberships(np.asarray(x, float)[:, [i]], prem)[0], rules)
            for i in range(np.shape(x)[1])]

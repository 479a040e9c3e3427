"""Fit metrics of a model output against a measurement (flight-test identification conventions)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


class MetricsError(ValueError):
    """Mismatched or empty series."""


@dataclass(frozen=True)
class FitMetrics:
    """RMSE [signal unit], NRMSE (RMSE / range of the measurement), Theil inequality coefficient U
    (0 perfect, 1 useless; < 0.3 is the usual acceptance bar), fit percent (100 (1 - |e| / |y - mean y|)),
    coefficient of determination R^2, largest absolute error, and the number of samples."""

    rmse: float
    nrmse: float
    theil_u: float
    fit_percent: float
    r2: float
    max_error: float
    n: int

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def fit_metrics(measured: np.ndarray, model: np.ndarray) -> FitMetrics:
    """Metrics of ``model`` against ``measured`` (same length, NaNs in either dropped)."""
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    if y.shape != m.shape:
        raise MetricsError(f"measured has {y.size} samples, model {m.size}: they must match")
    keep = np.isfinite(y) & np.isfinite(m)
    y, m = y[keep], m[keep]
    if y.size == 0:
        raise MetricsError("no sample where both measured and model values are finite")
    e = y - m
    sse = float(np.sum(e * e))  # plain sums, no BLAS dot: a threaded BLAS on a busy machine costs ms per call
    rmse = float(np.sqrt(sse / y.size))
    span = float(np.ptp(y))
    dev = y - y.mean()
    den_theil = float(np.sqrt(np.mean(y * y)) + np.sqrt(np.mean(m * m)))
    ss_tot = float(np.sum(dev * dev))
    return FitMetrics(
        rmse=rmse,
        nrmse=rmse / span if span > 0 else float("inf"),
        theil_u=rmse / den_theil if den_theil > 0 else 0.0,
        fit_percent=100.0 * (1.0 - math.sqrt(sse / ss_tot)) if ss_tot > 0 else float("-inf"),
        r2=1.0 - sse / ss_tot if ss_tot > 0 else float("-inf"),
        max_error=float(np.max(np.abs(e))),
        n=int(y.size),
    )


def segment_metrics(measured: np.ndarray, model: np.ndarray, starts: np.ndarray) -> list[FitMetrics]:
    """:func:`fit_metrics` of each segment ``[starts[i], starts[i+1])`` of the series, vectorised with
    ``reduceat`` (a replay of a 5-minute log has hundreds of windows per signal); segments with a NaN fall
    back to :func:`fit_metrics`."""
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    starts = np.asarray(starts, dtype=int)
    if y.shape != m.shape:
        raise MetricsError(f"measured has {y.size} samples, model {m.size}: they must match")
    counts = np.diff(np.append(starts, y.size))
    if np.any(counts <= 0):
        raise MetricsError("segment starts must increase strictly and lie inside the series")
    finite = np.isfinite(y) & np.isfinite(m)
    e = np.where(finite, y - m, 0.0)
    yy, mm = np.where(finite, y, 0.0), np.where(finite, m, 0.0)
    sum_e2 = np.add.reduceat(e * e, starts)
    sum_y, sum_y2 = np.add.reduceat(yy, starts), np.add.reduceat(yy * yy, starts)
    sum_m2 = np.add.reduceat(mm * mm, starts)
    span = np.maximum.reduceat(yy, starts) - np.minimum.reduceat(yy, starts)
    max_err = np.maximum.reduceat(np.abs(e), starts)
    bad = np.add.reduceat(~finite, starts) > 0
    out = []
    for i, n in enumerate(counts):
        if bad[i]:
            a = starts[i]
            out.append(fit_metrics(y[a:a + n], m[a:a + n]))
            continue
        rmse = float(np.sqrt(sum_e2[i] / n))
        ss_tot = float(sum_y2[i] - sum_y[i] ** 2 / n)
        ss_tot = ss_tot if ss_tot > 1e-12 * max(float(sum_y2[i]), 1e-300) else 0.0
        den = float(np.sqrt(sum_y2[i] / n) + np.sqrt(sum_m2[i] / n))
        out.append(FitMetrics(
            rmse=rmse,
            nrmse=rmse / float(span[i]) if span[i] > 0 else float("inf"),
            theil_u=rmse / den if den > 0 else 0.0,
            fit_percent=100.0 * (1.0 - np.sqrt(sum_e2[i] / ss_tot)) if ss_tot > 0 else float("-inf"),
            r2=1.0 - float(sum_e2[i]) / ss_tot if ss_tot > 0 else float("-inf"),
            max_error=float(max_err[i]),
            n=int(n),
        ))
    return out


# --------------------------------------------------------------------------- baselines and skill
def skill(rmse_model: float, rmse_baseline: float) -> float:
    """``1 - RMSE_model / RMSE_baseline``: > 0 the model beats the baseline, 1 perfect, NaN when the baseline
    is exact (nothing to beat)."""
    if not (math.isfinite(rmse_model) and math.isfinite(rmse_baseline)) or rmse_baseline <= 0.0:
        return float("nan")
    return 1.0 - rmse_model / rmse_baseline


#: verdicts of a scored signal: beats persistence with confidence, loses or is inaccurate, beats it by a margin
#: that noise makes (the interval reaches zero), nothing to score
VERDICTS = ("pass", "FAIL", "tie", "n/a")


@dataclass(frozen=True)
class Score:
    """A model's fit beside its two baselines over the same samples: persistence (the logged value at the
    start of each replay window held over the window) and the window mean of the log (an oracle: it knows the
    window's data). ``verdict`` is one of :data:`VERDICTS`, with a plain-words ``reason``; ``interval`` is the
    block-bootstrap interval of the skill against persistence (pooled scores only)."""

    fit: FitMetrics
    rmse_persistence: float
    rmse_mean: float
    verdict: str = "n/a"
    reason: str = ""
    gated: bool = True
    interval: SkillInterval | None = None

    @property
    def skill_persistence(self) -> float:
        return skill(self.fit.rmse, self.rmse_persistence)

    @property
    def skill_mean(self) -> float:
        return skill(self.fit.rmse, self.rmse_mean)

    def as_dict(self) -> dict[str, Any]:
        return {**self.fit.as_dict(), "rmse_persistence": self.rmse_persistence, "rmse_mean": self.rmse_mean,
                "skill_persistence": self.skill_persistence, "skill_mean": self.skill_mean,
                "verdict": self.verdict, "reason": self.reason, "gated": self.gated,
                **({} if self.interval is None else {
                    "skill_persistence_lo": self.interval.lo, "skill_persistence_hi": self.interval.hi,
                    "skill_level": self.interval.level, "skill_blocks": self.interval.n_blocks,
                    "skill_outcome": self.interval.outcome})}


def window_baselines(measured: np.ndarray, starts: np.ndarray, init_values: np.ndarray) -> tuple[np.ndarray,
                                                                                                  np.ndarray]:
    """Persistence and window-mean series of ``measured`` for the segments ``[starts[i], starts[i+1])``:
    ``init_values[i]`` (the logged value at the window's re-initialisation) held, and the segment's mean."""
    y = np.asarray(measured, dtype=float).ravel()
    starts = np.asarray(starts, dtype=int)
    counts = np.diff(np.append(starts, y.size))
    finite = np.isfinite(y)
    n_finite = np.add.reduceat(finite.astype(float), starts)
    sums = np.add.reduceat(np.where(finite, y, 0.0), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = np.where(n_finite > 0, sums / np.maximum(n_finite, 1), np.nan)
    return np.repeat(np.asarray(init_values, dtype=float), counts), np.repeat(means, counts)


def segment_rmse(measured: np.ndarray, model: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """RMSE of each segment ``[starts[i], starts[i+1])`` over the samples finite in both (NaN if none)."""
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    finite = np.isfinite(y) & np.isfinite(m)
    e2 = np.where(finite, (y - m) ** 2, 0.0)
    n = np.add.reduceat(finite.astype(float), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(np.add.reduceat(e2, starts) / np.maximum(n, 1)), np.nan)


def rmse(measured: np.ndarray, model: np.ndarray) -> float:
    """RMSE over the samples finite in both (NaN if none)."""
    e = np.asarray(measured, dtype=float) - np.asarray(model, dtype=float)
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


# --------------------------------------------------------------------------- skill with a margin
#: skills within this of zero are the same RMSE (0.1 %), not a loss
SAME_SKILL = 1e-3

@dataclass(frozen=True)
class SkillInterval:
    """Skill of a model against a baseline, ``1 - RMSE_model / RMSE_baseline`` pooled over blocks, with its
    two-sided ``level`` block-bootstrap interval ``[lo, hi]`` (blocks resampled with replacement: windows of a
    replay, held-out flights or time blocks, so serial correlation inside a block is kept). ``outcome`` is
    ``lose`` when the skill is below ``-SAME_SKILL`` (the baseline's RMSE is lower on these data by more than
    0.1 %: the model is beaten, whatever the interval), ``win`` when the whole interval is above zero, else
    ``tie``: a difference that noise can make is not a win, and the same RMSE (a one-rule thrust map is the
    least-squares polynomial) is not a loss. ``identify thrust`` and ``identify aero`` decide by this rule;
    ``validate`` fails a signal whose skill is not above its configured ``min_skill_persistence`` (0 by
    default) and passes it only when this interval lies above that."""

    skill: float
    lo: float
    hi: float
    level: float
    n_blocks: int

    @property
    def outcome(self) -> str:
        if not math.isfinite(self.skill):
            return "tie"
        if self.skill < -SAME_SKILL:
            return "lose"
        return "win" if self.n_blocks >= 2 and self.lo > 0.0 else "tie"

    def as_dict(self) -> dict[str, Any]:
        return {"skill": self.skill, "skill_lo": self.lo, "skill_hi": self.hi, "level": self.level,
                "n_blocks": self.n_blocks, "outcome": self.outcome}


def overall_outcome(outcomes: list[str]) -> str:
    """One verdict over several skill outcomes (baselines, held-out sets): ``lose`` if any loses, ``win`` if all
    win, else ``tie``."""
    if "lose" in outcomes:
        return "lose"
    return "win" if outcomes and all(o == "win" for o in outcomes) else "tie"


def block_starts(n_samples: int, block_len: int) -> np.ndarray:
    """Starts of consecutive blocks of ``block_len`` samples covering ``n_samples`` (the last may be shorter)."""
    if n_samples < 1 or block_len < 1:
        raise MetricsError(f"block_starts needs n_samples >= 1 and block_len >= 1, got {n_samples}, {block_len}")
    return np.arange(0, n_samples, block_len, dtype=int)


def skill_interval(measured: np.ndarray, model: np.ndarray, baseline: np.ndarray, starts: np.ndarray,
                   level: float = 0.90, n_boot: int = 2000, seed: int = 0) -> SkillInterval:
    """Pooled skill of ``model`` against ``baseline`` over the blocks ``[starts[i], starts[i+1])`` with a
    block-bootstrap percentile interval (``n_boot`` resamples, 10..100000; deterministic for a ``seed``).
    Samples not finite in all three series are left out; blocks left empty are dropped."""
    if not 0.5 <= level < 1.0:
        raise MetricsError(f"level must lie in [0.5, 1), got {level}")
    if not 10 <= n_boot <= 100_000:
        raise MetricsError(f"n_boot must lie in [10, 100000], got {n_boot}")
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    b = np.asarray(baseline, dtype=float).ravel()
    if not (y.shape == m.shape == b.shape):
        raise MetricsError(f"measured, model and baseline have {y.size}, {m.size}, {b.size} samples: they must match")
    starts = np.asarray(starts, dtype=int)
    if starts.size == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0) or starts[-1] >= max(y.size, 1):
        raise MetricsError("block starts must begin at 0, increase strictly and lie inside the series")
    ok = np.isfinite(y) & np.isfinite(m) & np.isfinite(b)
    sse_m = np.add.reduceat(np.where(ok, (y - m) ** 2, 0.0), starts)
    sse_b = np.add.reduceat(np.where(ok, (y - b) ** 2, 0.0), starts)
    keep = np.add.reduceat(ok.astype(int), starts) > 0
    sse_m, sse_b = sse_m[keep], sse_b[keep]
    n_blocks = int(sse_m.size)
    nan = float("nan")
    if n_blocks == 0 or float(np.sum(sse_b)) <= 0.0:
        return SkillInterval(nan, nan, nan, level, n_blocks)
    point = 1.0 - math.sqrt(float(np.sum(sse_m)) / float(np.sum(sse_b)))
    if n_blocks < 2:
        return SkillInterval(point, nan, nan, level, n_blocks)
    idx = np.random.default_rng(seed).integers(0, n_blocks, size=(n_boot, n_blocks))
    num, den = sse_m[idx].sum(axis=1), sse_b[idx].sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        boot = np.where(den > 0, 1.0 - np.sqrt(num / np.where(den > 0, den, 1.0)), -np.inf)
    tail = 100.0 * (1.0 - level) / 2.0
    # order statistics, not interpolation: the interval is never narrower than the resamples say, and a
    # resample without any baseline error (-inf) gives lo = -inf instead of NaN (-inf - -inf)
    lo = np.percentile(boot, tail, method="lower")
    hi = np.percentile(boot, 100.0 - tail, method="higher")
    return SkillInterval(point, float(lo), float(hi), level, n_blocks)

"""PNG evidence plots for identification (matplotlib, Agg backend: no display needed).

Generic helpers (:func:`figure`, :func:`save`, :func:`scatter_fit`, :func:`learning_curve`,
:func:`time_overlay`, :func:`bar_values`) are shared by all identification code; the ``thrust_*`` functions
draw paper 000's Figs. 3-6 from them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

DPI = 110
FIGSIZE_IN = (7.0, 4.5)


def figure(nrows: int = 1, ncols: int = 1, **kwargs: Any) -> tuple[Any, Any]:
    """A new figure of the house size; returns ``(fig, axes)`` like ``plt.subplots``."""
    kwargs.setdefault("figsize", FIGSIZE_IN)
    kwargs.setdefault("layout", "constrained")
    return plt.subplots(nrows, ncols, **kwargs)


def save(fig: Any, path: str | Path) -> Path:
    """Write ``fig`` as PNG to ``path`` (parent folders created) and close it."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=DPI)
    plt.close(fig)
    return p


def scatter_fit(
    ax: Any,
    x: np.ndarray,
    y: np.ndarray,
    curves: Sequence[tuple[str, np.ndarray, np.ndarray]] = (),
    band: tuple[float, float] | None = None,
    label: str = "data",
) -> None:
    """Scatter of ``y`` over ``x`` with fitted ``curves`` (label, x, y) and a shaded trusted ``band``."""
    ax.plot(x, y, ".", ms=2.5, alpha=0.5, label=label, color="0.45")
    for name, cx, cy in curves:
        ax.plot(cx, cy, lw=2, label=name)
    if band is not None:
        ax.axvspan(band[0], band[1], color="tab:green", alpha=0.08, label="trained band")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def learning_curve(
    ax: Any, curves: Sequence[tuple[str, Sequence[float]]], best_epoch: int | None = None
) -> None:
    """Error per epoch (1-based on the axis) for each named curve; marks the kept epoch."""
    for name, values in curves:
        ax.plot(np.arange(1, len(values) + 1), values, lw=1.5, label=name)
    if best_epoch is not None:
        ax.axvline(best_epoch + 1, color="k", ls="--", lw=1, label=f"kept epoch {best_epoch + 1}")
    ax.set_xlabel("epoch")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def time_overlay(ax: Any, t_s: np.ndarray, series: Sequence[tuple[str, np.ndarray]]) -> None:
    """Several series over the same time axis [s]; gaps (NaN) break the lines."""
    for name, y in series:
        ax.plot(t_s, y, lw=1.0, label=name)
    ax.set_xlabel("time [s]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def bar_values(
    ax: Any, names: Sequence[str], values: Sequence[float], threshold: float | None = None
) -> None:
    """Horizontal bars (e.g. correlations) with an optional threshold line."""
    ypos = np.arange(len(names))
    ax.barh(
        ypos,
        values,
        color=["tab:blue" if (threshold is None or v >= threshold) else "tab:red" for v in values],
    )
    ax.set_yticks(ypos, names, fontsize=8)
    if threshold is not None:
        ax.axvline(threshold, color="k", ls="--", lw=1, label=f"gate {threshold:.2f}")
        ax.legend(loc="lower right", fontsize=8)
    ax.grid(True, axis="x", alpha=0.3)


def _with_gaps(t_s: np.ndarray, y: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert NaN where consecutive samples are more than 1.5 periods apart (segment breaks)."""
    breaks = np.flatnonzero(np.diff(t_s) > 1.5 * period_s) + 1
    return np.insert(t_s.astype(float), breaks, np.nan), np.insert(y.astype(float), breaks, np.nan)


# --------------------------------------------------------------------------- paper 000 figures
def thrust_correlation(
    path: str | Path,
    pwm_sum_us: np.ndarray,
    fz_N: np.ndarray,
    correlations: dict[str, float],
    threshold: float,
) -> Path:
    """Fig. 3: F_z against summed PWM, and the Pearson r of every candidate input against the gate."""
    fig, (ax1, ax2) = figure(1, 2, figsize=(11.0, 4.5))
    scatter_fit(
        ax1, pwm_sum_us, fz_N, label=f"samples (r = {correlations.get('pwm_sum_us', float('nan')):.3f})"
    )
    ax1.set_xlabel("summed motor PWM [us]")
    ax1.set_ylabel("F_z = -m a_z [N]")
    ax1.set_title("input-output correlation (paper 000 Fig. 3)")
    names = list(correlations)
    bar_values(ax2, names, [correlations[n] for n in names], threshold)
    ax2.set_xlabel("Pearson r with F_z")
    return save(fig, path)


def thrust_training(
    path: str | Path, train_rmse: Sequence[float], check_rmse: Sequence[float] | None, best_epoch: int
) -> Path:
    """Fig. 4: training and checking RMSE per epoch."""
    fig, ax = figure()
    curves = [("training RMSE", train_rmse)]
    if check_rmse is not None:
        curves.append(("checking RMSE", check_rmse))
    learning_curve(ax, curves, best_epoch)
    ax.set_ylabel("RMSE [N]")
    ax.set_title("ANFIS hybrid training (paper 000 Fig. 4)")
    return save(fig, path)


def thrust_validation(
    path: str | Path,
    t_s: np.ndarray,
    measured_N: np.ndarray,
    predicted_N: np.ndarray,
    period_s: float,
    title: str = "validation",
) -> Path:
    """Fig. 5: predicted and measured F_z over time on validation data."""
    fig, ax = figure(figsize=(10.0, 4.5))
    tm, ym = _with_gaps(t_s, measured_N, period_s)
    _, yp = _with_gaps(t_s, predicted_N, period_s)
    time_overlay(ax, tm, [("measured F_z", ym), ("ANFIS", yp)])
    ax.set_ylabel("F_z [N]")
    ax.set_title(f"{title} (paper 000 Fig. 5)")
    return save(fig, path)


def thrust_curve(
    path: str | Path,
    pwm_sum_us: np.ndarray,
    fz_N: np.ndarray,
    curves: Sequence[tuple[str, np.ndarray, np.ndarray]],
    band: tuple[float, float],
) -> Path:
    """Fig. 6: F_z versus summed PWM with the trained curve (and any reference curves)."""
    fig, ax = figure()
    scatter_fit(ax, pwm_sum_us, fz_N, curves, band)
    ax.set_xlabel("summed motor PWM [us]")
    ax.set_ylabel("F_z [N]")
    ax.set_title("thrust versus PWM (paper 000 Fig. 6)")
    return save(fig, path)


# --------------------------------------------------------------------------- paper 001 (output error)
def aero_overlay(path: str | Path, title: str, t_s: np.ndarray, measured: np.ndarray, model: np.ndarray,
                 outputs: Sequence[str], period_s: float, theil: dict[str, float] | None = None) -> Path:
    """Measured vs model per output over concatenated segments (paper 001 Fig. 1 is the roll angle)."""
    fig, axes = figure(len(outputs), 1, sharex=True, squeeze=False,
                       figsize=(FIGSIZE_IN[0], 1.0 + 1.7 * len(outputs)))
    for i, (ax, name) in enumerate(zip(axes[:, 0], outputs, strict=True)):
        tm, ym = _with_gaps(t_s, measured[:, i], period_s)
        _, yp = _with_gaps(t_s, model[:, i], period_s)
        ax.plot(tm, ym, lw=1.0, color="0.3", label="log")
        ax.plot(tm, yp, lw=1.2, color="tab:red", label="model")
        u = f"  (Theil U {theil[name]:.3f})" if theil and name in theil else ""
        ax.set_ylabel(name, fontsize=8)
        ax.set_title(f"{name}{u}", fontsize=9)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("log time [s]")
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def aero_residuals(path: str | Path, t_s: np.ndarray, residuals: np.ndarray, outputs: Sequence[str],
                   period_s: float) -> Path:
    """Output residuals (log - model) per output, over the fit segments."""
    fig, axes = figure(len(outputs), 1, sharex=True, squeeze=False,
                       figsize=(FIGSIZE_IN[0], 1.0 + 1.4 * len(outputs)))
    for i, (ax, name) in enumerate(zip(axes[:, 0], outputs, strict=True)):
        tm, r = _with_gaps(t_s, residuals[:, i], period_s)
        ax.plot(tm, r, lw=0.8, color="tab:purple")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(name, fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("log time [s]")
    fig.suptitle("residuals on the fit segments", fontsize=10)
    return save(fig, path)


def aero_parameters(path: str | Path, names: Sequence[str], start: np.ndarray, estimate: np.ndarray,
                    crb_std: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> Path:
    """Each estimate with its 2-sigma Cramér-Rao bar, its start value and its bounds, scaled by |start|."""
    scale = np.where(np.abs(start) > 1e-12, np.abs(start), 1.0)
    y = np.arange(len(names))
    fig, ax = figure(figsize=(FIGSIZE_IN[0], 1.2 + 0.35 * len(names)))
    ax.errorbar(estimate / scale, y, xerr=2 * crb_std / scale, fmt="o", color="tab:blue", capsize=3,
                label="estimate ± 2 CR std")
    ax.plot(start / scale, y, "x", color="0.4", label="start")
    for k in range(len(names)):
        for b in (lower[k], upper[k]):
            if np.isfinite(b):
                ax.plot([b / scale[k]] * 2, [k - 0.3, k + 0.3], color="tab:red", lw=2)
    ax.set_yticks(y, names, fontsize=8)
    ax.set_xlabel("value / |start value|  (red: bounds)")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return save(fig, path)

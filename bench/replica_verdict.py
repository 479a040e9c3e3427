"""Verdicts of replica benches that know how far their own draws can see.

A replica bench estimates, from a finite number of draws, an interval's coverage and its width over the actual
error. An interval that is exactly right covers 95 % and has a half-width of 1.96x the RMS error (2.91x the
median error), which is where the targets sit (coverage >= 0.90, half-width <= 2x the RMS error, <= 3x the
median error): over 20 draws a right interval shows a coverage below 0.90 in 7.5 % of the runs per parameter,
and a width ratio above 2 in about 45 % (the RMS of 20 errors scatters by 16 %). A point figure past its target
is therefore a finding only when the draws show it: a coverage whose one-sided 95 % Clopper-Pearson upper bound
lies below the target; a ratio whose one-sided 95 % lower bound (the error's scale at its upper bound,
:func:`width_figure`) lies above it. A point figure past its target that the draws cannot tell from it is
printed as unresolved, and is not called met. Measured on simulated draws (tests/bench): a right interval is
called a miss in 3 % of 20-draw runs; one 1.6x too wide in 80 % (RMS target).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: one-sided confidence of a shown miss
LEVEL = 0.95


@dataclass(frozen=True)
class Figure:
    """One target's figure: the point value, its one-sided Monte Carlo bound (the end towards the target) and
    the verdict: "met" (point value meets the target), "miss" (the draws show the miss) or "unresolved"."""

    value: float
    bound: float
    verdict: str

    def text(self, fmt: str = ".2f") -> str:
        mark = {"met": "", "miss": " MISS", "unresolved": " (unresolved)"}[self.verdict]
        return f"{self.value:{fmt}} [{self.bound:{fmt}}]{mark}"


def coverage_figure(covered: np.ndarray, target: float) -> Figure:
    """Coverage of ``covered`` (booleans, one per draw) against ``target`` (at least): the bound is the one-sided
    Clopper-Pearson upper bound at :data:`LEVEL`."""
    from scipy.stats import beta

    n, k = len(covered), int(np.sum(covered))
    upper = 1.0 if k == n else float(beta.ppf(LEVEL, k + 1, n - k))
    value = k / n
    verdict = "met" if value >= target else ("miss" if upper < target else "unresolved")
    return Figure(value, upper, verdict)


def width_figure(half_width: np.ndarray, error: np.ndarray, target: float, stat: str = "rms") -> Figure:
    """Median half-width over the RMS (``stat="rms"``) or median (``"median"``) absolute error, against ``target``
    (at most). The bound divides the median half-width by a one-sided :data:`LEVEL` upper bound of the error's
    scale: for the median the order statistic that bounds it without assuming a distribution (the binomial), for
    the RMS the chi-square bound of normal errors (``rms sqrt(n / chi2_{1-LEVEL}(n))``)."""
    from scipy.stats import binom, chi2

    hw, err = np.asarray(half_width, float), np.sort(np.abs(np.asarray(error, float)))
    n = len(err)
    if stat == "rms":
        scale = math.sqrt(float(np.mean(err ** 2)))
        upper = scale * math.sqrt(n / float(chi2.ppf(1.0 - LEVEL, n)))
    else:
        scale = float(np.median(err))
        j = int(np.searchsorted(binom.cdf(np.arange(n + 1), n, 0.5), LEVEL))  # P(#errors below e_(j+1)) >= LEVEL
        upper = float(err[min(j, n - 1)])
    value = float(np.median(hw)) / max(scale, 1e-300)
    lower = float(np.median(hw)) / max(upper, 1e-300)
    verdict = "met" if value <= target else ("miss" if lower > target else "unresolved")
    return Figure(value, lower, verdict)


def draw_width_figure(half_width: np.ndarray, error: np.ndarray, target: float, stat: str = "rms") -> Figure:
    """:func:`width_figure` of draws that each have their own truth and interval scale: each draw's error is taken
    in its own interval's units, ``z = 1.96 |error| / half-width``, so the figure is ``1.96 / median |z|``
    (``stat="median"``) or ``1.96 / rms z`` (``"rms"``), the same as the plain ratio when every draw shares one
    scale. A plain median half-width over the median (or RMS) error of unlike draws mixes their scales, which is
    not one distribution's scatter."""
    hw = np.asarray(half_width, float)
    z = 1.96 * np.abs(np.asarray(error, float)) / np.maximum(hw, 1e-300)
    return width_figure(np.full(len(z), 1.96), z, target, stat=stat)


def overall(figures: list[Figure]) -> str:
    """"met" when every figure is, "miss" when any draws show a miss, else "unresolved"."""
    verdicts = {f.verdict for f in figures}
    return "miss" if "miss" in verdicts else ("unresolved" if "unresolved" in verdicts else "met")

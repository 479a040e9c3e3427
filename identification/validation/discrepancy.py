"""The model's discrepancy: how far an FMU replay is from the log, learned where the truth is known.

A Monte Carlo band over the identified parameters alone covers a fraction of a real flight (on the Erle
quadrotor, 18-35 % of the samples of a 90 % band): the model's own error, which dominates a replay, is in no
parameter. This module learns that error from replays of flights the model is meant to explain (the
identification flights, or better flights left out of the identification) and stores it in the parameter file
beside the covariance (``discrepancy``, :class:`fmu_models.common.params.Discrepancy`); ``validate --mc``
convolves the parameter draws with it (``mc_bands.mixture_band``: the discrepancy's whole distribution, at
evenly spread levels, around every draw), so the band is parameters + discrepancy + sensor noise.

**Method: empirical quantiles of the scaled residual per signal and horizon bin, symmetric about the FMU.** The
residual is logged - FMU, the horizon the time since the replay window restarted from the logged state, and the
scale one of (per signal, :func:`learn` keeps a scaled form only where its band scores better than the unscaled
one on every learning replay left out in turn, by the interval score, and on more of their windows than chance
gives; with one replay the narrowest):
none; ``|FMU(t) - FMU(t0)| + floor``, how far the model itself moved since the window's first sample;
``|FMU(t)| + floor``, the output's size; ``|dFMU/dt| + floor``, how fast it changes (a small lag or phase error
of the model) - each floor the mean of its basis over the learning replays, and the scale held at the 99th
percentile of the learning residuals' scales (``scale_max``: the quantiles say nothing of larger ones). The same
procedure for every signal, no per-signal factor. Chosen over an AR model or a Gaussian process because the
replay error of an open-loop unstable vehicle is not Gaussian or stationary: it grows with the horizon and is
heavy-tailed (a few windows with a manoeuvre carry most of the error). Quantiles need no distribution, cost
nothing to evaluate and say how many samples they rest on; the horizon bins carry the growth, the scale the state.

**Symmetric unless the sign carries**: the residuals enter with both signs (a band centred on the FMU) unless,
each learning replay left out in turn, the band keeping their sign covers the left-out replays as well as the
symmetric one (within ``SIGN_TOLERANCE``; never with a single replay); per signal the narrowest form is then kept.
Measured on the two PX4 csv flights (``bench/prediction_bands.py``): the sign of a replay's drift does not carry
from one flight to the next (the x body rate's residual, 5-95 %, is -1.79..+6.51 rad/s on drone1-10 and
-3.30..+0.95 rad/s on drone1-8), and bands keeping the other flight's sign covered 74-79 % of roll, x rate and
thrust; on the Erle flights the thrust's sign does carry between two of them, and an always-symmetric band was
4.23x its RMSE wide (docs/validation.md#prediction-bands).

**Centred on a bias where one carries**: a symmetric band is centred on the residuals' median at the restart
(:func:`restart_offset`, the first horizon bin, where the model's dynamics have not yet erred: a sensor's
calibration the FMU does not have) where, each learning replay left out in turn, that band scores better than the
band centred on the FMU on every replay left out and on more of their windows than chance gives. One number per
signal, read where no drift is: on the fixed-wing excitation log the logged airspeed is 0.25 % above the FMU's from
the restart on (ArduPilot's SITL pitot ratio 1.99 read with ``ARSPD_RATIO`` 2.0), and a band centred on the FMU had
to straddle that offset.

The residuals are against the logged, noisy signal, so they carry the sensor noise too: a signal with a
discrepancy gets no second white-noise term in the Monte Carlo. The scale and the quantile lookup are
``fmu_models.common.params.discrepancy_scale`` / ``discrepancy_quantile``, shared with the HIL record's band.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.params import (
    Discrepancy,
    SignalDiscrepancy,
    discrepancy_bins,
    discrepancy_of,
    discrepancy_scale,
    read_json,
)
from identification.validation.replay import ReplayResult, ValidationInputError

#: quantile levels stored per horizon bin: dense in the tails a 90 % band reads
LEVELS = (0.005, 0.01, 0.025, 0.05, 0.075, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.925, 0.95, 0.975, 0.99,
          0.995)
N_BINS = 10  #: horizon bins over a window (full-length replays: over the longest horizon)
MIN_BIN_SAMPLES = 20  #: a horizon bin with fewer residuals is merged into its neighbour
#: the residual's sign is kept unless dropping it raises the coverage of the replays left out in turn by more than
#: this (two points: about the scatter of a pooled coverage of a few thousand autocorrelated samples)
SIGN_TOLERANCE = 0.02
#: a scaled band form is kept only where it beats the unscaled one on more replay windows left out than chance
#: gives at this one-sided level, over the scaled forms tried (:func:`scale_carries`)
SCALE_EVIDENCE = 0.05
#: a scaled table's scale is held at this quantile of the learning residuals' scales (``scale_max``): the
#: quantiles say nothing of larger scales, and the maximum of a slope is one sample's spike
SCALE_HELD_AT = 0.99


def window_index(res: ReplayResult) -> np.ndarray:
    """Per sample of ``res.t_s``: the index of its replay window (a window's end sample belongs to it)."""
    starts = np.array([a for a, _ in res.windows], dtype=float)
    return np.clip(np.searchsorted(starts, np.asarray(res.t_s, float), side="left") - 1, 0, len(starts) - 1)


def horizons_s(res: ReplayResult) -> np.ndarray:
    """Per sample of ``res.t_s``: time [s] since its replay window restarted from the logged state (a window's
    end sample belongs to it, not to the next window, which restarts there)."""
    starts = np.array([a for a, _ in res.windows], dtype=float)
    return np.asarray(res.t_s, dtype=float) - starts[window_index(res)]


def residuals(res: ReplayResult, name: str) -> np.ndarray:
    """Logged minus FMU of signal ``name`` on ``res.t_s`` (NaN where not scored; angles wrapped to +-pi)."""
    m = next(x for x in res.maps if x.fmu == name)
    r = np.asarray(res.measured[name], float) - np.asarray(res.model[name], float)
    return (r + math.pi) % (2.0 * math.pi) - math.pi if m.wrap else r


def window_first(res: ReplayResult, name: str) -> np.ndarray:
    """Per sample of ``res.t_s``: the FMU output of signal ``name`` at its window's first scored sample (NaN where
    the window has none)."""
    mod = np.asarray(res.model[name], float)
    idx = window_index(res)
    first = np.full(len(res.windows), np.nan)
    ok = np.flatnonzero(np.isfinite(mod))
    if ok.size:
        w, pos = np.unique(idx[ok], return_index=True)  # the first finite sample of each window
        first[w] = mod[ok[pos]]
    return first[idx]


def slope_of(res: ReplayResult, name: str) -> np.ndarray:
    """Per sample of ``res.t_s``: |dFMU/dt| [unit/s] of signal ``name``, the backward difference inside the
    sample's window (a window's first sample: the forward one; an angle the short way round)."""
    m = next(x for x in res.maps if x.fmu == name)
    mod = np.asarray(res.model[name], float)
    t = np.asarray(res.t_s, float)
    if mod.size < 2:
        return np.zeros_like(mod)
    d = np.diff(mod)
    if m.wrap:
        d = (d + math.pi) % (2.0 * math.pi) - math.pi
    d = d / np.diff(t)
    back = np.r_[np.nan, d]
    idx = window_index(res)
    new_window = np.r_[True, idx[1:] != idx[:-1]] | ~np.isfinite(back)
    fwd = np.r_[d, np.nan]
    return np.abs(np.where(new_window, fwd, back))


def scale_of(res: ReplayResult, name: str, s: SignalDiscrepancy) -> np.ndarray:
    """Per sample of ``res.t_s``: what the quantiles of ``s`` multiply (``fmu_models.common.params.
    discrepancy_scale``: 1, or its basis + floor; NaN where the FMU output is not scored)."""
    return discrepancy_scale(s, np.asarray(res.model[name], float), window_first(res, name), slope_of(res, name))


def _edges(h: np.ndarray, span_s: float) -> np.ndarray:
    """Horizon bin edges over [0, span]: ``N_BINS`` equal bins, merged until each holds ``MIN_BIN_SAMPLES``."""
    edges = list(np.linspace(0.0, span_s, N_BINS + 1))
    edges[-1] = span_s + 1e-9
    while len(edges) > 2:
        counts = np.histogram(h, bins=edges)[0]
        low = int(np.argmin(counts))
        if counts[low] >= MIN_BIN_SAMPLES:
            break
        drop = low + 1 if low == 0 else low  # merge with the neighbour: drop one of its edges
        del edges[min(drop, len(edges) - 2)]
    return np.asarray(edges)


def _fit(results: Sequence[ReplayResult], name: str, form: SignalDiscrepancy, window_s: float,
         signed: bool = False, offset: bool = False) -> tuple[SignalDiscrepancy, float] | None:
    """The quantile table of signal ``name`` in the form of ``form`` (its scale basis and floor; its quantiles
    are ignored) and the mean width of its 90 % band over the learning samples (None: too few samples). The
    residuals enter with both signs (the band symmetric about the FMU) unless ``signed``; with ``offset`` (and not
    ``signed``) symmetric about the residuals' median at the restart (:func:`restart_offset`) instead. A scaled
    table holds its scale at the ``SCALE_HELD_AT`` quantile of the learning residuals' scales (``scale_max``),
    learning too."""
    form = form.model_copy(update={"scale_max": None, "offset": None})
    hs, es, ss = [], [], []
    for res in results:
        scale = scale_of(res, name, form)
        err = residuals(res, name)
        ok = np.isfinite(err) & np.isfinite(scale)
        hs.append(horizons_s(res)[ok])
        es.append(err[ok])
        ss.append(scale[ok])
    h, err, sc = np.concatenate(hs), np.concatenate(es), np.concatenate(ss)
    if err.size < MIN_BIN_SAMPLES:
        return None
    held = None if form.scale_floor is None else float(np.quantile(sc, SCALE_HELD_AT))
    if held is not None:
        sc = np.minimum(sc, held)  # as discrepancy_scale holds it wherever the table is used
    r = err / sc
    edges = _edges(h, window_s if window_s > 0 else float(h.max()))
    centre = restart_offset(r, h, edges) if offset and not signed else 0.0
    r = r - centre
    rows, counts, width = [], [], 0.0
    i5, i95 = LEVELS.index(0.05), LEVELS.index(0.95)
    for a, b in itertools.pairwise(edges):
        sel = (h >= a) & (h < b)
        counts.append(int(sel.sum()))
        both = r[sel] if signed else np.concatenate([r[sel], -r[sel]])
        q = [float(v) for v in np.quantile(both, LEVELS)] if sel.any() else [0.0] * len(LEVELS)
        if not signed:
            q = [0.5 * (v - w) + centre for v, w in zip(q, q[::-1], strict=True)]  # antisymmetric about it
        rows.append(q)
        width += float(np.sum((q[i95] - q[i5]) * sc[sel]))
    table = form.model_copy(update={"horizon_edges_s": [float(e) for e in edges], "quantiles": rows,
                                    "samples": counts, "symmetric": not signed, "scale_max": held,
                                    "offset": centre if offset and not signed else None})
    return table, width / r.size


def restart_offset(r: np.ndarray, h: np.ndarray, edges: np.ndarray) -> float:
    """The median of the (scaled) residuals ``r`` in the first horizon bin of ``edges`` (``h`` [s] since the
    window's restart from the logged state): at the restart the model's own dynamics have had no time to err, so
    what is left there is a bias the FMU does not have, e.g. an airspeed sensor's calibration (ArduPilot's SITL
    simulates its pitot with ``SIM_ARSPD_RATIO`` 1.99 and reads it with ``ARSPD_RATIO`` 2.0: 0.25 % high)."""
    first = r[h < edges[1]]
    return float(np.median(first)) if first.size else 0.0


def band_on(table: SignalDiscrepancy, res: ReplayResult, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The 5 and 95 % of ``table`` (scaled as it says) per sample of ``res``, as residuals logged - FMU of signal
    ``name`` (NaN where the FMU output is not scored)."""
    q = np.asarray(table.quantiles)[discrepancy_bins(table, horizons_s(res))]
    scale = scale_of(res, name, table)
    return q[:, LEVELS.index(0.05)] * scale, q[:, LEVELS.index(0.95)] * scale


def _covered(table: SignalDiscrepancy, res: ReplayResult, name: str) -> tuple[int, int]:
    """Samples of ``res`` whose residual lies in the 5-95 % of ``table`` (scaled as it says), and samples scored."""
    lo, hi = band_on(table, res, name)
    r = residuals(res, name)
    ok = np.isfinite(r) & np.isfinite(lo)
    inside = (r[ok] >= lo[ok]) & (r[ok] <= hi[ok])
    return int(inside.sum()), int(ok.sum())


def sign_carries(results: Sequence[ReplayResult], name: str, form: SignalDiscrepancy, window_s: float) -> bool:
    """Whether the residual's sign carries from replay to replay: each replay left out in turn, the signed band
    learned on the others (same form) covers the left-out samples, pooled, within ``SIGN_TOLERANCE`` of what the
    symmetric band learned on them covers (dropping the sign would buy no coverage, only width). Never with one
    replay: nothing shows it, and the symmetric band is the safe side."""
    if len(results) < 2:
        return False
    counts = {True: [0, 0], False: [0, 0]}
    for i, res in enumerate(results):
        others = [x for j, x in enumerate(results) if j != i]
        for signed in (True, False):
            fit = _fit(others, name, form, window_s, signed=signed)
            if fit is None:
                return False
            a, n = _covered(fit[0], res, name)
            counts[signed][0] += a
            counts[signed][1] += n
    if not counts[True][1]:
        return False
    return counts[True][0] / counts[True][1] >= counts[False][0] / counts[False][1] - SIGN_TOLERANCE


def interval_score(r: np.ndarray, lo: np.ndarray, hi: np.ndarray, level: float = 0.90) -> tuple[float, int]:
    """Summed interval score of the central ``level`` bands [lo, hi] for the values ``r`` (NaN skipped), and the
    samples scored: width + (2 / alpha) x how far a value falls outside (alpha = 1 - level; Gneiting & Raftery
    2007, a proper score: lowest in expectation for the true quantiles, so it trades width against coverage
    and neither a band too wide nor one too narrow wins)."""
    per_sample = interval_scores(r, lo, hi, level)
    ok = np.isfinite(per_sample)
    return float(np.sum(per_sample[ok])), int(ok.sum())


def interval_scores(r: np.ndarray, lo: np.ndarray, hi: np.ndarray, level: float = 0.90) -> np.ndarray:
    """Per value of ``r``, the interval score of :func:`interval_score` (NaN where ``r``, ``lo`` or ``hi`` is)."""
    miss = np.maximum(lo - r, 0.0) + np.maximum(r - hi, 0.0)
    return np.asarray(hi - lo + 2.0 / (1.0 - level) * miss, float)


def refit(results: Sequence[ReplayResult], name: str, like: SignalDiscrepancy,
          window_s: float) -> SignalDiscrepancy | None:
    """Signal ``name``'s quantile table learned anew on ``results`` in the form of ``like`` (scale basis, floor,
    sign; its other fields kept); None with too few samples."""
    fit = _fit(results, name, like, window_s, signed=not like.symmetric, offset=like.offset is not None)
    return None if fit is None else fit[0]


def held_out_score(results: Sequence[ReplayResult], name: str, form: SignalDiscrepancy, window_s: float,
                   signed: bool, offset: bool = False) -> tuple[list[float], np.ndarray]:
    """Each replay of ``results`` scored by the 90 % band of ``form`` learned on the others: per replay the mean
    interval score (:func:`interval_score`), and per replay window (all replays' windows in order) its mean
    interval score (NaN where the window has no scored sample); ``([], empty)`` with fewer than two replays or too
    few samples."""
    none: tuple[list[float], np.ndarray] = ([], np.zeros(0))
    if len(results) < 2:
        return none
    out, windows = [], []
    for i, res in enumerate(results):
        fit = _fit([x for j, x in enumerate(results) if j != i], name, form, window_s, signed=signed,
                   offset=offset)
        if fit is None:
            return none
        per_sample = interval_scores(residuals(res, name), *band_on(fit[0], res, name))
        ok = np.isfinite(per_sample)
        if not ok.any():
            return none
        out.append(float(np.mean(per_sample[ok])))
        idx = window_index(res)[ok]
        count = np.bincount(idx, minlength=len(res.windows))
        summed = np.bincount(idx, weights=per_sample[ok], minlength=len(res.windows))
        windows.append(np.where(count > 0, summed / np.maximum(count, 1), math.nan))
    return out, np.concatenate(windows) if windows else np.zeros(0)


def offset_carries(results: Sequence[ReplayResult], name: str, form: SignalDiscrepancy, window_s: float) -> bool:
    """Whether the residual's offset at the restart (:func:`restart_offset`) carries from replay to replay: each
    learning replay left out in turn, the band centred on the others' offset scores better (interval score) than
    the band centred on the FMU on every replay left out and on more of their windows than chance gives
    (:func:`scale_carries`). Never with one replay. One number per signal, read where the dynamics have not yet
    erred: a bias, not the drift a signed band would fit (whose sign does not carry from flight to flight)."""
    if len(results) < 2:
        return False
    shifted, shifted_windows = held_out_score(results, name, form, window_s, False, offset=True)
    centred, centred_windows = held_out_score(results, name, form, window_s, False)
    return bool(shifted) and len(shifted) == len(centred) and all(
        a < b for a, b in zip(shifted, centred, strict=True)) and scale_carries(shifted_windows, centred_windows, 1)


def scale_carries(scaled: np.ndarray, unscaled: np.ndarray, forms: int) -> bool:
    """Whether a scaled form's band beats the unscaled one on more replay windows left out than chance gives: the
    one-sided sign test of its per-window interval scores against the unscaled form's (:func:`held_out_score`)
    at :data:`SCALE_EVIDENCE` over the ``forms`` scaled forms tried (Bonferroni)."""
    from scipy.stats import binom

    ok = np.isfinite(scaled) & np.isfinite(unscaled)
    n = int(ok.sum())
    wins = int(np.sum(scaled[ok] < unscaled[ok]))
    return n > 0 and float(binom.sf(wins - 1, n, 0.5)) <= SCALE_EVIDENCE / max(forms, 1)


def learn(results: Sequence[ReplayResult], logs: Sequence[str], note: str = "",
          scaled: bool = True) -> Discrepancy:
    """The discrepancy of the replays ``results`` (same FMU, same options), pooled per signal and horizon bin.
    Per signal the form is unscaled, or scaled by the departure, the magnitude or the slope (:func:`scale_of`);
    each form's band keeps the residual's sign where it carries (:func:`sign_carries`), else is centred on the
    offset at the restart where that carries (:func:`offset_carries`), else on the FMU.
    With two replays or more, each left out in turn, a scaled form is kept only where its band scores better
    than the unscaled one (mean interval score, :func:`held_out_score`) on every replay left out and on more of
    their replay windows than chance gives (:func:`scale_carries`: the fourteen 2 s windows of two 12 s segments, as
    the fixed-wing bench learns on, can hardly show it; flights of hundreds of windows can), the best such; else
    the unscaled form. With one replay nothing is left to score on: the form whose band is narrowest on it
    (every form covers its learning samples at its level by construction; the scale helps where the error
    follows the model's own motion, e.g. a diverging attitude, not where it does not, e.g. vibration on a
    thrust measured at the PWM rate). Why not the narrowest, or the best pooled score, always: with two or three
    replays a scaled form that is narrow on them is often wide on the next (docs/validation.md#prediction-bands).
    ``scaled=False``: the unscaled form only (a study of the choice)."""
    if not results:
        raise ValidationInputError("discrepancy: no replay to learn from")
    first = results[0]
    window_s = float(first.options.get("window_s", 0.0))
    rate_hz = float(first.options.get("rate_hz", 50.0))
    signals: dict[str, SignalDiscrepancy] = {}
    one = {"horizon_edges_s": [0.0, 1.0], "quantiles": [[0.0] * len(LEVELS)], "samples": [0]}
    for m in first.maps:
        forms = [SignalDiscrepancy(**one, wrap=m.wrap)]
        for basis in ("departure", "magnitude", "slope") if scaled else ():
            raw = SignalDiscrepancy(**one, scale_floor=1.0, scale_by=basis, wrap=m.wrap)
            b = np.concatenate([scale_of(res, m.fmu, raw) - 1.0 for res in results])
            floor = float(np.nanmean(b)) if np.isfinite(b).any() else 0.0
            if floor > 0.0:
                forms.append(raw.model_copy(update={"scale_floor": floor}))
        scored = []
        for form in forms:
            signed = sign_carries(results, m.fmu, form, window_s)
            offset = not signed and offset_carries(results, m.fmu, form, window_s)
            fit = _fit(results, m.fmu, form, window_s, signed, offset)
            if fit is not None:
                scored.append((held_out_score(results, m.fmu, form, window_s, signed, offset), fit[1], fit[0]))
        if scored and len(results) >= 2 and scored[0][2].scale_floor is None and scored[0][0][0]:
            (base, base_windows), tried = scored[0][0], len(scored) - 1  # the unscaled form's, replay by replay
            better = [f for f in scored[1:] if len(f[0][0]) == len(base) and all(
                a < b for a, b in zip(f[0][0], base, strict=True))
                and scale_carries(f[0][1], base_windows, tried)]
            signals[m.fmu] = min(better, key=lambda f: sum(f[0][0]))[2] if better else scored[0][2]
        elif scored:
            signals[m.fmu] = min(scored, key=lambda f: f[1])[2]
    if not signals:
        raise ValidationInputError(f"discrepancy: fewer than {MIN_BIN_SAMPLES} scored samples in every signal")
    return Discrepancy(levels=list(LEVELS), signals=signals, window_s=window_s, rate_hz=rate_hz,
                       start_velocity=first.options.get("start_velocity"),
                       logs=[str(x) for x in logs], note=note or (
                           "empirical quantiles of logged - FMU (with both signs about the offset at the restart, "
                           "else 0, where symmetric) per horizon bin, "
                           "where scale_floor is given "
                           "divided by (|FMU - FMU at the window start| or |FMU|, per scale_by, + scale_floor) "
                           "(identification.validation.discrepancy); learned from replays of the listed logs"))


def points(levels: Sequence[float], s: SignalDiscrepancy, h_s: np.ndarray, count: int,
           scale: np.ndarray) -> np.ndarray:
    """``count`` x len(``h_s``): the discrepancy ``s`` at the levels (k + 1/2) / ``count`` (linear between the
    stored ``levels``, the outer stored quantile beyond them) at horizons ``h_s`` [s], times ``scale``
    (:func:`scale_of`: ones when its quantiles are of the residual itself): a deterministic sample of its
    distribution, for a band computed without Monte Carlo noise."""
    lv = np.asarray(levels, float)
    u = (np.arange(count) + 0.5) / count
    q = np.asarray(s.quantiles)
    table = np.array([np.interp(u, lv, row) for row in q])  # bins x count
    out = table[discrepancy_bins(s, h_s)].T
    return out * np.asarray(scale, float)


@dataclass(frozen=True)
class DiscrepancyResult:
    """What :func:`learn_discrepancy` learned, from which replays, and where it was written."""

    discrepancy: Discrepancy
    replays: tuple[dict[str, Any], ...]
    written: Path | None = None

    def lines(self) -> list[str]:
        d = self.discrepancy
        out = [f"discrepancy learned from {len(self.replays)} replay(s) ({d.window_s:g} s windows, {d.rate_hz:g} Hz):"]
        i5, i95 = d.levels.index(0.05), d.levels.index(0.95)
        for name, s in d.signals.items():
            first, last = s.quantiles[0], s.quantiles[-1]
            what = ("logged - FMU" if s.scale_floor is None
                    else f"(logged - FMU) / ({s.scale_by} + {s.scale_floor:.3g})")
            out.append(f"  {name:<18} 5-95 % of {what}: [{first[i5]:+.3g}, {first[i95]:+.3g}] at "
                       f"{s.horizon_edges_s[0]:g}-{s.horizon_edges_s[1]:.2g} s, [{last[i5]:+.3g}, {last[i95]:+.3g}] at "
                       f"{s.horizon_edges_s[-2]:.2g}-{s.horizon_edges_s[-1]:.2g} s ({sum(s.samples)} samples)"
                       + (f"; centred on the restart's offset {s.offset:+.3g}" if s.offset is not None else "")
                       + (f"; band factor {s.band_factor:.3g}" if s.band_factor is not None else "")
                       + ("; the discrepancy alone (parameter draws left out)" if s.parameter_weight == 0.0 else ""))
        if self.written:
            out.append(f"written to {self.written} (key 'discrepancy', beside 'uncertainty')")
        return out


def write_discrepancy(path: Path, disc: Discrepancy) -> None:
    """Store ``disc`` in the JSON parameter file ``path`` under ``discrepancy`` (the rest kept as it is)."""
    from identification.common.jsonio import write_json

    if Path(path).suffix.lower() != ".json":
        raise ValidationInputError(f"{path}: the discrepancy is written into a JSON parameter file (.json)")
    data = read_json(path)
    data["discrepancy"] = json.loads(disc.model_dump_json())
    discrepancy_of(data, str(path))  # what is written reads back
    write_json(Path(path), data)


def read_discrepancy(path: Path | None, fmu: Path | None = None) -> Discrepancy | None:
    """The ``discrepancy`` block of ``path``, else of the parameter file embedded in ``fmu`` (``build --params``);
    None when there is none."""
    if path is not None:
        return discrepancy_of(read_json(path), str(path))
    if fmu is None:
        return None
    from fmu_models.fmi.fmuzip import embedded_params

    found = embedded_params(Path(fmu))
    return None if found is None else discrepancy_of(*found)

"""Monte Carlo bands of a replay: how far it can be trusted given the identified parameters' uncertainty.

Each of N draws replays the log's windows with

* parameters drawn from the identified estimate and covariance (the parameter file's ``uncertainty`` block,
  :class:`fmu_models.common.params.Uncertainty`),
* each window's restart state drawn around the logged state with that signal's sensor noise (a restart from a
  noisy logged attitude or rate is uncertain by that noise), and
* the compared output plus white noise of the logged signal's sensor noise (the log is measured, the model
  predicts the truth),

and the 5-95 % band per sample is taken over the draws. Sensor noise (1 sigma) is estimated from each logged
signal alone, model-free: the median absolute deviation of its second differences, / sqrt(6) (white noise on
a signal smooth at the sample rate). A band's *coverage* is the fraction of the scored logged samples inside
it: about 90 % when the model and its stated uncertainty explain the log, well below when they do not. A
coverage past ``MIN_COVERAGE`` or ``MAX_COVERAGE`` is a finding when the replay's windows show it
(:func:`coverage_bounds`), else ``unresolved``.

Draw ``k`` is seeded by (seed, k) alone (``identification.common.parallel.task_rng``): the bands are the same bit for
bit
whichever worker runs which draw. Draws run in chunks as tasks of ``identification.common.parallel``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from fmu_models.common.params import Discrepancy, Uncertainty
from identification.validation.replay import ReplayResult, ValidationInputError

if TYPE_CHECKING:
    from identification.common.parallel import Executor
    from identification.logs.flightlog import FlightLog
    from identification.validation.job import ValidationJob
    from identification.validation.output_map import SignalMap

MAX_DRAWS = 10_000
#: fewest draws whose order statistics bound a 5-95 % band (:func:`band_ranks`)
MIN_DRAWS = 19
BAND = (0.05, 0.95)
#: a 90 % band covering less than this of the logged samples: the model, or its stated uncertainty, does not
#: explain the log (a sample-fraction has scatter: with autocorrelated residuals a few points below 90 % are
#: normal)
MIN_COVERAGE = 0.80
#: covering more than this: the band is wider than the log's scatter (the uncertainty is overstated)
MAX_COVERAGE = 0.98
#: one-sided confidence with which a coverage past ``MIN_COVERAGE`` or ``MAX_COVERAGE`` must be shown by the
#: replay's windows before it is a finding (:func:`coverage_bounds`)
VERDICT_LEVEL = 0.95
#: restart-state variables and the logged signal whose noise they carry (velocity: see ``_state_noise``)
STATE_SIGNALS = {"init_roll_rad": "roll_rad", "init_pitch_rad": "pitch_rad", "init_yaw_rad": "yaw_rad",
                 "init_rate_body_x_rad_s": "gyro_body_x_rad_s", "init_rate_body_y_rad_s": "gyro_body_y_rad_s",
                 "init_rate_body_z_rad_s": "gyro_body_z_rad_s", "init_pos_down_m": "altitude_m"}
#: bytes per draw, grid sample and compared signal held at the peak (draws on the client, one signal at a time,
#: plus a chunk on each worker: counted as all signals at once, an upper bound)
BYTES_PER_DRAW_SAMPLE = 8
#: points of the band's mixture per sample, parameter draws x discrepancy levels (:func:`mixture_band`): the
#: discrepancy alone at this many levels reproduces its stored 5 and 95 % quantiles to interpolation
MIXTURE_POINTS = 400
#: most values (points x samples) sorted at once by :func:`mixture_band` (64 MB of float64)
MIXTURE_CHUNK = 8_000_000


def noise_std(values: np.ndarray, wrap: bool = False) -> float:
    """White-noise standard deviation of a sampled signal: 1.4826 MAD of its second differences / sqrt(6)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) < 5:
        return 0.0
    d = np.diff(np.unwrap(v) if wrap else v, 2)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(6.0))


def _state_noise(log: FlightLog) -> dict[str, float]:
    """Sensor noise (1 sigma) of each restart-state variable, from the logged signal it is taken from; body
    velocities from the GPS velocity's noise (rms over north, east, down), else x from the airspeed's."""
    out = {k: noise_std(log.signal(s).values, wrap=s == "yaw_rad") for k, s in STATE_SIGNALS.items() if log.has(s)}
    vel = [f"vel_{a}_m_s" for a in ("north", "east", "down")]
    if all(log.has(v) for v in vel):
        s = math.sqrt(sum(noise_std(log.signal(v).values) ** 2 for v in vel) / 3.0)
        out |= {f"init_vel_body_{a}_m_s": s for a in "xyz"}
    elif log.has("airspeed_m_s"):
        out["init_vel_body_x_m_s"] = noise_std(log.signal("airspeed_m_s").values)
    return out


def output_noise(log: FlightLog, maps: tuple[SignalMap, ...], units: dict[str, str | None],
                 params: dict[str, float]) -> dict[str, float]:
    """Sensor noise (1 sigma) of each compared signal in the FMU output's units."""
    out = {}
    for m in maps:
        v = m.convert(log.signal(m.log).values, units.get(m.fmu), params)
        out[m.fmu] = noise_std(v, wrap=m.wrap)
    return out


@dataclass(frozen=True)
class McTask:
    """A chunk of draws of one replay (plain data: paths, options, the uncertainty, the noise levels)."""

    job: ValidationJob
    uncertainty: Uncertainty
    seed: int
    draws: tuple[int, ...]
    state_std: dict[str, float]
    output_std: dict[str, float]


def _factor(cov: np.ndarray) -> np.ndarray:
    """A square root L of a positive semi-definite covariance (L L^T = C), by eigendecomposition."""
    w, v = np.linalg.eigh(cov)
    return v * np.sqrt(np.clip(w, 0.0, None))


def mc_task(task: McTask) -> dict[str, Any]:
    """Worker side: simulate the task's draws; per compared signal an array (draws x grid samples), NaN where
    not scored or where a draw's FMU run failed (listed with its error)."""
    from fmu_models.fmi.host import FmuHost, FmuRunError
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.common.parallel import local_path, task_rng
    from identification.logs.readers import read_log
    from identification.validation.job import load_maps
    from identification.validation.replay import replay_setup, simulate_setup, vehicle_of
    from identification.validation.replay_battery import job_battery_state

    job = task.job
    log = read_log(local_path(job.log), channel_map=local_path(job.channel_map) if job.channel_map else None)
    unc = task.uncertainty
    mean, chol = np.asarray(unc.mean), _factor(np.asarray(unc.covariance, dtype=float))
    with FmuHost(local_path(job.fmu)) as host:
        maps = load_maps(replace(job, output_map=local_path(job.output_map) if job.output_map else None),
                          vehicle_of(host))
        mapping = PwmMapping.load(local_path(job.mapping)) if job.mapping else None
        battery = job_battery_state(local_path(job.fmu), local_path(job.params_file) if job.params_file else None,
                                    job.embedded_params, vehicle_of(host))
        setup = replay_setup(host, log, job.log, maps, job.options, dict(job.start_values), mapping,
                             t_range=job.t_range_s, battery=battery)
        n = len(setup.t)
        out = {m.fmu: np.full((len(task.draws), n), np.nan) for m in maps}
        failed = []
        for r, k in enumerate(task.draws):
            rng = task_rng(task.seed, k)  # fixed order of use: parameters, restart states, output noise
            params = dict(zip(unc.names, (mean + chol @ rng.standard_normal(len(mean))).tolist(), strict=True))
            keys = [key for key in setup.starts[0] if key in task.state_std]
            kicks = rng.standard_normal((len(setup.starts), len(keys)))
            starts = [{**s, **params, **{key: s[key] + task.state_std[key] * kicks[w, j]
                                         for j, key in enumerate(keys)}} for w, s in enumerate(setup.starts)]
            noise = {m.fmu: rng.normal(0.0, task.output_std.get(m.fmu, 0.0), n) for m in maps}
            try:
                model, _ = simulate_setup(host, setup, maps, starts)
            except FmuRunError as err:
                failed.append([k, str(err)])
                continue
            for m in maps:
                out[m.fmu][r] = model[m.fmu] + noise[m.fmu]
    return {"draws": np.asarray(task.draws), "failed": failed, **{f"y:{k}": v for k, v in out.items()}}


@dataclass(frozen=True)
class CoverageBounds:
    """How far a coverage measured on a replay's windows can be trusted (:func:`coverage_bounds`): its one-sided
    ``VERDICT_LEVEL`` lower and upper bounds, the effective number of independent samples behind them and the
    number of windows."""

    lower: float
    upper: float
    effective: float
    windows: int

    def as_dict(self) -> dict[str, float | int]:
        return {"lower": self.lower, "upper": self.upper, "effective_samples": self.effective,
                "windows": self.windows}


#: a sample's distance from its band's centre, in half-widths, is clipped here before its intra-window
#: correlation is estimated (:func:`coverage_bounds`): a far outlier would otherwise stand for the whole window
POSITION_CLIP = 3.0


def band_position(y: np.ndarray, lo: np.ndarray, hi: np.ndarray, wrap: bool = False) -> np.ndarray:
    """``|y - centre| / half-width`` of each sample in its band [lo, hi] (1 on the edge; for an angle the short
    way round), clipped to ``POSITION_CLIP``; a zero-width band gives the clip (or 0 where ``y`` is on it)."""
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    d = y - mid
    if wrap:
        d = (d + math.pi) % (2.0 * math.pi) - math.pi
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(half > 0.0, np.abs(d) / np.where(half > 0.0, half, 1.0), np.where(d == 0.0, 0.0, np.inf))
    return np.minimum(u, POSITION_CLIP)


def _intra_window_correlation(values: np.ndarray, idx: np.ndarray, sizes: np.ndarray) -> float | None:
    """The one-way ANOVA estimator of the intra-window correlation of ``values`` (grouped by ``idx``), clipped
    to [0, 1]; None where the values cannot tell it (one window, a window per sample, or no spread)."""
    n, m = float(values.size), len(sizes)
    if m < 2 or n <= m:
        return None
    mean_w = np.bincount(idx, weights=values) / sizes
    grand = float(values.mean())
    msb = float(np.sum(sizes * (mean_w - grand) ** 2)) / (m - 1)
    msw = float(np.sum((values - mean_w[idx]) ** 2)) / (n - m)
    n0 = (n - float(np.sum(sizes ** 2)) / n) / (m - 1)
    den = msb + (n0 - 1.0) * msw
    return None if den <= 0.0 else min(1.0, max(0.0, (msb - msw) / den))


def coverage_bounds(inside: np.ndarray, window: np.ndarray, position: np.ndarray | None = None) -> CoverageBounds:
    """One-sided ``VERDICT_LEVEL`` bounds of the coverage ``mean(inside)`` (booleans, one per scored sample) of
    samples grouped by replay window (``window``: an index per sample); ``position``: each sample's distance from
    its band's centre (:func:`band_position`).

    Samples within a window are not independent: each window is one run from one logged restart, and its
    residual is one drift. The bounds are Clopper-Pearson bounds of ``k = c n_eff`` successes in ``n_eff``
    trials, ``n_eff = N / deff`` with the design effect ``deff = 1 + (n_w - 1) rho`` (``n_w`` the size-weighted
    mean window size) and ``rho`` the intra-window correlation (one-way ANOVA estimator, clipped to [0, 1]): the
    larger of that of ``inside`` and that of ``position``. The position is continuous, so its correlation is
    estimated where few samples fall outside (one sample out of 600 gives the indicator a correlation near zero,
    as if every sample were independent). Where neither can tell it (one window, or no spread) ``rho`` is 1: each
    window counts as one trial. Measured on simulated replays of 6-60 windows of 50 samples whose correlation is
    0.5-0.98 from one sample to the next (``bench/band_verdict.py``, 1000 replays each): a right 90 % band was a
    finding in none (its point figure alone past 80 % or 98 % in up to 25 %); a band covering exactly 98 % was
    called wide in at most 3.0 %; a band covering 60 % was shown in 38-100 % of 6-window replays and 91 % or more
    from 20 windows."""
    from scipy.stats import beta

    ok = np.asarray(inside, bool)
    if ok.size == 0:
        return CoverageBounds(math.nan, math.nan, 0.0, 0)
    _, idx = np.unique(np.asarray(window), return_inverse=True)
    sizes = np.bincount(idx).astype(float)
    n, m = float(ok.size), len(sizes)
    c = float(ok.mean())
    rhos = [r for v in (ok.astype(float), None if position is None else np.asarray(position, float))
            if v is not None for r in [_intra_window_correlation(v, idx, sizes)] if r is not None]
    rho = max(rhos) if rhos else 1.0
    n_w = float(np.sum(sizes ** 2) / n)
    n_eff = n / (1.0 + (n_w - 1.0) * rho)
    k = c * n_eff
    upper = 1.0 if k >= n_eff else float(beta.ppf(VERDICT_LEVEL, k + 1.0, n_eff - k))
    lower = 0.0 if k <= 0.0 else float(beta.ppf(1.0 - VERDICT_LEVEL, k, n_eff - k + 1.0))
    return CoverageBounds(lower, upper, n_eff, m)


@dataclass
class Bands:
    """5-95 % bands (on the replay's scored grid) and their coverage of the logged samples, per signal, with the
    coverage's bounds from the replay's windows (:func:`coverage_bounds`) where they were measured."""

    lo: dict[str, np.ndarray]
    hi: dict[str, np.ndarray]
    coverage: dict[str, float]
    info: dict[str, Any] = field(default_factory=dict)
    bounds: dict[str, CoverageBounds] = field(default_factory=dict)

    def verdict(self, name: str) -> tuple[str, str]:
        """``consistent`` | ``not explained`` | ``wide`` | ``unresolved``, and the reason in words. A coverage
        below ``MIN_COVERAGE`` (above ``MAX_COVERAGE``) is ``not explained`` (``wide``) when its bound from the
        replay's windows is past the threshold too; when the windows cannot show it, ``unresolved`` (not a
        finding, and not called consistent)."""
        c = self.coverage.get(name, float("nan"))
        nominal = f"{BAND[1] - BAND[0]:.0%} band covers {c:.0%} of the logged samples"
        if not math.isfinite(c):
            return "n/a", "no scored sample"
        b = self.bounds.get(name)
        if c < MIN_COVERAGE:
            if b is not None and b.upper >= MIN_COVERAGE:
                return "unresolved", self._unresolved(nominal, f"below {MIN_COVERAGE:.0%}", b, "upper", b.upper)
            return "not explained", (f"{nominal} (below {MIN_COVERAGE:.0%}{self._shown(b, 'upper')}): the model, "
                                     "or its stated uncertainty, does not explain the log")
        if c > MAX_COVERAGE:
            if b is not None and b.lower <= MAX_COVERAGE:
                return "unresolved", self._unresolved(nominal, f"above {MAX_COVERAGE:.0%}", b, "lower", b.lower)
            return "wide", (f"{nominal} (above {MAX_COVERAGE:.0%}{self._shown(b, 'lower')}): the stated "
                            "uncertainty may be overstated")
        return "consistent", nominal

    @staticmethod
    def _shown(b: CoverageBounds | None, end: str) -> str:
        return "" if b is None else (f"; its {VERDICT_LEVEL:.0%} {end} bound {getattr(b, end):.0%} from "
                                     f"{b.windows} windows, about {b.effective:.0f} independent samples")

    @staticmethod
    def _unresolved(nominal: str, past: str, b: CoverageBounds, end: str, bound: float) -> str:
        if b.windows == 1:
            return (f"{nominal}, {past}, but from one replay window (one run from one start, its residual one "
                    "drift) a band's level cannot be shown; replay the log in windows (--window-s) to tell")
        return (f"{nominal}, {past}, but its {b.windows} windows (about {b.effective:.0f} independent samples) "
                f"cannot show it: the {VERDICT_LEVEL:.0%} {end} bound is {bound:.0%}; a longer log, or more "
                "windows, would tell")


def band_ranks(n: int) -> tuple[int, int]:
    """0-based ranks (j, k) of the draws bounding the 5-95 % band of ``n`` draws: j = floor(0.05 (n+1)),
    k = ceil(0.95 (n+1)) (1-based), so a new sample exchangeable with the draws falls inside with probability
    (k - j) / (n + 1) >= 0.90 (``numpy.quantile`` would give about 0.9 (n-1)/(n+1): 86 % at 40 draws)."""
    j = max(1, math.floor(BAND[0] * (n + 1) + 1e-9))
    k = min(n, math.ceil(BAND[1] * (n + 1) - 1e-9))
    return j - 1, k - 1


def prediction_band(ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper band per column of ``ys`` (draws x samples; NaN columns give NaN)."""
    j, k = band_ranks(len(ys))
    srt = np.sort(ys, axis=0)
    return srt[j], srt[k]


def mixture_quantiles(devs: np.ndarray, disc: np.ndarray, weight: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 5, 50 and 95 % quantiles per sample of the mixture of :func:`mixture_band` (unstretched). A draw with no
    value at a sample (NaN: not scored there, or its run stopped) is left out of that sample's mixture; a sample
    with no value at all is NaN."""
    n = disc.shape[1]
    out = np.full((3, n), np.nan)
    rows = disc.shape[0] * (devs.shape[0] if weight > 0.0 else 1)
    step = max(1, MIXTURE_CHUNK // max(rows, 1))
    for a in range(0, n, step):
        b = min(n, a + step)
        pts = disc[:, a:b]
        if weight > 0.0:
            pts = (weight * devs[:, None, a:b] + pts[None, :, :]).reshape(-1, b - a)
        gaps = np.isnan(pts).any(axis=0)
        out[:, a:b][:, ~gaps] = np.quantile(pts[:, ~gaps], [BAND[0], 0.5, BAND[1]], axis=0, method="hazen")
        for j in np.flatnonzero(gaps & ~np.isnan(pts).all(axis=0)):  # few: a stopped draw, a gap
            out[:, a + j] = np.nanquantile(pts[:, j], [BAND[0], 0.5, BAND[1]], method="hazen")
    return out[0], out[1], out[2]


def signal_band(levels: Sequence[float], table: Any, res: Any, name: str, devs: np.ndarray,
                weight: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`mixture_quantiles` of the parameter draws' deviations ``devs`` (draws x samples of the replay ``res``)
    and the discrepancy ``table`` (a ``SignalDiscrepancy``) of signal ``name`` at each sample's horizon, scaled as
    it says on ``res`` (``discrepancy.points``), a block of samples at a time so that no more than
    ``MIXTURE_CHUNK`` values are held."""
    from identification.validation.discrepancy import horizons_s, points, scale_of

    h_s, scale = horizons_s(res), scale_of(res, name, table)
    count = mixture_levels(len(devs), weight)
    n = h_s.size
    lo, mid, hi = (np.full(n, np.nan) for _ in range(3))
    step = max(1, MIXTURE_CHUNK // (count * (len(devs) if weight > 0.0 else 1)))
    for a in range(0, n, step):
        b = min(n, a + step)
        pts = points(levels, table, h_s[a:b], count, scale[a:b])
        lo[a:b], mid[a:b], hi[a:b] = mixture_quantiles(devs[:, a:b], pts, weight)
    return lo, mid, hi


def mixture_band(devs: np.ndarray, disc: np.ndarray, weight: float, factor: float = 1.0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The 5-95 % band, as deviations from the nominal replay, of ``weight`` x a parameter draw's deviation
    (``devs``, draws x samples) plus an independent discrepancy sampled at evenly spread levels (``disc``, levels
    x samples, ``discrepancy.points``), stretched by ``factor`` about the mixture's median. The discrepancy's
    distribution enters whole, not as one random draw per parameter draw: with 19 parameter draws a band of
    draws + random discrepancy is their min..max, whose width scatters sample to sample and which had to be
    stretched wider to cover the same share (on the fixed-wing excitation log's held-out segments: altitude,
    pitch and roll 3.4-3.6x the RMSE that way against 2.8-3.0x exactly, both with the discrepancy alone)."""
    return stretch(*mixture_quantiles(devs, disc, weight), factor)


def stretch(lo: np.ndarray, mid: np.ndarray, hi: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """The band [lo, hi] stretched by ``factor`` about ``mid`` (its median: it widens or narrows about its own
    centre, so its coverage grows with the factor)."""
    return mid + factor * (lo - mid), mid + factor * (hi - mid)


def inside_band(y: np.ndarray, lo: np.ndarray, hi: np.ndarray, wrap: bool = False) -> np.ndarray:
    """Which samples ``y`` lie in [lo, hi]; for an angle (``wrap``) on the arc from ``lo`` to ``hi`` modulo 2 pi
    (a logged -3.1 rad is inside a band 3.0..3.3 rad; a band 2 pi wide or more holds every angle)."""
    if not wrap:
        return (y >= lo) & (y <= hi)
    return (hi - lo >= 2.0 * math.pi) | (np.mod(y - lo, 2.0 * math.pi) <= hi - lo)


def check_draws(draws: int, n_samples: int, n_signals: int, max_memory_mb: float) -> None:
    """``ValidationInputError`` before anything is allocated when ``draws`` is out of range or the draws
    would not fit in ``max_memory_mb``."""
    if not MIN_DRAWS <= draws <= MAX_DRAWS:
        raise ValidationInputError(f"--mc = {draws}: allowed {MIN_DRAWS}..{MAX_DRAWS} (a 5-95 % band needs at least "
                                   f"{MIN_DRAWS} draws)")
    need = draws * n_samples * max(1, n_signals) * BYTES_PER_DRAW_SAMPLE
    if need > max_memory_mb * 2**20:
        raise ValidationInputError(f"--mc = {draws}: the draws would need about {need / 2**20:,.0f} MB ({n_samples:,} "
                                   f"samples x {n_signals} signals), above --max-memory-mb {max_memory_mb:g}; use "
                                   "fewer draws, a lower --rate-hz or raise --max-memory-mb")


def monte_carlo(job: ValidationJob, unc: Uncertainty, res: ReplayResult, log: FlightLog, draws: int, seed: int,
                executor: Executor, units: dict[str, str | None], progress: Any = False,
                discrepancy: Discrepancy | None = None, keep: dict[str, np.ndarray] | None = None) -> Bands:
    """Run ``draws`` draws of ``job`` (whose nominal replay is ``res``) on ``executor``; the bands. With
    ``discrepancy`` (``identification.validation.discrepancy``) the band of a signal it covers is that of the
    draws (times the discrepancy's ``parameter_weight``) convolved with the model's discrepancy at each sample's
    horizon (:func:`mixture_band`), instead of the draws plus white sensor noise (the learned residuals are
    against the logged signal: they carry its noise), stretched about its per-sample median by the
    discrepancy's ``band_factor`` where it has one. ``keep``: filled with each signal's draws minus the nominal
    replay (draws x samples; without the discrepancy: what :func:`calibrate` calibrates it on)."""
    from identification.validation.job import job_files

    check_draws(draws, len(res.t_s) + 1, len(res.maps), res.options["max_memory_mb"])
    params = {**{k: float(v) for k, v in res.fmu["parameters"].items()}, **dict(job.start_values)}
    # a start velocity read from the specific force (``start_fit``) has the accelerometer's noise, not the GPS's
    state_std, out_std = {**_state_noise(log), **res.start_std}, output_noise(log, res.maps, units, params)
    learned = [m.fmu for m in res.maps if discrepancy is not None and m.fmu in discrepancy.signals]
    out_std = {k: (0.0 if k in learned else v) for k, v in out_std.items()}
    chunk = max(1, math.ceil(draws / (2 * executor.threads())))  # each chunk reads the log and sets up once
    tasks = [McTask(job, unc, seed, tuple(range(a, min(draws, a + chunk))), state_std, out_std)
             for a in range(0, draws, chunk)]
    run = executor.map_tasks(mc_task, tasks, files=lambda t: job_files(t.job), progress=progress, desc="mc")
    failed = [*([f"draws {t.draws[0]}..{t.draws[-1]}: {e}" for i, e in run.failures.items() for t in [tasks[i]]]),
              *(f"draw {k}: {e}" for _, r in run.results(arrays=()) if r for k, e in r["failed"])]
    from identification.validation.discrepancy import window_index

    lo, hi, cov, bounds = {}, {}, {}, {}
    win = window_index(res)
    for m in res.maps:  # one signal of all draws in memory at a time
        rows = [r[f"y:{m.fmu}"] for _, r in run.results(arrays=[f"y:{m.fmu}"]) if r is not None]
        ys = np.concatenate(rows)[:, 1:] if rows else np.full((0, len(res.t_s)), np.nan)
        ys = ys[np.isfinite(ys).any(axis=1)]
        if len(ys) < MIN_DRAWS:
            raise ValidationInputError(f"Monte Carlo: fewer than {MIN_DRAWS} of {draws} draws ran "
                                       f"({'; '.join(failed[:3])})")
        if m.wrap:  # an angle: each draw the short way round from the nominal replay, so the band is an arc
            ys = res.model[m.fmu] + ((ys - res.model[m.fmu] + math.pi) % (2.0 * math.pi) - math.pi)
        if keep is not None:
            keep[m.fmu] = ys - res.model[m.fmu]
        if m.fmu in learned:  # about the band's median: it widens or narrows about its own centre
            s = discrepancy.signals[m.fmu]  # type: ignore[union-attr]
            weight = 1.0 if s.parameter_weight is None else s.parameter_weight
            a, mid, b = signal_band(discrepancy.levels, s, res, m.fmu, ys - res.model[m.fmu],  # type: ignore[union-attr]
                                    weight)
            a, b = stretch(a, mid, b, s.band_factor or 1.0)
            lo[m.fmu], hi[m.fmu] = res.model[m.fmu] + a, res.model[m.fmu] + b
        else:
            lo[m.fmu], hi[m.fmu] = prediction_band(ys)
        y = res.measured[m.fmu]
        ok = np.isfinite(y) & np.isfinite(lo[m.fmu]) & np.isfinite(res.model[m.fmu])
        inside = inside_band(y[ok], lo[m.fmu][ok], hi[m.fmu][ok], m.wrap)
        cov[m.fmu] = float(inside.mean()) if ok.any() else float("nan")
        bounds[m.fmu] = coverage_bounds(inside, win[ok], band_position(y[ok], lo[m.fmu][ok], hi[m.fmu][ok], m.wrap))
    info = {"draws": draws, "draws_run": len(ys), "seed": seed, "band": list(BAND), "parameters": unc.names,
            "mean": unc.mean, "std": list(unc.std.values()), "output_noise_std": out_std, "state_noise_std": state_std,
            "failed": failed, "retried_tasks": len(run.retried),
            "min_coverage": MIN_COVERAGE, "max_coverage": MAX_COVERAGE, "verdict_level": VERDICT_LEVEL,
            "coverage_bounds": {k: b.as_dict() for k, b in bounds.items()},
            "discrepancy": {"signals": learned, "logs": discrepancy.logs if discrepancy else [],
                            "window_s": discrepancy.window_s if discrepancy else None,
                            "band_factor": {k: discrepancy.signals[k].band_factor for k in learned}
                            if discrepancy else {},
                            "parameter_weight": {k: discrepancy.signals[k].parameter_weight for k in learned}
                            if discrepancy else {},
                            "offset": {k: _offset_words(discrepancy.signals[k], units.get(k)) for k in learned
                                       if discrepancy.signals[k].offset is not None} if discrepancy else {},
                            "same_windows": discrepancy is None or (
                                discrepancy.window_s == res.options.get("window_s")
                                and discrepancy.rate_hz == res.options.get("rate_hz")),
                            "start_velocity": discrepancy.start_velocity if discrepancy else None,
                            "same_starts": discrepancy is None or discrepancy.start_velocity is None
                            or discrepancy.start_velocity == res.options.get("start_velocity"),
                            "parts": ("parameters (times parameter_weight) + restart-state noise, convolved with "
                                      "the learned discrepancy (carries the sensor noise)") if learned
                            else "parameters + restart-state noise + sensor noise"}}
    return Bands(lo, hi, cov, info, bounds)


def _offset_words(s: Any, unit: str | None) -> str:
    """A band's centre off the FMU (``SignalDiscrepancy.offset``) in words: in the signal's unit, or in its
    scale's where the table is scaled."""
    if s.scale_floor is None:
        return f"{s.offset:+.3g}" + (f" {unit}" if unit else "")
    return f"{s.offset:+.3g} x ({s.scale_by} + {s.scale_floor:.3g})"


#: the band factor searched between these (a ratio of band widths)
FACTOR_RANGE = (0.05, 20.0)


def mixture_levels(draws: int, weight: float) -> int:
    """Discrepancy levels per parameter draw in :func:`mixture_band`: about ``MIXTURE_POINTS`` points per sample
    (every one of them when the parameter draws do not enter)."""
    return MIXTURE_POINTS if weight == 0.0 else max(2, math.ceil(MIXTURE_POINTS / max(draws, 1)))


def band_factor_for(levels: Sequence[float], table: Any, parts: list[tuple[Any, np.ndarray]], name: str,
                    weight: float, level: float) -> float:
    """The smallest factor (bisection, 1 % steps, in ``FACTOR_RANGE``) by which the band of ``weight`` x the
    parameter draws convolved with the discrepancy ``table`` must be stretched about its median to cover
    ``level`` of the replays' residuals in ``parts`` (replay, draws' deviations), pooled; the widest when even
    that is short."""
    from identification.validation.discrepancy import residuals

    bands = []
    for res, devs in parts:
        lo, mid, hi = signal_band(levels, table, res, name, devs, weight)
        bands.append((residuals(res, name), mid, lo, hi))

    def covered(f: float) -> float:
        inside = n = 0
        for r, mid, lo, hi in bands:
            ok = np.isfinite(r) & np.isfinite(mid) & np.isfinite(lo) & np.isfinite(hi)
            inside += int(inside_band(r[ok], *stretch(lo[ok], mid[ok], hi[ok], f)).sum())
            n += int(ok.sum())
        return inside / n if n else math.nan

    a, b = FACTOR_RANGE
    if not covered(b) >= level:  # NaN or short even at the widest: keep the widest
        return b
    while b / a > 1.01:
        mid = math.sqrt(a * b)
        a, b = (a, mid) if covered(mid) >= level else (mid, b)
    return b


def _held_out(disc: Discrepancy, name: str, parts: list[tuple[Any, np.ndarray]], weight: float,
              level: float) -> float:
    """Mean interval score (``discrepancy.interval_score``) of the calibrated band with parameter weight
    ``weight`` on each learning replay when its discrepancy and factor are learned on the others (NaN when a
    table cannot be learned)."""
    from identification.validation.discrepancy import interval_score, refit, residuals

    total, n = 0.0, 0
    for i, (res, devs) in enumerate(parts):
        others = [p for j, p in enumerate(parts) if j != i]
        table = refit([r for r, _ in others], name, disc.signals[name], disc.window_s)
        if table is None:
            return math.nan
        f = band_factor_for(disc.levels, table, others, name, weight, level)
        lo, mid, hi = signal_band(disc.levels, table, res, name, devs, weight)
        a, k = interval_score(residuals(res, name), *stretch(lo, mid, hi, f), level)
        total, n = total + a, n + k
    return total / n if n else math.nan


def calibrate(disc: Discrepancy, kept: Sequence[tuple[ReplayResult, dict[str, np.ndarray]]],
              level: float = 0.90, weights: Sequence[float] = (1.0, 0.0)) -> Discrepancy:
    """``disc`` with each signal's ``parameter_weight`` and ``band_factor``. The factor: the smallest by which the
    band of the Monte Carlo draws' deviations from the nominal replay (parameters + restart states, ``kept`` per
    learning replay by :func:`monte_carlo`) times the weight, convolved with this discrepancy
    (:func:`mixture_band`), must be stretched about its median to cover ``level`` of the learning replays'
    logged samples, pooled. The discrepancy alone covers them at its level by construction: the parameter draws
    on top count the parameters' error twice (the residuals carry it) and the factor takes that back, or widens
    the band where the draws' spread and the discrepancy do not add up to the residuals'. The weight: 1 (the
    draws' spread in the band) or 0 (the discrepancy alone), whichever band scores better (mean interval score)
    on each learning replay when learned and calibrated on the others; 1 with a single learning replay. Where
    the draws' spread follows the error (the body rates of the fixed wing) it narrows the band; where it does not
    (docs/validation.md#prediction-bands) it only widens it. ``weights``: the candidates, the first kept on a tie
    or with a single learning replay (``(1.0,)``: the draws always in, a study of the choice)."""
    signals = dict(disc.signals)
    for name, s in disc.signals.items():
        parts = [(res, devs[name]) for res, devs in kept if name in devs]
        if not parts:
            continue
        weight = float(weights[0])
        if len(parts) >= 2 and len(weights) > 1:
            score = {float(w): _held_out(disc, name, parts, float(w), level) for w in weights}
            if all(math.isfinite(v) for v in score.values()):
                weight = min(score, key=lambda w: (score[w], w != weight))
        factor = band_factor_for(disc.levels, s, parts, name, weight, level)
        signals[name] = s.model_copy(update={"band_factor": round(factor, 4), "parameter_weight": weight})
    return disc.model_copy(update={"signals": signals})

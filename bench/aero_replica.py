"""A truth-known replica of the excitation log: does ``identify aero`` get within 10 % and cover?

The FMU behind ``fixed_wing/arduplane_sitl_fmu_excitation.BIN`` has derivatives that are not handed over, so
the Done-when ("every primary derivative within 10 % with a covering 95 % interval") cannot be checked on it.
The replica keeps everything of that log but the aircraft: the same servo PWM (RCOU), the same timeline and
segments, the logged state at each segment start; inside every fit and held-out segment every signal
``identify aero`` reads (attitude and heading, gyro, accelerometer, airspeed, GPS velocity, altitude: the fitted
outputs, the state a segment or a piece of it starts from, the airborne test) is replaced by our fixed-wing
model flown from that state with those inputs and a known derivative set, plus sensor noise. The set:
Aerosonde's with the primaries and the fixed lateral/pitch coefficients (:data:`SCALED`) each times a seeded
factor in
[0.6, 1.6] (one draw per seed), ``C_m_0`` re-balanced so the logged trim (median elevator and angle of attack
at the segment starts) stays a trim. Noise per output: the demo's white sensor noise
(``identification.flights.synthetic.NOISE``) plus an AR(1) part of the same std (pole 0.9 at 50 Hz).

The truth is flown open loop with the logged servo PWM (the log's FBWA recoveries included): a draw with an
unstable spiral can dive into the ground inside a segment, which a real flight, recovered by its autopilot,
would not; the truth's modes at trim are printed per draw, and ``identify aero`` cuts such segments where the
aircraft comes within 10 m of the ground level (its notes are printed). A draw whose truth diverges numerically
inside a segment leaves no replica to identify: it is printed as skipped and left out of the summary.

Then the library path of the command a user types (``uavfmu identify aero LOG --out x.json``: every default,
timeline found beside the log) runs on the replica, and per primary derivative the relative error, the
printed 95 % interval, whether it covers the truth and what determines it are printed. Over the draws, per
primary derivative: the coverage of its 95 % intervals and the half-width over the RMS error, each draw's error
taken in its own interval's units (every draw has its own truth and interval: ``1.96 / rms z``, ``z = 1.96
|error| / half-width``; ``replica_verdict.draw_width_figure``), beside the RMS relative error and the median
relative half-width.

A draw fails when a primary derivative misses 10 % or ``identify aero`` records a failure (e.g. a fitted model
that runs away in a segment, whose bounds it then refuses to call credible). An interval that misses is not a
failed draw: eleven honest 95 % intervals all cover in only 57 % of draws; coverage is judged over the draws.

Each draw's header names the nuisance set ``identify aero`` chose (per-segment initial states and output biases,
``identification.aero.identify._nuisance_fits``); the summary counts the draws whose interval is the small-sample
bound (``oem.data_bound``). Studies of that bound: ``--start-state exact`` hands the tool the truth's initial state
at every segment start (a sample there holding the original log's value, which the truth starts from; by default
the tool interpolates between the last original sample and the first replica one, both with the replica's noise, as
it would between noisy samples of a real log: the noise is stationary from that last sample on, its AR(1) part
drawn from its long-run distribution there, not started at 0); ``--estimate-initial STATE,...`` fits those
per-segment initial states (with the gyro and accelerometer biases) instead of the tool's automatic choice;
``--truth-seed N`` keeps draw N's truth in every draw and redraws only the noise (seeds ``--seed``, ``--seed`` + 1,
...); ``--initial-sd STATE=SD,...`` gives some of the ``--estimate-initial`` states their logged start as a
measurement of that std (a prior at the logged value, ``AeroOptions.initial_sd``) instead of leaving them free;
``--fixed-spread zeros`` also draws the scaled coefficients at 0 in Aerosonde's set (C_Y_p, C_Y_r: a factor leaves
them at 0 in every draw, while the tool gives each, when it stays fixed, a consider std of 0.05) about 0 with that
std; ``--fixed-spread consider`` draws every scaled coefficient that is not a primary about Aerosonde's value with
the std the tool's consider covariance gives it (50 % of the value, at least the family's floor), as that
covariance assumes a fixed coefficient varies.

Run: ``.venv/bin/python bench/aero_replica.py [--draws 1] [--seed 0] [--bound ar|bootstrap] [--start-state
logged|exact] [--estimate-initial STATES [--initial-sd STATE=SD,...]] [--truth-seed N] [--fixed-spread
factor|zeros|consider] [--save FILE]`` (one identify run per draw: 15-60 s on 2 cores, more when they are shared).
Exit 1 when a draw fails, or the draws show a primary derivative's coverage below 0.90 or its median half-width above
2 x its RMS error (``replica_verdict``: a point figure past its target within the Monte Carlo error of the draws is
printed "(unresolved)", not called met); the log is read from ``../shared/data`` (exit 2 when absent). ``--save FILE``
writes each draw's relative error and half-widths (JSON, after every draw); ``--pool FILE...`` runs no draw and
judges the draws of several saved runs together, the same way: runs of other seeds with the same settings (truth
family, bound, segment starts, nuisance), so that figures 20 draws leave unresolved can be resolved by more draws
run in parallel (a file of another bench, other settings or a draw seed twice is refused by name).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.fixed_wing import linear
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fixed_wing.trim import trim
from fmu_models.signals.names import OUTPUT_TO_LOG
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero import model as aero
from identification.aero.identify import (
    AUTO_BIASES,
    PRIMARY,
    AeroOptions,
    AeroResult,
    AeroSource,
    _pool,
    identify_aero,
)
from identification.estimation.oem import BOUNDS, Manoeuvre, OutputErrorEstimator
from identification.flights.synthetic import NOISE
from identification.logs.flightlog import FlightLog, Signal
from identification.logs.log_state import resample_angle
from identification.logs.readers import read_log

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aero_coverage import white_plus_ar1  # the coverage study's noise, here stationary
from replica_verdict import coverage_figure, draw_width_figure, overall

LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "fixed_wing" / "arduplane_sitl_fmu_excitation.BIN"
#: coefficients scaled in the truth: the primaries and the fixed ones that couple into them
SCALED = (*PRIMARY, "C_m_delta_e", "C_Y_delta_r", "C_Y_p", "C_Y_r", "C_Y_delta_a", "C_ell_delta_r", "C_n_p",
          "C_n_delta_a", "C_L_q")


#: the truth families (``--fixed-spread``): every scaled coefficient times U(0.6, 1.6) (factor); besides, those at 0
#: drawn about 0 with their consider std (zeros); or every scaled one that is not a primary drawn about Aerosonde's
#: value with its consider std, the primaries times the factors (consider)
FIXED_SPREADS = ("factor", "zeros", "consider")


def truth_params(model: FixedWingModel, p: np.ndarray, rng: np.random.Generator, data: list[Manoeuvre],
                 scaled: Sequence[str] = SCALED, fixed_spread: str = "factor") -> np.ndarray:
    """Aerosonde's parameters with ``scaled`` times factors in [0.6, 1.6] and ``C_m_0`` re-balanced at the
    median trim (elevator, angle of attack) of the segment starts in ``data``. ``fixed_spread`` "zeros": besides,
    each of ``scaled`` whose Aerosonde value is 0 (C_Y_p and C_Y_r, which a factor leaves at 0 in every draw) is
    drawn about 0 with the std the tool's consider covariance gives it when it stays fixed (``priors.fixed_sd``,
    normal, clipped at 2 std, from a child stream of ``rng`` that leaves its own draws, and so the replica's noise,
    as they are); neither acts at the trim, so the logged trim stays one. "consider": each of ``scaled`` that is not
    a primary is drawn so about its Aerosonde value, as the consider covariance takes a coefficient the tool keeps
    fixed to vary (the factors give them a spread of 0.29 of the value against its 0.5), the primaries keep their
    factors; none of those acts on the pitch trim."""
    from identification.aero.priors import fixed_sd

    if fixed_spread not in FIXED_SPREADS:
        raise ValueError(f"fixed_spread {fixed_spread!r}: expected one of {', '.join(FIXED_SPREADS)}")
    ix, st, inp = model.params.index, model.states.index, list(model.inputs.index)
    out = p.copy()
    for n in dict.fromkeys(scaled):
        out[ix[n]] *= rng.uniform(0.6, 1.6)
    if fixed_spread != "factor":  # from a child stream: the other coefficients and the noise stay the factor family's
        child = rng.spawn(1)[0]
        for n in dict.fromkeys(scaled):
            if p[ix[n]] == 0.0 or (fixed_spread == "consider" and n not in PRIMARY):
                out[ix[n]] = p[ix[n]] + fixed_sd(n, p[ix[n]]) * float(np.clip(child.normal(), -2.0, 2.0))
    alpha = float(np.median([np.arctan2(m.x0[st["vel_body_z_m_s"]], m.x0[st["vel_body_x_m_s"]]) for m in data]))
    elev = float(np.median([m.u[0, inp.index("elevator_rad")] for m in data]))
    out[ix["C_m_0"]] = p[ix["C_m_0"]] + sum((p[ix[a]] - out[ix[a]]) * v for a, v in
                                            (("C_m_alpha", alpha), ("C_m_delta_e", elev)))
    return out


#: signals the identification reads from a log besides the fitted outputs: the state at each segment start
#: (``identification.logs.log_state.initial_values``: yaw, GPS velocity, altitude) and the airborne test
STATE_OUTPUTS = ("yaw_rad", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s", "altitude_m")
#: white noise of those that ``identification.flights.synthetic.NOISE`` does not give (GPS velocity and baro altitude)
STATE_NOISE = {"vel_north_m_s": 0.05, "vel_east_m_s": 0.05, "vel_down_m_s": 0.05, "altitude_m": 0.1}


class TruthDivergesError(RuntimeError):
    """A drawn truth whose open-loop flight from the logged state diverges inside a segment: there is no replica
    log to identify (a draw of the truth, not a failure of the tool)."""


def replica_log(log: FlightLog, model: FixedWingModel, p_truth: np.ndarray, segments: list[aero.Segment],
                mapping: PwmMapping, outputs: list[str], rate_hz: float, rng: np.random.Generator,
                exact_start: bool = False) -> FlightLog:
    """``log`` with every signal ``identify aero`` reads (the fitted ``outputs`` and :data:`STATE_OUTPUTS`)
    replaced inside ``segments`` by the model's response (``p_truth``, from the logged state, logged inputs) plus
    noise, so that the state at any instant inside a segment (a re-initialised piece) is the truth's too; the last
    sample at or before each segment start, which the start is read from with the first replica one, gets the same
    (stationary) noise series, as a real log's sample there would carry it.
    ``exact_start``: a sample at each segment start holds the original log's value there (the state the truth
    starts from), so the state the tool reads at a segment start is the truth's exactly."""
    names = list(dict.fromkeys([*outputs, *STATE_OUTPUTS]))
    sim = OutputErrorEstimator(model, p_truth, ["C_ell_p"], names)
    data = aero.manoeuvres(model, p_truth, log, mapping, segments, outputs, rate_hz)
    runs = []
    for seg, m in zip(segments, data, strict=True):
        y, _, bad = sim.simulate(p_truth[sim.i_free], m, sensitivities=False)
        if bad:
            raise TruthDivergesError(f"the truth model diverges in segment {seg}")
        runs.append((aero.grid(seg, rate_hz)[1:], y))
    signals = dict(log.signals)
    for i, name in enumerate(names):
        col = OUTPUT_TO_LOG[name]
        s = log.signal(col)
        t, v = s.t_s, s.values.copy()  # a start's left sample gets noise below: the log read stays untouched
        sd = NOISE.get(col, STATE_NOISE.get(name, 0.01))
        replaced: list[tuple[float, float]] = []
        for seg, (tg, y) in zip(segments, runs, strict=True):
            keep = (t <= seg.t0_s) | (t > seg.t1_s)
            # one stationary noise series from the last sample at or before the start on: the start is read
            # between that sample and the first replica one, and in a real log both carry the sensor's noise
            # (white and coloured alike); the original log's own sample there is nearly noise-free (SITL)
            noise = white_plus_ar1(rng, (len(tg) + 1,), sd, sd, stationary=True)
            yv = y[:, i] + noise[1:]
            left = np.flatnonzero(t <= seg.t0_s)
            if not exact_start and len(left) and not any(a < t[left[-1]] <= b for a, b in replaced):
                v[left[-1]] += noise[0]
                if name == "yaw_rad":
                    v[left[-1]] = np.angle(np.exp(1j * v[left[-1]]))
            replaced.append((seg.t0_s, seg.t1_s))
            if name == "yaw_rad":
                yv = np.angle(np.exp(1j * yv))
            if exact_start:
                t0 = np.array([seg.t0_s])
                keep &= t != seg.t0_s
                tg, yv = np.r_[t0, tg], np.r_[resample_angle(s, t0) if name == "yaw_rad" else s.resample(t0), yv]
            t = np.concatenate([t[keep], tg])
            v = np.concatenate([v[keep], yv])
            order = np.argsort(t, kind="stable")
            t, v = t[order], v[order]
        signals[col] = Signal(col, t, v, s.unit, s.description)
    return FlightLog(log.source, log.fmt, signals, dict(log.params), log.vehicle, list(log.warnings), log.quality)


def modes_line(model: FixedWingModel, p_truth: np.ndarray, data: list[Manoeuvre]) -> str:
    """The truth's classical modes at a wings-level trim at the median airspeed of the segment starts
    (``fmu_models.fixed_wing.linear``): an unstable spiral flown open loop drifts into a spiral dive."""
    st = model.states.index
    va = float(np.median([np.linalg.norm(m.x0[[st["vel_body_x_m_s"], st["vel_body_y_m_s"], st["vel_body_z_m_s"]]])
                          for m in data]))
    md = linear.modes(linear.linearise(model, p_truth, trim(model, p_truth, va)))
    return f"truth modes at {va:.1f} m/s: " + ", ".join(
        f"{m.name} {m.eigenvalues[0].real:+.3f}{m.eigenvalues[0].imag:+.3f}j" for m in md.all())


def replica_fit(seed: int, bound: str = "ar", exact_start: bool = False,
                estimate_initial: Sequence[str] | None = None, truth_seed: int | None = None,
                initial_sd: dict[str, float] | None = None, fixed_spread: str = "factor"
                ) -> tuple[FixedWingModel, np.ndarray, list[Manoeuvre], AeroResult, dict[str, float]]:
    """One truth draw identified as ``identify aero`` does: (model, the truth's parameters, the fit segments of
    the original log, the result, per state the RMS over the fit segments of the initial state the tool reads
    minus the truth's). ``exact_start``: see :func:`replica_log`; ``estimate_initial``: these
    per-segment initial states and the gyro/accelerometer biases instead of the tool's automatic nuisance choice;
    ``truth_seed``: the truth of that draw, only the noise from ``seed``; ``initial_sd``: those estimated initial
    states with their logged start as a measurement of that std (``AeroOptions.initial_sd``)."""
    log = read_log(LOG)
    mapping = PwmMapping.from_ardupilot(log.params)
    init, opt = FixedWingParams(), AeroOptions(bound=bound)
    if estimate_initial is not None:
        opt = AeroOptions(bound=bound, nuisance="given", estimate_initial=tuple(estimate_initial),
                          biases=tuple(b for b in AUTO_BIASES if b in opt.outputs), initial_sd=dict(initial_sd or {}))
    model = FixedWingModel(init)
    p = np.array(model.params.starts(), dtype=float)
    pool = _pool([AeroSource(log, mapping)], model, opt, [])
    segs = [s for _, s in pool.fit + pool.val]
    rng = np.random.default_rng(seed if truth_seed is None else truth_seed)
    start = aero.manoeuvres(model, p, log, mapping, [s for _, s in pool.fit], list(opt.outputs), opt.rate_hz)
    p_truth = truth_params(model, p, rng, start, fixed_spread=fixed_spread)
    if truth_seed is not None:
        rng = np.random.default_rng(seed)
    rep = replica_log(log, model, p_truth, segs, mapping, list(opt.outputs), opt.rate_hz, rng, exact_start)
    fit = [s for _, s in pool.fit]
    dx = np.array([b.x0 - a.x0 for a, b in zip(
        aero.manoeuvres(model, p_truth, log, mapping, fit, list(opt.outputs), opt.rate_hz),
        aero.manoeuvres(model, p_truth, rep, mapping, fit, list(opt.outputs), opt.rate_hz), strict=True)])
    start_rms = {n: float(np.sqrt(np.mean(dx[:, i] ** 2))) for n, i in model.states.index.items()}
    return model, p_truth, start, identify_aero([AeroSource(rep, mapping)], None, init, opt), start_rms


def run_draw(seed: int, bound: str = "ar", exact_start: bool = False, estimate_initial: Sequence[str] | None = None,
             truth_seed: int | None = None, initial_sd: dict[str, float] | None = None,
             fixed_spread: str = "factor") -> tuple[bool, str, dict[str, tuple[float, float, bool, float, float]]]:
    """One truth draw (:func:`replica_fit`): returns (all primaries within 10 % and no failure, the printed table,
    per primary derivative its relative error and the relative 95 % half-width, both over |truth|, whether the
    small-sample bound made its interval, the relative half-width the AR bound alone would give (with the
    consider shares of the fixed coefficients and of the logged start states), and that without the start states'
    share)."""
    model, p_truth, start, result, start_rms = replica_fit(seed, bound, exact_start, estimate_initial, truth_seed,
                                                           initial_sd, fixed_spread)
    est = result.fit.estimate
    values, std, dom = est.derivatives(), est.std, est.dominance()
    data_std, small = est.data_std, est.small_sample()
    cons = est.consider_std if est.consider_std is not None else np.zeros(est.n_global)
    freed = ", ".join(n for n in result.free if n not in PRIMARY) or "none"
    x0_bounds = {}  # per estimated initial state, the range over the segments of its coloured Cramér-Rao std
    for s in result.fit.oe.states_est:
        sd = [float(est.crb_std[i]) for i, n in enumerate(est.names) if n.endswith(f".x0.{s}")]
        if sd:
            x0_bounds[s] = (min(sd), max(sd))
    truth = "" if truth_seed is None else f" (draw {truth_seed}'s, noise of seed {seed})"
    family = f"Aerosonde x U(0.6, 1.6) on {len(dict.fromkeys(SCALED))} coefficients" + {
        "factor": "", "zeros": ", those at 0 drawn with their consider std",
        "consider": ", those not primary drawn about Aerosonde's with their consider std instead"}[fixed_spread]
    lines = [f"draw {seed}: truth = {family}{truth}; "
             f"freed: {freed}; failures: {result.failures or 'none'}", modes_line(model, p_truth, start),
             f"nuisance: {result.nuisance_choice}; segment starts: "
             f"{'the truth state' if exact_start else 'interpolated from the log (noisy)'}; the tool's initial state "
             "- the truth's, RMS over the fit segments: " + (", ".join(
                 f"{n} {v:.2g}" for n, v in start_rms.items() if v > 1e-9 and n not in ("lat_rad", "lon_rad"))
                 or "none"),
             *[f"note: {n}" for n in result.notes if "airborne" in n or "restart" in n or "logged start" in n],
             *(["the start's std the tool reads from the log's noise, RMS over the fit segments: " + ", ".join(
                 f"{n} {v:.2g}" for n, v in result.start_state_sd.items())] if result.start_state_sd else []),
             *(["estimated initial states, their coloured bound over the segments: " + ", ".join(
                 f"{s} {lo:.2g}-{hi:.2g}" for s, (lo, hi) in x0_bounds.items())] if x0_bounds else []),
             f"{'derivative':<14} {'truth':>9} {'estimate':>9} {'err %':>7} {'95 % interval':>22} {'covers':>6} "
             f"{'data %':>7} {'consider %':>10}  determined by"]
    ok = not result.failures  # e.g. bounds that are not credible
    worst, covered = (0.0, ""), 0
    rel: dict[str, tuple[float, float, bool, float, float]] = {}
    start = est.start_var if est.start_var is not None else np.zeros(est.n_global)
    ar_alone = np.hypot(np.sqrt(est.crb_std[:est.n_global] ** 2 + start), cons)
    no_start = np.hypot(est.crb_std[:est.n_global], cons)  # a study: the starts counted as exact
    for n in PRIMARY:
        i = est.names.index(n)
        truth, v = float(p_truth[model.params.index[n]]), values[n]
        err = 100.0 * (v - truth) / abs(truth)
        covers = abs(v - truth) <= 1.96 * std[i]
        ok &= bool(abs(err) <= 10.0)
        worst, covered = max(worst, (abs(err), n)), covered + bool(covers)
        rel[n] = ((v - truth) / abs(truth), 1.96 * float(std[i]) / abs(truth), n in small,
                  1.96 * float(ar_alone[i]) / abs(truth), 1.96 * float(no_start[i]) / abs(truth))
        lines.append(f"{n:<14} {truth:9.4f} {v:9.4f} {err:+7.1f} [{v - 1.96 * std[i]:9.4f}, {v + 1.96 * std[i]:9.4f}] "
                     f"{'yes' if covers else 'NO':>6} {196 * data_std[i] / abs(truth):7.2f} "
                     f"{196 * cons[i] / abs(truth):10.2f}  {dom[i]}{' (small-sample bound)' if n in small else ''}")
    lines.append(f"largest primary error {worst[0]:.1f} % ({worst[1]}); {covered} of {len(PRIMARY)} covered -> "
                 f"{'pass' if ok else 'FAIL'} (within 10 %, no failure)")
    return ok, "\n".join(lines), rel


#: targets over the draws, per primary derivative: coverage of the 95 % intervals at least ...
MIN_COVERAGE = 0.90
#: ... and the median relative half-width at most this many times the RMS relative error
MAX_WIDTH = 2.0


def summary(rel: list[dict[str, tuple[float, float, bool, float, float]]]) -> tuple[list[str], str]:
    """Per primary derivative over the draws: coverage, and the half-width over the RMS error with each draw's
    error in its own interval's units (``replica_verdict.draw_width_figure``: every draw has its own truth and
    interval, so ``1.96 / rms z`` with ``z = 1.96 |error| / half-width``), each with its one-sided 95 % Monte Carlo
    bound, and in how many draws the small-sample bound made the interval; the RMS relative error and the median
    relative half-width are printed beside them, and the coverage and width the AR bound alone would give (a
    study of the small-sample bound: not judged), and that bound without the logged starts' share (a study of
    that share: not judged). Returns the lines and the overall verdict ("met", "miss" or
    "unresolved")."""
    lines = [f"{'derivative':<14} {'RMS err %':>9} {'median hw %':>11}  {'coverage [upper]':<22} "
             f"{'hw/rms per draw [lower]':<24} {'small-sample':>12}  AR bound alone: coverage, hw/rms; "
             "without the start share"]
    figures = []
    for n in PRIMARY:
        err = np.array([r[n][0] for r in rel])
        hw = np.array([r[n][1] for r in rel])
        cov = coverage_figure(np.abs(err) <= hw, MIN_COVERAGE)
        width = draw_width_figure(hw, err, MAX_WIDTH, stat="rms")
        figures += [cov, width]
        rms = float(np.sqrt(np.mean(err ** 2)))
        small = sum(r[n][2] for r in rel)
        hw_ar = np.array([r[n][3] for r in rel])
        ar_cov = float(np.mean(np.abs(err) <= hw_ar))
        ar_width = draw_width_figure(hw_ar, err, MAX_WIDTH, stat="rms").value
        hw_ns = np.array([r[n][4] for r in rel])
        ns_cov = float(np.mean(np.abs(err) <= hw_ns))
        ns_width = draw_width_figure(hw_ns, err, MAX_WIDTH, stat="rms").value
        lines.append(f"{n:<14} {100 * rms:9.2f} {100 * np.median(hw):11.2f}  {cov.text():<22} {width.text():<24} "
                     f"{f'{small} of {len(rel)}':>12}  {ar_cov:.2f}, {ar_width:.2f}; {ns_cov:.2f}, {ns_width:.2f}")
    return lines, overall(figures)


def _settings(args: argparse.Namespace, states: list[str] | None, initial_sd: dict[str, float]) -> dict[str, Any]:
    """What a run's draws have in common (the draws of runs pooled must agree on every one of these)."""
    return {"fixed_spread": args.fixed_spread, "bound": args.bound, "start_state": args.start_state,
            "estimate_initial": states, "initial_sd": initial_sd, "truth_seed": args.truth_seed}


def _save(path: Path, settings: dict[str, Any], draws: list[dict[str, Any]], skipped: list[int]) -> None:
    """Write the run so far (after every draw: a run stopped early keeps its draws) for ``--pool``."""
    path.write_text(json.dumps({"bench": "aero_replica", "settings": settings, "draws": draws,
                                "skipped": skipped}, indent=1))


def _pooled(paths: Sequence[Path]) -> tuple[dict[str, Any], list[dict[str, Any]], list[int]]:
    """The settings, draws and skipped draw seeds of ``--save`` files; ``ValueError`` naming the file and field
    that does not fit (another bench's file, settings that differ from the first file's, a draw seed twice)."""
    settings: dict[str, Any] | None = None
    draws: list[dict[str, Any]] = []
    skipped: list[int] = []
    seen: dict[int, Path] = {}
    for path in paths:
        try:
            got = json.loads(path.read_text())
            if got.get("bench") != "aero_replica":
                raise ValueError(f"field 'bench' is {got.get('bench')!r}, not 'aero_replica'")
            mine, rows = got["settings"], got["draws"]
            for row in rows:
                seed = int(row["seed"])
                row["passed"] = bool(row["passed"])
                row["rel"] = {n: tuple(float(x) if k != 2 else bool(x) for k, x in enumerate(row["rel"][n]))
                              for n in PRIMARY}
                if seed in seen:
                    raise ValueError(f"draw {seed} is in {seen[seed]} as well: a draw pooled twice")
                seen[seed] = path
            skipped += [int(x) for x in got["skipped"]]
        except (OSError, KeyError, TypeError, AttributeError, json.JSONDecodeError) as err:
            raise ValueError(f"{path}: not a --save file of this bench ({type(err).__name__}: {err})") from None
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from None
        if settings is None:
            settings = mine
        elif mine != settings:
            diff = [k for k in sorted(set(settings) | set(mine)) if settings.get(k) != mine.get(k)]
            raise ValueError(f"{path}: settings {', '.join(f'{k}={mine.get(k)!r}' for k in diff)} differ from "
                             f"{paths[0]}'s ({', '.join(f'{k}={settings.get(k)!r}' for k in diff)}): the draws of "
                             "unlike runs are not one distribution")
        draws += rows
    return settings or {}, draws, skipped


def _verdict(settings: dict[str, Any], rel: list[dict[str, tuple[float, float, bool, float, float]]],
             passed: int, skipped: list[int], source: str) -> int:
    """Print the figures over the draws and the verdict; the exit status (1 on a failed draw or a shown miss)."""
    if not rel:
        print(f"every drawn truth diverges (draws {', '.join(map(str, skipped))}): nothing judged")
        return 1
    lines, verdict = summary(rel)
    gone = f" ({len(skipped)} skipped: the truth diverges)" if skipped else ""
    states = settings["estimate_initial"]
    print(f"over {len(rel)} draws{gone}{source} (truths {settings['fixed_spread']}, bound {settings['bound']!r}, "
          f"segment starts {settings['start_state']}, nuisance "
          f"{'auto' if states is None else 'initial ' + ', '.join(states) + ' and biases'}; targets: coverage >= "
          f"{MIN_COVERAGE:.2f}, median half-width <= {MAX_WIDTH:g} x the RMS error; [bound]: the one-sided 95 % "
          "Monte Carlo bound towards the target):")
    print("\n".join(lines))
    widths = {"met": "met", "miss": "MISSED (the draws show it)",
              "unresolved": f"no miss shown; the figures marked (unresolved) are past their targets by less than "
                            f"the Monte Carlo error of {len(rel)} draws"}[verdict]
    failed = passed < len(rel) or verdict == "miss"
    print(f"{passed} of {len(rel)} draws: every primary derivative within 10 %, no failure; per derivative "
          f"coverage and width: {widths} -> "
          f"{'FAIL' if failed else ('PASS' if verdict == 'met' else 'NO MISS SHOWN (unresolved, not a pass)')}")
    return 1 if failed else 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bound", choices=BOUNDS, default="ar", help="the data bound (identify aero's: ar)")
    parser.add_argument("--start-state", choices=("logged", "exact"), default="logged",
                        help="the state the tool reads at a segment start: interpolated from the log (default) or "
                             "the truth's")
    parser.add_argument("--estimate-initial", default=None, metavar="STATES",
                        help="comma-separated per-segment initial states to fit (with the gyro and accelerometer "
                             "biases) instead of the tool's automatic nuisance choice, e.g. "
                             "rate_body_x_rad_s,rate_body_y_rad_s,rate_body_z_rad_s,vel_body_y_m_s,quat_x")
    parser.add_argument("--truth-seed", type=int, default=None, help="keep this draw's truth, redraw only the noise")
    parser.add_argument("--fixed-spread", choices=FIXED_SPREADS, default="factor",
                        help="the truths' coefficients: times U(0.6, 1.6) (factor), and those at 0 (C_Y_p, C_Y_r) "
                             "drawn with the std the tool's consider covariance gives them (zeros), or every one not "
                             "primary drawn so about Aerosonde's value (consider)")
    parser.add_argument("--initial-sd", default=None, metavar="STATE=SD,...",
                        help="with --estimate-initial: those states' logged start as a measurement of this std "
                             "(a prior at the logged value), e.g. vel_body_x_m_s=0.07,vel_body_y_m_s=0.07")
    parser.add_argument("--save", type=Path, default=None,
                        help="write every draw's errors and half-widths here (JSON, after each draw), for --pool")
    parser.add_argument("--pool", type=Path, nargs="+", default=None,
                        help="no draws: the figures and verdict over the draws of these --save files together (runs "
                             "of other seeds with the same settings)")
    args = parser.parse_args(argv)
    if args.pool:
        try:
            settings, rows, skipped = _pooled(args.pool)
        except ValueError as err:
            parser.error(f"--pool {err}")
        return _verdict(settings, [r["rel"] for r in rows], sum(r["passed"] for r in rows), skipped,
                        f" of {len(args.pool)} runs pooled")
    if not 1 <= args.draws <= 50:
        parser.error("--draws must be in 1..50")
    states = None if args.estimate_initial is None else [x for x in args.estimate_initial.split(",") if x]
    known = FixedWingModel(FixedWingParams()).states.index
    if states is not None and (not states or any(x not in known for x in states)):
        parser.error(f"--estimate-initial {args.estimate_initial!r}: give states of the fixed-wing model "
                     f"({', '.join(known)})")
    initial_sd: dict[str, float] = {}
    for item in args.initial_sd.split(",") if args.initial_sd is not None else ():
        name, _, sd = item.partition("=")
        try:
            initial_sd[name] = float(sd)
        except ValueError:
            parser.error(f"--initial-sd {args.initial_sd!r}: {item!r} is not STATE=SD")
        if states is None or name not in states or not (np.isfinite(initial_sd[name]) and initial_sd[name] > 0):
            parser.error(f"--initial-sd {item!r}: give a state of --estimate-initial and a finite std > 0")
    if not LOG.exists():
        print(f"{LOG} is absent; nothing to replicate")
        return 2
    settings = _settings(args, states, initial_sd)
    passed, rel, skipped, saved = 0, [], [], []
    if args.save is not None:  # a path that cannot be written is named now, not after the first draw's minutes
        try:
            _save(args.save, settings, saved, skipped)
        except OSError as err:
            parser.error(f"--save {args.save}: cannot be written ({err.strerror})")
    for k in range(args.draws):
        try:
            ok, table, r = run_draw(args.seed + k, args.bound, args.start_state == "exact", states, args.truth_seed,
                                    initial_sd, args.fixed_spread)
        except TruthDivergesError as err:
            print(f"draw {args.seed + k}: skipped, {err} (no replica to identify)\n", flush=True)
            skipped.append(args.seed + k)
            if args.save is not None:
                _save(args.save, settings, saved, skipped)
            continue
        print(table + "\n", flush=True)
        passed += ok
        rel.append(r)
        saved.append({"seed": args.seed + k, "passed": bool(ok), "rel": {n: list(v) for n, v in r.items()}})
        if args.save is not None:
            _save(args.save, settings, saved, skipped)
    return _verdict(settings, rel, passed, skipped, "")

if __name__ == "__main__":
    raise SystemExit(main())

"""Fit and held-out segments that follow the manoeuvres: from a timeline file, the blocks the log itself shows,
else the input activity.

A timeline (``uavfmu excite`` writes one; ``*.timeline.json`` beside a log is found by name) lists blocks of
``axis, start_s, excitation_start_s, end_s`` in seconds since autopilot boot; ``log_first_sample_s`` in the
file (or the first entry of ``log_span_s``) maps them onto the log's own time axis, which starts at its first
sample. Each block becomes one segment from ``start_s`` (the mode switch, trim held) to ``end_s`` plus
``tail_s`` of the recovery. Per axis, every third block (the middle one of three repetitions) is held out for
scoring; an axis flown once is fitted only.

A timeline planned by ``uavfmu excite`` (times from the Lua script's trigger) is placed on the log by the
script's trigger mark (:func:`planned_on_log`). Without a timeline, the blocks the log shows are used
(:func:`flown_blocks`: the script's EXCT marks, else the ArduPlane MANUAL spans). Without those, segments are the
spans where a control surface moves faster than its slow trend (a
3-2-1-1, a doublet, a pilot's stick input), padded and merged; when none is found the airborne part is cut
into windows as before, and the caller says so. Whatever cut them, segments are then reduced to the spans where
the aircraft is airborne (:func:`airborne_parts`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmu_models.config import ConfigError
from identification.aero.model import Segment, SegmentError
from identification.logs.flightlog import FlightLog
from identification.logs.flown_blocks import (
    FlownBlock,
    flown_timeline,
    marked_blocks,
    mode_blocks,
    px4_mode_blocks,
    trigger_time_s,
)
from identification.logs.log_state import any_of, ground_level, parked_samples
from identification.logs.timeline import load_timeline

#: recovery time kept after a block's end [s]: the response to the last pulse is still informative
TAIL_S = 2.0
#: a segment is cut where the aircraft comes within this height [m] of the log's ground level or flies slower
#: than this airspeed [m/s]: the aerodynamic model's range ends there (the gear may touch the ground, whose
#: contact model no derivative describes, and what follows a ground strike is no manoeuvre)
AIRBORNE_HEIGHT_M = 10.0
AIRBORNE_AIRSPEED_M_S = 12.0
#: shortest airborne piece of a segment that is kept [s]
MIN_AIRBORNE_S = 3.0
#: longest segment cut from detected input activity [s]; longer spans are split into equal pieces, each fitted
#: from the log's state at its start (closed-loop flight moves the surfaces all the time: without a split
#: the whole flight would be one record, and drift, not the manoeuvres, would dominate the fit)
MAX_SEGMENT_S = 4.0


@dataclass(frozen=True)
class Block:
    """One excitation block of a timeline, times in seconds since boot."""

    axis: str
    start_s: float
    excitation_start_s: float
    end_s: float


@dataclass(frozen=True)
class TimelineFile:
    """The blocks of a timeline file and the boot time of the log's first sample."""

    path: Path
    blocks: list[Block]
    log_start_s: float | None
    planned: bool = False  #: written by ``uavfmu excite``: times from the Lua script's trigger


def load_timeline_blocks(path: Path) -> TimelineFile:
    """Read a timeline file through the shared schema (:func:`identification.logs.timeline.load_timeline`); a bad file
    raises :class:`SegmentError` naming the file, the field and the value."""
    try:
        tl = load_timeline(path)
    except ConfigError as err:
        raise SegmentError(str(err)) from None
    blocks = [Block(str(b.axis), float(b.start_s), float(b.excitation_start_s), float(b.end_s)) for b in tl.blocks]
    start = tl.log_first_sample_s
    span = (tl.model_extra or {}).get("log_span_s")
    if start is None and isinstance(span, list) and span and isinstance(span[0], (int, float)):
        start = float(span[0])
    planned = (tl.model_extra or {}).get("plan") == "uavfmu excite"
    return TimelineFile(Path(path), blocks, None if start is None else float(start), planned)


def planned_on_log(tl: TimelineFile, log: FlightLog) -> tuple[TimelineFile, list[str]]:
    """A timeline planned by ``uavfmu excite`` (times from the trigger, no ``log_first_sample_s``) placed on the
    log's time axis by the Lua script's trigger mark (EXCT phase 0); other timelines are returned as they are."""
    if tl.log_start_s is not None or not tl.planned:
        return tl, []
    t_trigger = trigger_time_s(log)
    if t_trigger is None:
        return tl, [f"timeline {tl.path.name} is a plan (times from the trigger) and the log has no EXCT trigger "
                    "mark: block times taken as log times"]
    return (TimelineFile(tl.path, tl.blocks, -t_trigger, planned=True),
            [f"timeline {tl.path.name}: planned times placed on the log by its trigger mark at {t_trigger:.3f} s"])


def flown_blocks(log: FlightLog) -> tuple[TimelineFile, list[FlownBlock]] | None:
    """The blocks the log itself shows: the Lua script's EXCT marks, else the spans in ArduPlane MANUAL, else
    (a PX4 ULog) the spans in nav_state MANUAL (:mod:`identification.logs.flown_blocks`), as a timeline on the
    log's time axis; None when none is there."""
    for find, source in ((marked_blocks, "EXCT marks"), (mode_blocks, "MANUAL mode spans"),
                         (px4_mode_blocks, "PX4 MANUAL nav_state spans")):
        blocks = find(log)
        if blocks:
            tl = flown_timeline(blocks, source)
            return TimelineFile(Path(log.source), [Block(str(b.axis), float(b.start_s), float(b.excitation_start_s),
                                                         float(b.end_s)) for b in tl.blocks], 0.0), blocks
    return None


def timeline_beside(log_path: Path) -> Path | None:
    """``NAME.timeline.json`` next to ``NAME.BIN`` (or ``NAME.bin``, ...), if it exists."""
    cand = Path(log_path).with_suffix(".timeline.json")
    return cand if cand.exists() else None


def timeline_segments(tl: TimelineFile, duration_s: float, tail_s: float = TAIL_S
                      ) -> tuple[list[Segment], list[Segment], list[str]]:
    """Fit and held-out segments on the log's time axis from a timeline; notes say what was dropped."""
    notes = []
    offset = tl.log_start_s if tl.log_start_s is not None else 0.0
    if tl.log_start_s is None:
        notes.append(f"timeline {tl.path.name}: no log_first_sample_s; block times taken as log times")
    by_axis: dict[str, list[Segment]] = {}
    for b in tl.blocks:
        seg = Segment(round(max(b.start_s - offset, 0.0), 3), round(min(b.end_s + tail_s - offset, duration_s), 3))
        if seg.t1_s - seg.t0_s < 1.0:
            notes.append(f"timeline block {b.axis} at {b.start_s:g} s lies outside the log; skipped")
            continue
        by_axis.setdefault(b.axis, []).append(seg)
    fit, val = [], []
    for segs in by_axis.values():
        held = len(segs) // 2 if len(segs) >= 2 else -1
        for i, s in enumerate(segs):
            (val if i == held else fit).append(s)
    if not fit:
        raise SegmentError(f"timeline {tl.path}: no block lies inside the log")
    return sorted(fit, key=lambda s: s.t0_s), sorted(val, key=lambda s: s.t0_s), notes


def active_segments(t_s: np.ndarray, u: np.ndarray, airborne: np.ndarray, pad_s: float = 1.0, tail_s: float = 3.0,
                    min_s: float = 3.0, max_s: float = MAX_SEGMENT_S) -> list[Segment]:
    """Spans where an input (columns of ``u`` at ``t_s``) departs from its 4 s running median by more than
    three robust std of its fast part (and at least 0.01 rad), padded by ``pad_s`` before and ``tail_s``
    after, merged, kept inside ``airborne`` samples, split at ``max_s``."""
    dt = float(np.median(np.diff(t_s)))
    half = max(int(2.0 / dt), 1)
    active = np.zeros(len(t_s), dtype=bool)
    for col in u.T:
        trend = np.array([np.median(col[max(0, k - half):k + half + 1]) for k in range(len(col))])
        dev = np.abs(col - trend)
        mad = float(np.median(np.abs(dev - np.median(dev)))) * 1.4826
        active |= dev > max(3.0 * mad, 0.01)
    grow = np.zeros_like(active)
    for k in np.flatnonzero(active):
        grow[max(0, k - int(pad_s / dt)):k + int(tail_s / dt) + 1] = True
    grow &= airborne
    out: list[Segment] = []
    k = 0
    while k < len(grow):
        if not grow[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(grow) and grow[j + 1]:
            j += 1
        t0, t1 = float(t_s[k]), float(t_s[j])
        n = max(1, math.ceil((t1 - t0) / max_s))
        if t1 - t0 >= min_s:
            step = (t1 - t0) / n
            out += [Segment(round(t0 + i * step, 3), round(t0 + (i + 1) * step, 3)) for i in range(n)]
        k = j + 1
    return out


def ground_level_m(log: FlightLog) -> float | None:
    """The log's ground level [m, its altitude scale], as the ground test of every replay computes it
    (``log_state.ground_level`` over the samples ``log_state.parked_samples`` finds parked: the ``landed`` flag
    or airspeed below ``log_state.WING_GROUND_AIRSPEED_M_S``); None when the log never shows the aircraft on
    the ground (a log that starts in the air: no height criterion then)."""
    if not log.has("altitude_m"):
        return None
    t = log.signal("altitude_m").t_s
    return ground_level(log, "fixed_wing", t, any_of(parked_samples(log, "fixed_wing", t, 0.0), len(t)))


def airborne(log: FlightLog, t_s: np.ndarray) -> np.ndarray:
    """Samples of ``t_s`` where the aircraft flies: more than :data:`AIRBORNE_HEIGHT_M` above the log's
    :func:`ground_level_m` (when known) and faster than :data:`AIRBORNE_AIRSPEED_M_S` (when logged)."""
    ok = np.ones(len(t_s), dtype=bool)
    level = ground_level_m(log)
    if level is not None:
        ok &= log.signal("altitude_m").resample(t_s) - level > AIRBORNE_HEIGHT_M
    if log.has("airspeed_m_s"):
        ok &= log.signal("airspeed_m_s").resample(t_s) > AIRBORNE_AIRSPEED_M_S
    return ok


def airborne_parts(log: FlightLog, segs: Sequence[Segment], min_s: float = MIN_AIRBORNE_S
                   ) -> tuple[list[Segment], list[str]]:
    """Each segment reduced to its spans (0.02 s grid) where the aircraft is :func:`airborne`, each of at least
    ``min_s`` and fitted from the log's state at its start: a record that reaches the ground cannot be fitted by
    an aerodynamic model, and what follows a ground strike is no manoeuvre. Notes say what was cut."""
    out, notes = [], []
    for s in segs:
        t = np.arange(s.t0_s, s.t1_s + 1e-9, 0.02)
        ok = airborne(log, t)
        if ok.all():
            out.append(s)
            continue
        edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))  # run starts and ends, alternating
        runs = [Segment(round(float(t[i]), 3), round(float(t[j - 1]), 3)) for i, j in zip(edges[::2], edges[1::2],
                                                                                            strict=True)]
        kept = [r for r in runs if r.t1_s - r.t0_s >= min_s]
        out += kept
        what = f"kept {', '.join(map(str, kept))}" if kept else f"dropped (no airborne span of {min_s:g} s)"
        notes.append(f"segment {s}: the aircraft is not airborne throughout (within {AIRBORNE_HEIGHT_M:g} m of the "
                     f"ground level or below {AIRBORNE_AIRSPEED_M_S:g} m/s); {what}")
    return out, notes


def split_segments(segs: Sequence[Segment], length_s: float) -> list[Segment]:
    """Each segment cut into consecutive pieces of at most ``length_s`` (a shorter last piece kept if >= 1 s)."""
    out = []
    for s in segs:
        t = s.t0_s
        while t < s.t1_s - 1e-9:
            t1 = min(t + length_s, s.t1_s)
            if t1 - t >= 1.0:
                out.append(Segment(round(t, 3), round(t1, 3)))
            t = t1
    return out


def airborne_windows(log: FlightLog, length_s: float = 2.0) -> list[Segment]:
    """Consecutive windows of ``length_s`` [s] (0.1 s grid) where the aircraft is :func:`airborne`."""
    alt, vas = log.signal("altitude_m"), log.signal("airspeed_m_s")
    t = np.arange(max(alt.t_s[0], vas.t_s[0]), min(alt.t_s[-1], vas.t_s[-1]), 0.1)
    ok = airborne(log, t)
    out, start = [], None
    for ti, flag in zip(t, ok, strict=True):
        if flag and start is None:
            start = ti
        if start is not None and (not flag or ti == t[-1]):
            n = int((ti - start) // length_s)
            out += [Segment(start + k * length_s, start + (k + 1) * length_s) for k in range(n)]
            start = None
    return out


def fallback_windows(log: FlightLog, window_s: float) -> tuple[list[Segment], list[Segment]]:
    """Alternating airborne windows (fit, held out): the old default when no manoeuvre is found."""
    auto = airborne_windows(log, window_s)
    if len(auto) < 2:
        raise SegmentError(f"{log.source}: fewer than two airborne windows of {window_s:g} s; give segments")
    return auto[0::2], auto[1::2]

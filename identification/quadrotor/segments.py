"""Fit and held-out windows of a quadrotor log: from its excitation blocks file, given windows, or airborne time.

A blocks file (``NAME.blocks.json`` beside the log, as the shared PX4 SITL flight has) lists excitation blocks
with ``block`` (``roll_3211``, ``yaw_doublet``, ..., ``posctl_settle``), ``start_s``, ``end_s`` and optionally
``rest_end_s``, in seconds since autopilot boot; ``FlightLog.boot_s`` maps them onto the log's time axis.
Each excitation block becomes one segment from its start to its rest end (``end_s`` + ``REST_S`` without one);
settle blocks are skipped. Every third segment (``hold_out_every``) is held out for scoring. Segments are then
cut into windows of ``window_s``, each replayed from the log's state at its start: a quadrotor's attitude is
open-loop unstable, so a long open-loop record drifts away whatever the parameters.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import Field

from fmu_models.config import ConfigError, Schema, validate_config
from fmu_models.quadrotor.constants import N_MOTORS
from identification.logs.flightlog import FlightLog
from identification.logs.log_state import any_of, ground_samples
from identification.logs.timeline import SpanError, parse_spans

#: rest kept after a block without ``rest_end_s`` [s]
REST_S = 3.0
#: most entries a blocks file may hold
MAX_BLOCKS = 2000
#: most windows one identification fits (each carries its own nuisance parameters: memory and time bound)
MAX_WINDOWS = 600

Seconds = Annotated[float, Field(ge=0.0, le=1e7)]


class BlockEntry(Schema):
    """One entry of a blocks file (times [s] since boot; ``*_us`` the same in microseconds, not read)."""

    block: str = Field(max_length=64)
    start_s: Seconds
    end_s: Seconds
    rest_end_s: Seconds | None = None
    set: int | None = Field(None, ge=0, le=1000)
    start_us: int | None = None
    end_us: int | None = None
    rest_end_us: int | None = None
    xy_after_m: float | None = None
    rel_alt_after_m: float | None = None


class BlocksFile(Schema):
    blocks: list[BlockEntry] = Field(max_length=MAX_BLOCKS)


class SegmentError(ValueError):
    """Segments that do not parse or lie outside the log."""


@dataclass(frozen=True)
class Segment:
    """A span of the log [s, the log's own time axis] with what it is (block name or ``window``)."""

    t0_s: float
    t1_s: float
    label: str = ""

    def __str__(self) -> str:
        return f"{self.t0_s:g}:{self.t1_s:g}"


def parse_windows(text: str, option: str = "--segments") -> list[Segment]:
    """``"t0:t1,t0:t1"`` (seconds from log start) into segments; errors name the option and the item."""
    try:
        out = [Segment(a, b, "given") for a, b in parse_spans(text, option)]
    except SpanError as err:
        raise SegmentError(str(err)) from None
    if not out:
        raise SegmentError(f"{option}: no segment in {text!r}")
    return out


def blocks_beside(log_path: Path) -> Path | None:
    """``NAME.blocks.json`` beside ``NAME.ulg`` (or any log suffix), if there."""
    p = Path(log_path).with_suffix(".blocks.json")
    return p if p.is_file() else None


def load_blocks(path: Path, log: FlightLog) -> list[Segment]:
    """Excitation segments of a blocks file on the log's time axis (settle blocks skipped)."""
    import json

    try:
        raw = json.loads(Path(path).read_text())
    except (OSError, ValueError) as err:
        raise SegmentError(f"{path}: not readable JSON ({err})") from None
    try:
        parsed = validate_config({"blocks": raw} if isinstance(raw, list) else raw, BlocksFile, str(path))
    except ConfigError as err:
        raise SegmentError(str(err)) from None
    out = []
    for b in parsed.blocks:
        if "settle" in b.block:
            continue
        end = b.rest_end_s if b.rest_end_s is not None else b.end_s + REST_S
        t0, t1 = b.start_s - log.boot_s, end - log.boot_s
        if t1 <= 0 or t0 >= log.duration_s:
            continue
        out.append(Segment(max(t0, 0.0), min(t1, log.duration_s), b.block))
    if not out:
        raise SegmentError(f"{path}: no excitation block lies inside {log.source} (boot time of its start "
                           f"{log.boot_s:g} s, {log.duration_s:g} s long)")
    return out


#: a pause longer than this [s] between ArduCopter SystemId samples (SIDD) starts a new chirp
SYSID_GAP_S = 0.5


def sysid_segments(log: FlightLog, rest_s: float = 2.0) -> list[Segment]:
    """The chirps of ArduCopter's SystemId mode: spans of its ``SIDD`` samples (logged while a chirp runs;
    ``SIDS`` holds the settings once per chirp) plus ``rest_s``, labelled with the ``SIDS`` axis where logged."""
    if not log.has("SIDD.Targ"):
        return []
    t = log.signal("SIDD.Targ").t_s
    if len(t) < 2:
        return []
    cuts = np.flatnonzero(np.diff(t) > SYSID_GAP_S) + 1
    axis = log.signal("SIDS.Ax") if log.has("SIDS.Ax") else None
    out = []
    for run in np.split(t, cuts):
        label = "sysid"
        if axis is not None and len(axis.t_s):
            i = int(np.clip(np.searchsorted(axis.t_s, run[0] + 1e-3, side="right") - 1, 0, len(axis.t_s) - 1))
            label = f"sysid axis {int(axis.values[i])}"
        out.append(Segment(float(run[0]), float(min(run[-1] + rest_s, log.duration_s)), label))
    return out


def airborne_segments(log: FlightLog, idle_pwm_us: float, piece_s: float = 6.0, rate_hz: float = 50.0
                      ) -> list[Segment]:
    """Airborne spans (motors above idle, above the ground level), cut into pieces of ``piece_s``."""
    t = np.arange(0.0, log.duration_s, 1.0 / rate_hz)
    ground = any_of(ground_samples(log, "quadrotor", t, idle_pwm_us), len(t))
    for k in range(1, N_MOTORS + 1):
        if not log.has(f"motor_{k}_pwm_us"):
            raise SegmentError(f"{log.source}: no motor_{k}_pwm_us: the motor commands are needed")
    air = ~ground
    out, start = [], None
    for i, a in enumerate(np.r_[air, False]):
        if a and start is None:
            start = i
        elif not a and start is not None:
            t0, t1 = t[start] + 1.0, t[min(i, len(t) - 1)] - 1.0  # a second off each end: take-off, landing
            n = int((t1 - t0) // piece_s)
            out += [Segment(t0 + k * piece_s, t0 + (k + 1) * piece_s, "airborne") for k in range(n)]
            start = None
    return out


def split_windows(segments: Sequence[Segment], window_s: float) -> list[Segment]:
    """Each segment cut into windows of ``window_s`` (a remainder under half a window joins the last one)."""
    out = []
    for s in segments:
        n = max(int((s.t1_s - s.t0_s) / window_s + 0.5), 1)
        edges = np.linspace(s.t0_s, s.t1_s, n + 1) if n > 1 else np.array([s.t0_s, s.t1_s])
        out += [Segment(float(a), float(b), s.label) for a, b in itertools.pairwise(edges)]
    return out


def hold_out(segments: Sequence[Segment], every: int) -> tuple[list[Segment], list[Segment]]:
    """(fit, held out): every ``every``-th segment (the 2nd, 5th, ...) held out; ``every`` 0 holds none out."""
    if every <= 0 or len(segments) < 3:
        return list(segments), []
    fit = [s for i, s in enumerate(segments) if i % every != 1]
    val = [s for i, s in enumerate(segments) if i % every == 1]
    return fit, val

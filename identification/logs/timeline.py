"""Manoeuvre timeline: when each excitation block ran (or is planned to run), for choosing fit and validation segments.

One schema reads both the timeline written beside a flown excitation log (e.g.
``fixed_wing/arduplane_sitl_fmu_excitation.timeline.json``, times in seconds since autopilot boot) and the
``*.timeline.json`` that ``uavfmu excite`` plans (times in seconds since the injecting script starts). The
``time_base`` text says which; ``log_first_sample_s`` (when present) converts to seconds from a log's first
sample, the base of ``identify aero --segments``.

Only the fields a segment chooser needs are typed; everything else a timeline carries (phases, responses,
trims, wall-clock stamps) is kept as extra data and not checked.

Use::

    tl = load_timeline("flight.timeline.json")      # ConfigError naming file, field and value on bad input
    for b in tl.blocks:
        print(b.axis, b.excitation_start_s, b.end_s)
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from fmu_models.config import FiniteFloat, Schema, load_config

__all__ = ["AXES", "Timeline", "TimelineBlock", "load_timeline"]

#: the axes a block can excite; ``multi`` = several surfaces at once (e.g. an orthogonal multisine)
AXES = ("aileron", "elevator", "rudder", "throttle", "multi")
Axis = Literal["aileron", "elevator", "rudder", "throttle", "multi"]


class _Open(Schema):
    """A schema that keeps (and does not check) keys it does not declare."""

    model_config = ConfigDict(extra="allow")


class TimelineBlock(_Open):
    """One excitation block: ``start_s`` = hand-over to the excitation mode, ``excitation_start_s`` = first
    input step (the trim before it is a settling phase), ``end_s`` = hand back to the recovery mode [s]."""

    index: int = Field(ge=0)
    axis: Axis
    channel: int | None = Field(None, ge=1, le=32)
    mode: str = ""
    input: str = ""
    pulse_unit_s: FiniteFloat | None = Field(None, gt=0, le=60)
    start_s: FiniteFloat
    excitation_start_s: FiniteFloat
    end_s: FiniteFloat
    #: surfaces a ``multi`` block moves, e.g. ["aileron", "rudder"]; empty for a single-axis block
    axes: list[Literal["aileron", "elevator", "rudder", "throttle"]] = Field(default_factory=list)

    @model_validator(mode="after")
    def _ordered(self) -> TimelineBlock:
        if not (self.start_s <= self.excitation_start_s < self.end_s):
            raise ValueError(
                f"block {self.index}: need start_s <= excitation_start_s < end_s, got {self.start_s!r}, "
                f"{self.excitation_start_s!r}, {self.end_s!r}")
        return self

    @property
    def excited_axes(self) -> tuple[str, ...]:
        """The surfaces this block moves (``axes`` for a ``multi`` block, else ``(axis,)``)."""
        return tuple(self.axes) if self.axis == "multi" else (self.axis,)


class Timeline(_Open):
    """A manoeuvre timeline: ``time_base`` says what the block times count from."""

    time_base: str = Field(min_length=1)
    blocks: list[TimelineBlock] = Field(min_length=1)
    log: str | None = None
    #: the log's first sample in the block time base [s] (subtract it to get ``identify aero --segments`` time)
    log_first_sample_s: FiniteFloat | None = None

    @model_validator(mode="after")
    def _unique_sorted(self) -> Timeline:
        idx = [b.index for b in self.blocks]
        if len(set(idx)) != len(idx):
            raise ValueError(f"block indices repeat: {idx}")
        starts = [b.start_s for b in self.blocks]
        if starts != sorted(starts):
            raise ValueError("blocks must be in time order (start_s increasing)")
        return self

    def shifted(self, offset_s: float, time_base: str) -> Timeline:
        """The same timeline with every block time plus ``offset_s`` (e.g. a planned timeline moved onto a log's
        clock: the log time of the trigger), described by ``time_base``."""
        keys = ("start_s", "excitation_start_s", "end_s")
        blocks = [b.model_copy(update={k: getattr(b, k) + offset_s for k in keys}) for b in self.blocks]
        return self.model_copy(update={"blocks": blocks, "time_base": time_base})

    def blocks_for(self, axis: str) -> list[TimelineBlock]:
        """Blocks that move ``axis`` (including ``multi`` blocks that list it)."""
        return [b for b in self.blocks if axis in b.excited_axes or b.axis == axis]


def load_timeline(path: str | Path) -> Timeline:
    """Read a timeline JSON (flown or planned); :class:`fmu_models.config.ConfigError` lists every problem."""
    return load_config(path, Timeline)


class SpanError(ValueError):
    """A time span given as text (``t0:t1``) that does not parse or is not a forward span from the log start."""


def parse_spans(items: str | Iterable[str], option: str = "--segments") -> list[tuple[float, float]]:
    """``"t0:t1,t0:t1"`` (or the items already split) into (t0, t1) pairs [s from the log start]; errors name the
    option and the item. Empty input gives an empty list (the caller decides whether that is an error)."""
    parts = items.split(",") if isinstance(items, str) else list(items)
    out = []
    for item in filter(None, (s.strip() for s in parts)):
        try:
            a, b = (float(v) for v in item.split(":"))
        except ValueError:
            raise SpanError(f"{option}: {item!r} is not t0:t1 in seconds") from None
        if not (math.isfinite(a) and math.isfinite(b) and b > a >= 0):
            raise SpanError(f"{option}: {item!r} needs 0 <= t0 < t1")
        out.append((a, b))
    return out

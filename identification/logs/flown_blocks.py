"""Where the excitation blocks were flown, read off the log itself: no timeline file, no time base to know.

Two sources, both on the log's own time axis (seconds from its first sample, the axis every
:class:`~identification.logs.flightlog.FlightLog` signal and ``identify aero`` segment uses; the DataFlash reader
subtracts the boot time of the first sample, so nobody needs to know it):

- **EXCT marks** (:func:`marked_blocks`): the ``uavfmu excite`` Lua script logs ``EXCT`` messages
  (``Blk, Ph, Ax, Tms, Pms``: block index, phase, axis code of :data:`AXIS_CODES`, the script's time since the
  trigger [ms] and the planned time of that phase [ms]) at the first scheduler tick at or after each planned
  phase time, time-stamped by the logger (``TimeUS``: the actual time). A block runs from its hand-over mark
  (phase 1) to its recovery mark (phase 3), or to the done/abort mark (4/5) that ends it; its input starts at
  the input mark (phase 2). A block aborted before its input mark is dropped.
- **Mode spans** (:func:`mode_blocks`): a flight flown by RC override (``docs/examples/excite_rc_override.py``)
  or by hand switches into the excitation mode (ArduPlane MANUAL) for each block and back to a stabilised mode
  between blocks. Each span in that mode is a block; its axis is the control that moves most about its value
  at the span's start (RC input ``RCIN`` on the ``RCMAP_*`` channels when logged, else the servo outputs),
  "multi" when a second one moves at least half as much; its input starts where that control first departs
  from its start value. PX4 ULogs (:func:`px4_mode_blocks`): the spans in a ``vehicle_status.nav_state``
  (MANUAL, the fixed-wing RC-override flights; ALTCTL for the quadrotor stick flights) with the sticks of
  ``manual_control_setpoint``.

:func:`flown_timeline` turns either list into the :class:`~identification.logs.timeline.Timeline` that
``identify aero`` cuts segments from.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from identification.logs.flightlog import FlightLog
from identification.logs.timeline import Timeline

#: EXCT.Ph values written by the Lua script
PHASE_START, PHASE_HANDOVER, PHASE_INPUT, PHASE_RECOVERY, PHASE_DONE, PHASE_ABORT = 0, 1, 2, 3, 4, 5
#: EXCT.Ax codes: the block's axis (``multi``: several surfaces at once)
AXIS_CODES = ("aileron", "elevator", "rudder", "throttle", "multi")
#: ArduPlane mode number of MANUAL (Plane/mode.h), the excitation mode of the RC-override flights
ARDUPLANE_MANUAL = 0
#: controls whose motion names a mode span's axis, with the ArduPilot RCMAP parameter of their RC input
CONTROLS = {"aileron": "RCMAP_ROLL", "elevator": "RCMAP_PITCH", "throttle": "RCMAP_THROTTLE",
            "rudder": "RCMAP_YAW"}
#: default RC input channels (ArduPilot's RCMAP defaults: AETR)
DEFAULT_RCMAP = {"RCMAP_ROLL": 1, "RCMAP_PITCH": 2, "RCMAP_THROTTLE": 3, "RCMAP_YAW": 4}
#: a control moves in a mode span when its peak departure from the span's start value exceeds this [us]
MIN_MOTION_US = 10.0
#: a second control counts for a ``multi`` block when it moves at least this share of the largest motion
MULTI_SHARE = 0.5
#: shortest mode span taken as a block [s] (a brief mode flick is no manoeuvre)
MIN_SPAN_S = 2.0
#: PX4 ``vehicle_status.nav_state`` of manual flight (NAVIGATION_STATE_MANUAL; 1 ALTCTL, 2 POSCTL, 15 STAB)
PX4_MANUAL = 0
#: PX4 ``manual_control_setpoint`` field per control: PX4 1.14+ name, then the 1.13 one
PX4_STICKS = {"aileron": ("roll", "y"), "elevator": ("pitch", "x"), "rudder": ("yaw", "r"),
              "throttle": ("throttle", "z")}
#: a stick moves in a mode span when its peak departure exceeds this (normalised sticks, -1..1)
MIN_MOTION_STICK = 0.02


@dataclass(frozen=True)
class FlownBlock:
    """One flown block on the log's time axis [s from its first sample]; ``source`` says how it was found."""

    index: int
    axis: str
    start_s: float
    excitation_start_s: float
    end_s: float
    source: str
    axes: tuple[str, ...] = ()
    aborted: bool = False

    def line(self) -> str:
        what = self.axis + (f" ({', '.join(self.axes)})" if self.axes else "")
        return (f"block {self.index} {what}: {self.start_s:.2f}-{self.end_s:.2f} s, input from "
                f"{self.excitation_start_s:.2f} s ({self.source}{', aborted' if self.aborted else ''})")


def _column(log: FlightLog, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    if not log.has(name):
        return None
    s = log.signal(name)
    return np.asarray(s.t_s, float), np.asarray(s.values, float)


def marked_blocks(log: FlightLog) -> list[FlownBlock]:
    """The blocks the ``EXCT`` marks of the Lua script delimit (see the module docstring); [] without marks."""
    blk, ph = _column(log, "EXCT.Blk"), _column(log, "EXCT.Ph")
    if blk is None or ph is None:
        return []
    t, index = blk
    phase = ph[1]
    ax = _column(log, "EXCT.Ax")
    axis_code = ax[1] if ax is not None else np.full(len(t), np.nan)
    out: list[FlownBlock] = []
    cur: tuple[int, float, int | None] | None = None  # open block: index, hand-over time, axis code
    t_input: float | None = None
    for k in np.argsort(t, kind="stable"):
        i, p, tk = int(index[k]), int(phase[k]), float(t[k])
        if p == PHASE_HANDOVER:
            code = axis_code[k]
            cur = (i, tk, int(code) if np.isfinite(code) and 0 <= code < len(AXIS_CODES) else None)
            t_input = None
        elif cur is None or cur[0] != i:
            continue
        elif p == PHASE_INPUT:
            t_input = tk
        elif p in (PHASE_RECOVERY, PHASE_DONE, PHASE_ABORT):
            if t_input is not None and cur[2] is not None and tk > t_input:
                out.append(FlownBlock(i, AXIS_CODES[cur[2]], cur[1], t_input, tk, "EXCT marks",
                                      aborted=p == PHASE_ABORT))
            cur = None
    return out


def _rc_or_servo(log: FlightLog, control: str) -> tuple[np.ndarray, np.ndarray, str] | None:
    """The control's RC input (``RCIN.C<n>``, channel from ``RCMAP_*``) or, without it, its servo output."""
    rcmap = CONTROLS[control]
    n = int(log.params.get(rcmap, DEFAULT_RCMAP[rcmap]))
    col = _column(log, f"RCIN.C{n}")
    if col is not None:
        return col[0], col[1], f"RCIN.C{n}"
    col = _column(log, f"{control}_pwm_us")
    return (col[0], col[1], f"{control} output") if col is not None else None


def _spans(t: np.ndarray, modes: np.ndarray, mode: int, end_s: float) -> list[tuple[float, float]]:
    """(start, end) of every stretch in ``mode``: a mode message repeated with the same value continues it."""
    keep = np.r_[True, modes[1:] != modes[:-1]]
    t, modes = t[keep], modes[keep]
    return [(float(t[k]), float(t[k + 1]) if k + 1 < len(t) else end_s) for k in np.flatnonzero(modes == mode)]


def _span_blocks(spans: list[tuple[float, float]], controls: dict[str, tuple[np.ndarray, np.ndarray, str]],
                 min_motion: float, what: str) -> list[FlownBlock]:
    """A block per span at least :data:`MIN_SPAN_S` long in which a control moves more than ``min_motion``."""
    out: list[FlownBlock] = []
    for t0, t1 in spans:
        if t1 - t0 < MIN_SPAN_S:
            continue
        motion: dict[str, tuple[float, float]] = {}
        for name, (ts, vs, _src) in controls.items():
            inside = (ts >= t0) & (ts < t1)
            if inside.sum() < 3:
                continue
            v = vs[inside]
            dev = np.abs(v - v[0])
            first = np.flatnonzero(dev > max(min_motion, 0.2 * dev.max()))
            if dev.max() > min_motion and first.size:
                motion[name] = (float(dev.max()), float(ts[inside][first[0]]))
        if not motion:
            continue
        top = max(v[0] for v in motion.values())
        moving = sorted((c for c, v in motion.items() if v[0] >= MULTI_SHARE * top), key=lambda c: -motion[c][0])
        axis = moving[0] if len(moving) == 1 else "multi"
        t_in = min(motion[c][1] for c in moving)
        src = ", ".join(sorted({controls[c][2] for c in moving}))
        out.append(FlownBlock(len(out) + 1, axis, t0, t_in, t1, f"{what} span, {src}",
                              tuple(moving) if axis == "multi" else ()))
    return out


def mode_blocks(log: FlightLog, mode: int = ARDUPLANE_MANUAL) -> list[FlownBlock]:
    """Blocks from the spans in flight mode ``mode`` (ArduPilot ``MODE.Mode``) and the controls that move in
    them (see the module docstring); [] when the log has no MODE messages or no control signal."""
    col = _column(log, "MODE.Mode")
    if col is None:
        return []
    controls = {c: s for c in CONTROLS if (s := _rc_or_servo(log, c)) is not None}
    if not controls:
        return []
    return _span_blocks(_spans(col[0], col[1], mode, log.duration_s), controls, MIN_MOTION_US, f"mode {mode}")


def px4_mode_blocks(log: FlightLog, nav_state: int = PX4_MANUAL) -> list[FlownBlock]:
    """Blocks of a PX4 ULog from the spans in ``vehicle_status.nav_state`` ``nav_state`` (MANUAL by default: the
    fixed-wing RC-override / MANUAL_CONTROL flights ``uavfmu excite`` plans for PX4) and the sticks that move in
    them (``manual_control_setpoint``, PX4 1.14+ ``roll/pitch/yaw/throttle`` or 1.13 ``y/x/r/z``); [] without."""
    col = _column(log, "vehicle_status.nav_state")
    if col is None:
        return []
    controls = {}
    for control, names in PX4_STICKS.items():
        for field in names:
            c = _column(log, f"manual_control_setpoint.{field}")
            if c is not None:
                controls[control] = (c[0], c[1], f"manual_control_setpoint.{field}")
                break
    if not controls:
        return []
    return _span_blocks(_spans(col[0], col[1], nav_state, log.duration_s), controls, MIN_MOTION_STICK,
                        f"nav_state {nav_state}")


def flown_timeline(blocks: Sequence[FlownBlock], source: str) -> Timeline:
    """The blocks as a :class:`Timeline` on the log's time axis (``log_first_sample_s`` = 0)."""
    return Timeline.model_validate({
        "time_base": f"seconds from the log's first sample ({source})", "log_first_sample_s": 0.0,
        "blocks": [{"index": k, "block": b.index, "axis": b.axis, "axes": [a for a in b.axes if a != "multi"],
                    "start_s": b.start_s, "excitation_start_s": b.excitation_start_s, "end_s": b.end_s,
                    "source": b.source, "aborted": b.aborted} for k, b in enumerate(blocks, start=1)]})


def trigger_time_s(log: FlightLog) -> float | None:
    """Log time [s] of the Lua script's trigger mark (EXCT phase 0), the zero of a planned timeline; None if
    the log has none."""
    ph = _column(log, "EXCT.Ph")
    if ph is None:
        return None
    hits = ph[0][ph[1] == PHASE_START]
    return float(hits[0]) if hits.size else None


__all__ = ["AXIS_CODES", "FlownBlock", "flown_timeline", "marked_blocks", "mode_blocks", "px4_mode_blocks",
           "trigger_time_s"]

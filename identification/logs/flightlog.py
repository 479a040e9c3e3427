"""One in-memory flight-log type: named signals, time in seconds from log start, SI units, NED/FRD frames.

Canonical signal names are listed in docs/interfaces.md; every raw field is also kept as ``MSG.Field`` in
the log's own units.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fmu_models.common.units import DEG_TO_RAD, G0_M_S2

#: canonical battery signals [V], [A] (``battery_voltage_V`` is kept as an alias of the voltage for older callers)
BATTERY_VOLTAGE, BATTERY_CURRENT, BATTERY_VOLTAGE_LEGACY = "battery_voltage_v", "battery_current_a", "battery_voltage_V"


class LogError(ValueError):
    """A log that cannot be read (missing, empty, corrupt); the message names the file."""


class MissingSignalError(LogError, KeyError):
    """A signal the caller needs is not in the log; the message names the file and what is there."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


#: a pause with no sample of any kind longer than this (and than GAP_FACTOR x the median interval) is a gap [s]
GAP_MIN_S = 0.5
GAP_FACTOR = 20.0
#: a forward step in time longer than this splits the log; only the part with the most samples is kept [s]
JUMP_S = 60.0
#: identification refuses a log whose damage fraction exceeds this unless forced
DEFAULT_MAX_DAMAGE = 0.05
#: |value| at or above which a canonical sensor signal counts as clipped (16 g, 2000 deg/s full scale, 2 % margin)
CLIP_LIMITS = {"accel_body_": 0.98 * 16 * G0_M_S2, "gyro_body_": 0.98 * 2000 * DEG_TO_RAD}
_MAX_LISTED = 20  #: gaps/jumps/regions kept in detail (the counts are always complete)


@dataclass
class DataQuality:
    """What a reader found wrong in one log, and what it kept (times [s] from the kept log start).

    ``damaged_regions``: ``(byte offset, bytes)``; ``gaps``: ``(at_s, length_s)`` pauses inside the kept data;
    ``jumps``: ``(at_s, length_s)`` forward time steps > ``JUMP_S`` where the log was split;
    ``dropped_segments``: ``(duration_s, samples)`` parts beyond a jump that were dropped.
    """

    source: str
    bytes_total: int = 0
    bytes_skipped: int = 0
    damaged_regions: list[tuple[int, int]] = field(default_factory=list)
    messages_total: int = 0
    messages_skipped: int = 0
    samples_total: int = 0
    gaps: list[tuple[float, float]] = field(default_factory=list)
    gap_count: int = 0
    gap_total_s: float = 0.0
    jumps: list[tuple[float, float]] = field(default_factory=list)
    dropped_segments: list[tuple[float, int]] = field(default_factory=list)
    samples_beyond_jumps: int = 0
    backward_steps: int = 0
    samples_reordered: int = 0
    samples_backward_dropped: int = 0
    time_outliers: int = 0
    duplicate_samples: int = 0
    non_finite_times: int = 0
    non_finite_samples: int = 0
    canonical_samples: int = 0
    clipped_samples: int = 0
    time_total_s: float = 0.0
    time_kept_s: float = 0.0

    def add_damage(self, offset: int, nbytes: int, messages: int = 1) -> None:
        """Record ``nbytes`` skipped at byte ``offset`` holding about ``messages`` messages."""
        self.bytes_skipped += nbytes
        self.messages_skipped += messages
        if len(self.damaged_regions) < _MAX_LISTED:
            self.damaged_regions.append((offset, nbytes))

    @property
    def samples_dropped(self) -> int:
        return (self.samples_beyond_jumps + self.samples_backward_dropped + self.time_outliers
                + self.non_finite_times)

    @property
    def damage_fraction(self) -> float:
        """Largest lost share: bytes, messages, samples, canonical values or flight time (0 clean .. 1)."""
        parts = [
            self.bytes_skipped / self.bytes_total if self.bytes_total else 0.0,
            self.messages_skipped / self.messages_total if self.messages_total else 0.0,
            self.samples_dropped / self.samples_total if self.samples_total else 0.0,
            self.non_finite_samples / self.canonical_samples if self.canonical_samples else 0.0,
            1.0 - self.time_kept_s / self.time_total_s if self.time_total_s > 0 else 0.0,
        ]
        return float(min(1.0, max(0.0, *parts)))

    @property
    def ok(self) -> bool:
        """True when the reader found nothing wrong at all."""
        return not self._findings()

    def _findings(self) -> list[str]:
        s, out = self.source, []
        if self.bytes_skipped:
            first = f"; first at byte {self.damaged_regions[0][0]}" if self.damaged_regions else ""
            out.append(f"{s}: {self.bytes_skipped} of {self.bytes_total} bytes could not be decoded and were "
                       f"skipped ({self.messages_skipped} damaged message(s) in {len(self.damaged_regions)}"
                       f"{'+' if len(self.damaged_regions) >= _MAX_LISTED else ''} region(s){first})")
        elif self.messages_skipped:
            out.append(f"{s}: {self.messages_skipped} of {self.messages_total} message(s) damaged and skipped")
        if self.jumps or self.samples_beyond_jumps:
            lens = ", ".join(f"{j[1]:+.3g} s at t={j[0]:.1f} s" for j in self.jumps[:3])
            dropped = sum(d[0] for d in self.dropped_segments)
            out.append(f"{s}: time jump(s) {lens or '(isolated)'}: the log was split there and {dropped:.1f} s "
                       f"({self.samples_beyond_jumps} samples) beyond the jump(s) dropped")
        if self.time_outliers or self.non_finite_times:
            out.append(f"{s}: {self.time_outliers + self.non_finite_times} sample(s) with implausible or "
                       "non-finite time stamps dropped")
        if self.backward_steps:
            out.append(f"{s}: time went backwards {self.backward_steps} time(s): {self.samples_reordered} "
                       f"sample(s) put back in order, {self.samples_backward_dropped} dropped (beyond the tolerance)")
        if self.duplicate_samples:
            out.append(f"{s}: {self.duplicate_samples} duplicated sample(s) dropped")
        if self.gap_count:
            longest = max(self.gaps, key=lambda g: g[1]) if self.gaps else (0.0, 0.0)
            out.append(f"{s}: {self.gap_count} gap(s) without data, {self.gap_total_s:.2f} s in all (longest "
                       f"{longest[1]:.2f} s at t={longest[0]:.1f} s)")
        if self.non_finite_samples:
            out.append(f"{s}: {self.non_finite_samples} non-finite (NaN/inf) value(s) removed from canonical signals")
        if self.clipped_samples:
            out.append(f"{s}: {self.clipped_samples} clipped sensor sample(s) (at full scale)")
        return out

    def lines(self) -> list[str]:
        """Console lines naming the file (empty when the log is clean)."""
        found = self._findings()
        if not found:
            return []
        return [*found, f"{self.source}: kept {self.time_kept_s:.1f} of {self.time_total_s:.1f} s of log; "
                        f"damage {100 * self.damage_fraction:.1f} %"]

    def to_dict(self) -> dict:
        """JSON-ready summary (finite numbers and lists only) for metrics files."""
        return {
            "source": self.source, "ok": self.ok, "damage_fraction": self.damage_fraction,
            "bytes_total": self.bytes_total, "bytes_skipped": self.bytes_skipped,
            "damaged_regions": [list(r) for r in self.damaged_regions],
            "messages_total": self.messages_total, "messages_skipped": self.messages_skipped,
            "samples_total": self.samples_total, "samples_dropped": self.samples_dropped,
            "gap_count": self.gap_count, "gap_total_s": self.gap_total_s, "gaps": [list(g) for g in self.gaps],
            "jumps": [list(j) for j in self.jumps], "dropped_segments": [list(d) for d in self.dropped_segments],
            "samples_beyond_jumps": self.samples_beyond_jumps, "backward_steps": self.backward_steps,
            "samples_reordered": self.samples_reordered, "samples_backward_dropped": self.samples_backward_dropped,
            "time_outliers": self.time_outliers, "duplicate_samples": self.duplicate_samples,
            "non_finite_times": self.non_finite_times, "non_finite_samples": self.non_finite_samples,
            "clipped_samples": self.clipped_samples, "time_total_s": self.time_total_s,
            "time_kept_s": self.time_kept_s, "lines": self.lines(),
        }


def check_quality(log: FlightLog, force: bool = False, max_damage: float = DEFAULT_MAX_DAMAGE) -> None:
    """Raise :class:`LogError` when ``log.quality.damage_fraction`` exceeds ``max_damage`` (0..1) unless
    ``force``; the message names the file, the damage and how to proceed."""
    q = getattr(log, "quality", None)
    if q is None or force or q.damage_fraction <= max_damage:
        return
    detail = "; ".join(line.split(": ", 1)[-1] for line in q.lines()[:3])
    raise LogError(f"{log.source}: {100 * q.damage_fraction:.1f} % of the log is damaged or lost (limit "
                   f"{100 * max_damage:.1f} %): {detail}. Repair or re-download the log, or pass --force to use "
                   "what is left")


@dataclass(frozen=True)
class Signal:
    """One time series: ``t_s`` [s] ascending and ``values`` in ``unit``."""

    name: str
    t_s: np.ndarray
    values: np.ndarray
    unit: str
    description: str = ""

    def resample(self, t_s: np.ndarray) -> np.ndarray:
        """Linear interpolation at ``t_s`` (held constant outside the recorded span)."""
        return np.interp(t_s, self.t_s, self.values)


@dataclass
class FlightLog:
    """Signals by name, logged parameters, vehicle kind, reader warnings and data quality of one log file."""

    source: str
    fmt: str
    signals: dict[str, Signal]
    params: dict[str, float]
    vehicle: str | None = None
    warnings: list[str] = field(default_factory=list)
    quality: DataQuality | None = None
    boot_s: float = 0.0  #: autopilot boot time [s] of the log's t = 0 (ULog: its start timestamp; else 0)

    def __post_init__(self) -> None:
        if self.quality is None:
            self.quality = DataQuality(self.source)

    def signal(self, name: str) -> Signal:
        if name not in self.signals:
            canonical = sorted(n for n in self.signals if "." not in n)
            raise MissingSignalError(
                f"{self.source}: signal {name!r} is not in this {self.fmt} log; canonical signals present: "
                f"{', '.join(canonical) or 'none'}"
            )
        return self.signals[name]

    def has(self, name: str) -> bool:
        return name in self.signals

    @property
    def duration_s(self) -> float:
        ends = [s.t_s[-1] for s in self.signals.values() if len(s.t_s)]
        return float(max(ends)) if ends else 0.0


#: altitudes above mean sea level an equivalent airspeed is converted at, in order of preference (ArduPilot's
#: baro AMSL altitude, the canonical GPS height)
AMSL_ALTITUDES = ("BARO.AltAMSL", "height_m")


def _measured(values: np.ndarray) -> bool:
    """Whether an altitude column holds a measurement: some finite value, not all exactly 0 (a field a firmware
    declares but does not fill)."""
    ok = np.isfinite(values)
    return bool(ok.any() and np.any(values[ok] != 0.0))


def true_airspeed(log: FlightLog, logged_as: str) -> None:
    """Make ``airspeed_m_s`` of ``log`` the true airspeed the FMUs output, from the equivalent airspeed the
    autopilot logged (``logged_as``, e.g. ``ARSP.Airspeed``): times ``fmu_models.common.atmosphere.eas_to_tas`` at
    the first of :data:`AMSL_ALTITUDES` logged; the logged value stays as ``airspeed_eas_m_s``. Unconverted, an
    airspeed logged at 600 m reads 3 % (0.8 m/s at 27 m/s) below the true one. Without an AMSL altitude the
    airspeed stays as logged and a warning says so."""
    from fmu_models.common.atmosphere import eas_to_tas

    s = log.signals.get("airspeed_m_s")
    if s is None or not len(s.t_s):
        return
    alt = next((n for n in AMSL_ALTITUDES if n in log.signals and _measured(log.signals[n].values)), None)
    if alt is None:
        log.warnings.append(
            f"{log.source}: airspeed_m_s is the equivalent airspeed the autopilot logged ({logged_as}); no altitude "
            f"above mean sea level ({', '.join(AMSL_ALTITUDES)}) is logged to convert it to the true airspeed the "
            f"FMUs output, so it is kept as logged ({100 * (float(eas_to_tas(1000.0)) - 1):.1f} % low at 1000 m)")
        return
    a = log.signals[alt]
    ok = np.isfinite(a.values)
    factor = eas_to_tas(np.interp(s.t_s, a.t_s[ok], a.values[ok]))
    log.signals["airspeed_eas_m_s"] = Signal("airspeed_eas_m_s", s.t_s, s.values, "m/s",
                                             f"equivalent airspeed as logged ({logged_as})")
    log.signals["airspeed_m_s"] = Signal("airspeed_m_s", s.t_s, s.values * factor, "m/s",
                                         f"true airspeed: {logged_as} (equivalent) x EAS2TAS at {alt} (ISA)")


def add_battery(signals: dict[str, Signal], t_s: np.ndarray, voltage_v: np.ndarray | None,
                current_a: np.ndarray | None, source: str) -> None:
    """Add ``battery_voltage_v`` [V] / ``battery_current_a`` [A] when the log really measured them.

    Samples that are not finite, and voltages <= 0 (no sensor: ArduPilot logs 0, MAVLink 65535 mV is mapped
    to NaN by the caller), are left out; a current is added only with a measured voltage or when it is not
    all zero. A name already present (an earlier, better source) is kept.
    """
    t = np.asarray(t_s, dtype=float)
    if voltage_v is not None and BATTERY_VOLTAGE not in signals:
        v = np.asarray(voltage_v, dtype=float)
        keep = np.isfinite(v) & (v > 0.0) & np.isfinite(t)
        if keep.any():
            sig = Signal(BATTERY_VOLTAGE, t[keep], v[keep], "V", f"battery voltage from {source}")
            signals[BATTERY_VOLTAGE] = sig
            signals.setdefault(BATTERY_VOLTAGE_LEGACY, Signal(BATTERY_VOLTAGE_LEGACY, sig.t_s, sig.values, "V",
                                                              f"alias of {BATTERY_VOLTAGE}"))
    if current_a is not None and BATTERY_CURRENT not in signals:
        c = np.asarray(current_a, dtype=float)
        keep = np.isfinite(c) & np.isfinite(t)
        measured = BATTERY_VOLTAGE in signals or bool(np.any(c[keep] != 0.0))
        if keep.any() and measured:
            signals[BATTERY_CURRENT] = Signal(BATTERY_CURRENT, t[keep], c[keep], "A", f"battery current from {source}")


def _gap_threshold(t_sorted: np.ndarray) -> float:
    """Pause [s] that counts as a gap in a sorted time array: GAP_FACTOR x its median positive interval."""
    d = np.diff(t_sorted)
    d = d[d > 0]
    return max(GAP_MIN_S, GAP_FACTOR * float(np.median(d))) if d.size else GAP_MIN_S


def _isolated_outliers(t: np.ndarray, thr: float) -> np.ndarray:
    """Single samples whose time is far from both neighbours while the neighbours agree (a corrupt stamp)."""
    out = np.zeros(t.size, dtype=bool)
    if t.size >= 3:
        before, after, bridge = t[1:-1] - t[:-2], t[2:] - t[1:-1], t[2:] - t[:-2]
        out[1:-1] = (np.abs(before) > thr) & (np.abs(after) > thr) & (np.abs(bridge) <= thr)
    return out


def _time_groups(signals: dict[str, Signal]) -> list[tuple[np.ndarray, list[str]]]:
    """Signals that share one time array (one message stream), in the reader's (file) order."""
    groups: dict[int, tuple[np.ndarray, list[str]]] = {}
    for name, s in signals.items():
        groups.setdefault(id(s.t_s), (s.t_s, []))[1].append(name)
    return list(groups.values())


def _main_segment(times: list[np.ndarray], q: DataQuality, jump_s: float) -> tuple[float, float]:
    """Split the union of all sample times at forward steps > ``jump_s``; keep the part with most samples."""
    all_t = np.sort(np.concatenate(times)) if times else np.empty(0)
    if all_t.size == 0:
        raise LogError(f"{q.source}: no sample has a finite time stamp")
    cut = np.flatnonzero(np.diff(all_t) > jump_s)
    first, last = np.r_[0, cut + 1], np.r_[cut, all_t.size - 1]
    starts, ends, counts = all_t[first], all_t[last], last - first + 1
    k = int(np.argmax(counts))
    q.time_total_s = float(np.sum(ends - starts))
    for i in range(len(starts)):
        if i != k:
            q.samples_beyond_jumps += int(counts[i])
            if len(q.dropped_segments) < _MAX_LISTED:
                q.dropped_segments.append((float(ends[i] - starts[i]), int(counts[i])))
    for i in cut[:_MAX_LISTED]:
        q.jumps.append((float(all_t[i] - starts[k]), float(all_t[i + 1] - all_t[i])))
    return float(starts[k]), float(ends[k])


def _clean_group(t: np.ndarray, lo: float, hi: float, q: DataQuality) -> np.ndarray:
    """Indices (in time order) of the samples of one stream to keep."""
    t = np.asarray(t, dtype=float)
    q.samples_total += t.size
    finite = np.isfinite(t)
    q.non_finite_times += int(np.count_nonzero(~finite))
    idx = np.flatnonzero(finite)
    ts = t[idx]
    thr = _gap_threshold(np.sort(ts))
    bad = _isolated_outliers(ts, thr)
    inside = (ts >= lo) & (ts <= hi)
    q.time_outliers += int(np.count_nonzero(bad & inside))
    idx, ts = idx[inside & ~bad], ts[inside & ~bad]
    back = np.diff(ts) < 0
    if back.any():
        q.backward_steps += int(np.count_nonzero(back))
        keep = ts >= np.maximum.accumulate(ts) - thr  # small reorders are sorted, resets dropped
        q.samples_backward_dropped += int(np.count_nonzero(~keep))
        idx, ts = idx[keep], ts[keep]
        order = np.argsort(ts, kind="stable")
        q.samples_reordered += int(np.count_nonzero(order != np.arange(order.size)))
        idx = idx[order]
    return idx


def _drop_duplicates(idx: np.ndarray, t: np.ndarray, values: list[np.ndarray], q: DataQuality) -> np.ndarray:
    """Remove rows equal in time and every value to the row before (duplicated blocks)."""
    if idx.size < 2:
        return idx
    same = np.diff(t[idx]) == 0
    if not same.any():
        return idx
    for v in values:
        if v.dtype.kind in "fiub":
            same &= v[idx][1:] == v[idx][:-1]
    q.duplicate_samples += int(np.count_nonzero(same))
    return idx[np.r_[True, ~same]]


def sanitize_log(log: FlightLog, quality: DataQuality | None = None, jump_s: float = JUMP_S) -> FlightLog:
    """Clean the time axis of every stream of ``log`` and attach the :class:`DataQuality` (every reader's last
    step; the thrust helper's PX4 CSV reader calls it too).

    Streams are the signals sharing one time array, given in file order. Non-finite and isolated corrupt time
    stamps are dropped; the log is split at forward time jumps > ``jump_s`` and only the part with the most
    samples is kept (a +1e6 s jump never reaches a resampling grid); backward steps within the gap threshold
    are put in order, larger ones (resets) dropped; duplicated rows dropped; non-finite values are removed
    from canonical signals; time is re-zeroed at the start of the kept part. Every loss is counted.
    """
    q = quality or DataQuality(log.source)
    groups = _time_groups(log.signals)
    finite = [np.asarray(t, dtype=float) for t, _ in groups]
    finite = [t[np.isfinite(t)] for t in finite]
    lo, hi = _main_segment(finite, q, jump_s)
    out: dict[str, Signal] = {}
    kept_times = []
    for t, names in groups:
        t = np.asarray(t, dtype=float)
        idx = _clean_group(t, lo, hi, q)
        vals = [np.asarray(log.signals[n].values) for n in names]
        idx = _drop_duplicates(idx, t, vals, q)
        ts = t[idx] - lo
        kept_times.append(ts)
        for n, v in zip(names, vals, strict=True):
            s = log.signals[n]
            out[n] = Signal(n, ts, v[idx], s.unit, s.description)
    _canonical_checks(out, q)
    _gaps(kept_times, q)
    log.signals = out
    log.quality = q
    return log


def _canonical_checks(signals: dict[str, Signal], q: DataQuality) -> None:
    """Drop non-finite values of canonical signals; count clipped sensor samples (and ArduPilot VIBE.Clip)."""
    for n, s in list(signals.items()):
        if "." in n or s.values.dtype.kind not in "fiub":
            continue
        q.canonical_samples += s.values.size
        fin = np.isfinite(s.values)
        if not fin.all():
            q.non_finite_samples += int(np.count_nonzero(~fin))
            signals[n] = Signal(n, s.t_s[fin], s.values[fin], s.unit, s.description)
        for prefix, limit in CLIP_LIMITS.items():
            if n.startswith(prefix):
                q.clipped_samples += int(np.count_nonzero(np.abs(signals[n].values) >= limit))
    for key in ("VIBE.Clip0", "VIBE.Clip1", "VIBE.Clip2", "VIBE.Clip"):  # old: one column per IMU; new: one
        clip = signals.get(key)
        if clip is not None and clip.values.size and np.isfinite(clip.values).all():
            q.clipped_samples += int(max(0.0, float(np.max(clip.values))))  # the IMU's own running count


def _gaps(kept_times: list[np.ndarray], q: DataQuality) -> None:
    """Pauses without any sample inside the kept part, and the time kept (its span minus the gaps)."""
    all_t = np.unique(np.concatenate(kept_times)) if kept_times else np.empty(0)
    if all_t.size < 2:
        q.time_kept_s = 0.0
        return
    thr = _gap_threshold(all_t)
    d = np.diff(all_t)
    big = np.flatnonzero(d > thr)
    q.gap_count = int(big.size)
    q.gap_total_s = float(np.sum(d[big]))
    q.gaps = [(float(all_t[i]), float(d[i])) for i in big[:_MAX_LISTED]]
    q.time_kept_s = float(all_t[-1] - all_t[0]) - q.gap_total_s

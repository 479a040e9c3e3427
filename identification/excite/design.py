"""Experiment design: identification manoeuvres planned from the vehicle model's own modes.

:func:`plan_excitation` trims the fixed-wing model, linearises it (:mod:`fmu_models.fixed_wing.linear`), takes
the roll-subsidence, Dutch-roll and short-period frequencies, and plans blocks of

- **3-2-1-1** (Koehler 1977; Plaetschke & Schulz 1979; Mulder et al.): pulses of 3, 2, 1, 1 time units Δt;
- **doublets**: +1, -1 for Δt each;
- **multisines** (Morelli 2003): every surface at once, each a sum of harmonics of ``1/T`` that no other
  surface uses (mutually orthogonal over ``T``), with Schroeder (1970) phases for a low peak factor, shifted so
  each signal starts and ends at zero.

Pulse widths put the peak of each input's energy spectrum on the mode it is meant to excite: the peak of the
unit pulse train's spectrum ``|U(jω)|`` is found numerically once (``ω* Δt`` = 2.33 for a doublet, the figure
Jategaonkar 2015 §2.5 quotes as 2.3/ωn), and ``Δt = ω* Δt / ω_mode``. Aileron: the roll-subsidence corner
``1/τ_roll`` (where roll damping and aileron power are both visible in the roll rate), capped by the highest
frequency the servos and log rate support; rudder: the Dutch-roll ``ωn``; elevator: the short-period ``ωn``.
Multisine bands run from ``band_low`` to ``band_high`` times the same frequencies.

Amplitudes: the largest deflection that keeps the open-loop linear response within ``attitude_fraction`` of
the roll and pitch limits, and the surface within its range less the trim deflection.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import expm

from fmu_models.config import bounded, range_problems
from fmu_models.fixed_wing.linear import INPUTS, LinearModel, Modes, linearise, modes
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fixed_wing.trim import Trim, trim

SURFACES = ("aileron", "elevator", "rudder")
INPUT_KINDS = ("3211", "doublet", "multisine")
#: pulse levels of one time unit each
PULSES = {"3211": (1, 1, 1, -1, -1, 1, -1), "doublet": (1, -1)}
INPUT_INDEX = {**{s: INPUTS.index(f"{s}_rad") for s in SURFACES}, "throttle": INPUTS.index("throttle")}
ROLL, PITCH = 3, 4  #: reduced-state indices of roll and pitch angle (fmu_models.fixed_wing.linear.STATES)


class ExciteError(ValueError):
    """Options out of range, or a vehicle that cannot be trimmed or has no usable modes."""


@dataclass(frozen=True)
class ExciteOptions:
    """What to plan; times in seconds, angles in degrees."""

    airspeed_m_s: float = bounded(25.0, 5.0, 100.0, "m/s")
    inputs: Sequence[str] = INPUT_KINDS
    surfaces: Sequence[str] = SURFACES
    roll_limit_deg: float = bounded(45.0, 5.0, 80.0, "deg")
    pitch_limit_deg: float = bounded(20.0, 2.0, 45.0, "deg")
    attitude_fraction: float = bounded(0.5, 0.05, 1.0)
    surface_limit_deg: float = bounded(20.0, 1.0, 45.0, "deg")
    surface_margin: float = bounded(0.8, 0.1, 1.0)
    rate_hz: float = bounded(50.0, 5.0, 400.0, "Hz")
    min_pulse_s: float = bounded(0.1, 0.02, 5.0, "s")
    settle_s: float = bounded(2.0, 0.0, 30.0, "s")
    tail_s: float = bounded(3.0, 0.0, 30.0, "s")
    recovery_s: float = bounded(10.0, 1.0, 300.0, "s")
    multisine_period_s: float = bounded(10.0, 2.0, 60.0, "s")
    multisine_periods: int = bounded(1, 1, 6)
    band_low: float = bounded(0.3, 0.01, 1.0)
    band_high: float = bounded(2.5, 1.0, 20.0)
    max_frequency_hz: float = bounded(3.0, 0.1, 50.0, "Hz")
    #: throttle doublets flown at attitude hold (airspeed, drag and thrust), alternating sign; 0: none. Two,
    #: so that ``identify aero`` can hold one out and score airspeed on it
    throttle_blocks: int = bounded(2, 0, 4)
    throttle_amplitude: float = bounded(0.2, 0.02, 0.5)  #: throttle doublet amplitude, fraction of full throttle
    #: throttle doublet time unit; 0: the doublet's spectrum centre on the phugoid (about 4 s on the Aerosonde,
    #: where the phugoid's pitch response caps the amplitude at 0.13 and C_D_p ~ C_T0 stay at |r| 0.98 on the
    #: SITL plane; 2 s allows 0.2 and brings it to 0.88: docs/excitation.md)
    throttle_pulse_s: float = bounded(2.0, 0.0, 20.0, "s")

    def problems(self) -> list[str]:
        out = range_problems(self)
        out += [f"inputs: {k!r} unknown; allowed {', '.join(INPUT_KINDS)}" for k in self.inputs if k not in INPUT_KINDS]
        out += [f"surfaces: {s!r} unknown; allowed {', '.join(SURFACES)}" for s in self.surfaces if s not in SURFACES]
        if not self.inputs or not self.surfaces:
            out.append("inputs and surfaces must each name at least one")
        if "multisine" in self.inputs and self.band_low * self.multisine_period_s > 0 and \
                self.multisine_period_s * self.rate_hz > 200_000:
            out.append("multisine_period_s * rate_hz above 200000 samples")
        return out


@dataclass(frozen=True)
class Signal:
    """One surface's deflection about trim [rad] from the excitation start: piecewise-constant ``steps``
    (``(t_end_s, level_rad)``, level 0 after the last) or a sum of cosines ``sines`` (``(ω rad/s, φ rad,
    a rad)``) over ``duration_s``."""

    steps: tuple[tuple[float, float], ...] = ()
    sines: tuple[tuple[float, float, float], ...] = ()
    duration_s: float = 0.0

    def __call__(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        out = np.zeros_like(t)
        if self.sines:
            inside = (t >= 0) & (t < self.duration_s)
            for w, ph, a in self.sines:
                out += np.where(inside, a * np.cos(w * t + ph), 0.0)
            return out
        t_prev = 0.0
        for t_end, level in self.steps:
            out[(t >= t_prev) & (t < t_end)] = level
            t_prev = t_end
        return out

    def peak_rad(self) -> float:
        if self.steps:
            return max(abs(v) for _, v in self.steps)
        t = np.arange(0.0, self.duration_s, self.duration_s / 4000.0)
        return float(np.max(np.abs(self(t)))) if self.sines else 0.0


@dataclass(frozen=True)
class Block:
    """One manoeuvre: hand-over at ``start_s``, input from ``excitation_start_s`` for ``input_s``, free
    response until ``end_s``, then recovery. Times from the start of the plan [s]."""

    index: int
    axis: str
    input: str
    signals: dict[str, Signal]
    start_s: float
    excitation_start_s: float
    end_s: float
    pulse_unit_s: float | None
    predicted_peak_deg: dict[str, float] = field(default_factory=dict)

    def deflection(self, t_s: np.ndarray) -> np.ndarray:
        """Surface deflections about trim (N x 4, model input order) at plan times ``t_s``."""
        out = np.zeros((len(t_s), len(INPUTS)))
        for s, sig in self.signals.items():
            out[:, INPUT_INDEX[s]] = sig(np.asarray(t_s) - self.excitation_start_s)
        return out


class PlanTiming:
    """The timing every excitation plan shares: its length and sample times, from its ``blocks`` and its
    ``options`` (``recovery_s`` after the last block, samples at ``rate_hz``)."""

    blocks: list[Any]
    options: Any

    @property
    def duration_s(self) -> float:
        return self.blocks[-1].end_s + self.options.recovery_s

    def times(self) -> np.ndarray:
        """The plan's sample times [s] at ``rate_hz``."""
        return np.arange(0.0, self.duration_s, 1.0 / self.options.rate_hz)


@dataclass
class ExcitationPlan(PlanTiming):
    """The planned experiment: trim, modes, blocks, and the options that produced them."""

    params: FixedWingParams
    options: ExciteOptions
    trim: Trim
    linear: LinearModel
    modes: Modes
    targets_rad_s: dict[str, float]
    blocks: list[Block]

    def deflection(self, t_s: np.ndarray) -> np.ndarray:
        """Planned deflection about trim (N x 4) at plan times (zero outside the blocks' input)."""
        out = np.zeros((len(t_s), len(INPUTS)))
        for b in self.blocks:
            out += b.deflection(t_s)
        return out

    def active_block(self, t_s: float) -> Block | None:
        """The block whose hand-over..end window holds ``t_s`` (None in recovery)."""
        return next((b for b in self.blocks if b.start_s <= t_s < b.end_s), None)

    def summary(self) -> str:
        m = self.modes
        lines = [f"trim at {self.linear.va_m_s:.1f} m/s: alpha {math.degrees(self.trim.alpha_rad):.2f} deg, "
                 f"elevator {math.degrees(self.trim.elevator_rad):.2f} deg, throttle {self.trim.throttle:.2f}"]
        for md in m.all():
            tc = f", time constant {md.time_constant_s:.3g} s" if md.time_constant_s else ""
            lines.append(f"  {md.name:16s} wn {md.wn_rad_s:7.3f} rad/s  zeta {md.zeta:+.3f}{tc}"
                         f"{'' if md.stable else '  (unstable)'}")
        lines.append("target frequencies: " + ", ".join(f"{k} {v:.3g} rad/s" for k, v in self.targets_rad_s.items()))
        for b in self.blocks:
            amp = ", ".join(f"{s} {sig.peak_rad():.2f} of full" if s == "throttle" else
                            f"{s} {math.degrees(sig.peak_rad()):.1f} deg" for s, sig in b.signals.items())
            dt = f", dt {b.pulse_unit_s:.2f} s" if b.pulse_unit_s else ""
            peak = ", ".join(f"{k} {v:.1f}" for k, v in b.predicted_peak_deg.items())
            lines.append(f"  block {b.index}: {b.input:9s} {b.axis:8s} {b.start_s:7.1f}..{b.end_s:7.1f} s "
                         f"({amp}{dt}; linear peak deg: {peak})")
        lines.append(f"total {self.duration_s:.1f} s")
        return "\n".join(lines)


# ------------------------------------------------------------------ design rules
def spectrum_centre(levels: Sequence[int], n_grid: int = 20000) -> float:
    """``ω_c Δt``: geometric centre of the half-power band of the energy spectrum of unit pulses ``levels``
    (each one time unit Δt): 2.04 for a doublet (its peak, 2.33, is Jategaonkar's 2.3/ωn), 0.86 for a 3-2-1-1
    (half-power band 0.28..2.65 / Δt)."""
    x = np.linspace(1e-3, 3 * math.pi, n_grid)  # ω Δt
    k = np.arange(len(levels))
    # U(jω)/Δt = Σ_k level_k e^{-jωkΔt} (1 - e^{-jωΔt}) / (jωΔt)
    u = np.abs((np.exp(-1j * np.outer(x, k)) @ np.asarray(levels, float)) * (1 - np.exp(-1j * x)) / (1j * x)) ** 2
    band = np.flatnonzero(u >= 0.5 * u.max())
    return float(math.sqrt(x[band[0]] * x[band[-1]]))


def target_frequencies(m: Modes, opt: ExciteOptions) -> dict[str, float]:
    """The frequency [rad/s] each surface's input is centred on (see the module docstring)."""
    w_max = max_frequency_rad_s(opt)
    roll = m.roll_subsidence.wn_rad_s
    return {"aileron": min(roll, w_max), "elevator": min(m.short_period.wn_rad_s, w_max),
            "rudder": min(m.dutch_roll.wn_rad_s, w_max)}


def max_frequency_rad_s(opt: ExciteOptions) -> float:
    """Highest input frequency planned: ``max_frequency_hz``, and at least 10 samples per period."""
    return 2 * math.pi * min(opt.max_frequency_hz, opt.rate_hz / 10.0)


def pulse_unit(kind: str, w_rad_s: float, opt: ExciteOptions) -> float:
    """Δt [s] putting the spectrum peak of ``kind`` on ``w_rad_s``, rounded to whole samples, >= min_pulse_s."""
    dt = spectrum_centre(PULSES[kind]) / w_rad_s
    n = max(round(dt * opt.rate_hz), math.ceil(opt.min_pulse_s * opt.rate_hz - 1e-9), 1)
    return n / opt.rate_hz


def schroeder_phases(n: int, power: Sequence[float] | None = None) -> np.ndarray:
    """Schroeder (1970) phases ``φ_k = -2π Σ_{i<k} (k - i) p_i`` for ``n`` harmonics of power fractions ``p``."""
    p = np.full(n, 1.0 / n) if power is None else np.asarray(power, float) / np.sum(power)
    return np.array([-2 * math.pi * sum((k - i) * p[i] for i in range(k)) for k in range(n)])


def assign_harmonics(bands: dict[str, tuple[float, float]], period_s: float) -> dict[str, list[int]]:
    """Harmonic indices ``k`` (frequency ``k / period_s`` Hz) for each surface: each inside its band, none
    shared, given in turn to the eligible surface holding the fewest so far (Morelli 2003's interleaving)."""
    f0 = 1.0 / period_s
    lo = min(b[0] for b in bands.values())
    hi = max(b[1] for b in bands.values())
    out: dict[str, list[int]] = {s: [] for s in bands}
    for k in range(max(1, math.ceil(lo / (2 * math.pi * f0))), math.floor(hi / (2 * math.pi * f0)) + 1):
        w = 2 * math.pi * f0 * k
        eligible = [s for s, (a, b) in bands.items() if a <= w <= b]
        if eligible:
            out[min(eligible, key=lambda s: len(out[s]))].append(k)
    return out


def multisine(harmonics: list[int], period_s: float, duration_s: float) -> Signal:
    """Unit-peak Schroeder multisine on ``harmonics`` of ``1/period_s``, time-shifted to start at zero."""
    w = 2 * math.pi * np.asarray(harmonics, float) / period_s
    ph = schroeder_phases(len(harmonics))
    t = np.linspace(0.0, period_s, 4000, endpoint=False)
    u = np.cos(np.outer(t, w) + ph).sum(axis=1)
    i = int(np.argmax((u[:-1] <= 0) & (u[1:] > 0)))  # first upward zero crossing: start there
    t0 = t[i] - u[i] * (t[i + 1] - t[i]) / (u[i + 1] - u[i])
    ph = np.angle(np.exp(1j * (ph + w * t0)))  # wrapped to (-pi, pi]
    peak = float(np.max(np.abs(np.cos(np.outer(t, w) + ph).sum(axis=1))))
    return Signal(sines=tuple((float(a), float(b), 1.0 / peak) for a, b in zip(w, ph, strict=True)),
                  duration_s=duration_s)


def steps(kind: str, dt_s: float, sign: float = 1.0) -> Signal:
    """Unit 3-2-1-1 or doublet with time unit ``dt_s``, merged into steps of constant level."""
    out: list[tuple[float, float]] = []
    for k, level in enumerate(PULSES[kind]):
        if out and out[-1][1] == sign * level:
            out[-1] = ((k + 1) * dt_s, sign * level)
        else:
            out.append(((k + 1) * dt_s, sign * level))
    return Signal(steps=tuple(out), duration_s=len(PULSES[kind]) * dt_s)


# ------------------------------------------------------------------ amplitudes
def linear_peaks(lin: LinearModel, signals: dict[str, Signal], length_s: float, rate_hz: float) -> np.ndarray:
    """Peak |roll|, |pitch| [rad] of the open-loop linear response to ``signals`` over ``length_s``."""
    dt = 1.0 / rate_hz
    n = lin.A.shape[0]
    big = expm(np.block([[lin.A, lin.B], [np.zeros((lin.B.shape[1], n + lin.B.shape[1]))]]) * dt)
    Ad, Bd = big[:n, :n], big[:n, n:]
    t = np.arange(0.0, length_s, dt)
    u = np.zeros((len(t), len(INPUTS)))
    for s, sig in signals.items():
        u[:, INPUT_INDEX[s]] = sig(t)
    x = np.zeros(n)
    peak = np.zeros(2)
    for k in range(len(t)):
        x = Ad @ x + Bd @ u[k]
        peak = np.maximum(peak, np.abs(x[[ROLL, PITCH]]))
    return peak


def scale_signals(signals: dict[str, Signal], amp: dict[str, float]) -> dict[str, Signal]:
    def one(sig: Signal, a: float) -> Signal:
        return dataclasses.replace(sig, steps=tuple((t, v * a) for t, v in sig.steps),
                                   sines=tuple((w, p, c * a) for w, p, c in sig.sines))
    return {s: one(sig, amp[s]) for s, sig in signals.items()}


def amplitudes(plan_lin: LinearModel, tr: Trim, signals: dict[str, Signal], length_s: float,
               opt: ExciteOptions) -> tuple[dict[str, float], np.ndarray]:
    """Common scale [rad] per surface within surface and attitude limits; and the predicted peaks [rad]."""
    trim_rad = {"aileron": tr.aileron_rad, "elevator": tr.elevator_rad, "rudder": tr.rudder_rad}
    cap = {s: opt.surface_margin * (math.radians(opt.surface_limit_deg) - abs(trim_rad[s])) for s in signals
           if s != "throttle"}
    if "throttle" in signals:  # a fraction of full throttle, within [0, 1] about the trim throttle
        cap["throttle"] = min(opt.throttle_amplitude, opt.surface_margin * min(tr.throttle, 1.0 - tr.throttle))
        if cap["throttle"] <= 0:
            raise ExciteError(f"at {opt.airspeed_m_s:g} m/s the trim throttle {tr.throttle:.2f} leaves no room for a "
                              "throttle doublet; fly at another airspeed or set throttle_blocks = 0")
    bad = [f"{s} {math.degrees(trim_rad[s]):.1f} deg" for s in signals if s != "throttle" and cap[s] <= 0]
    if bad:
        raise ExciteError(f"at {opt.airspeed_m_s:g} m/s the trim deflection ({', '.join(bad)}) leaves no room within "
                          f"surface_limit_deg = {opt.surface_limit_deg:g}; fly faster or raise the surface limit")
    unit = {s: cap[s] / max(cap.values()) for s in signals}  # keep each surface's share of its own range
    peak = linear_peaks(plan_lin, scale_signals(signals, unit), length_s, opt.rate_hz)
    lim = np.radians([opt.roll_limit_deg, opt.pitch_limit_deg]) * opt.attitude_fraction
    scale = min(max(cap.values()), *(lim[i] / peak[i] for i in range(2) if peak[i] > 1e-12))
    return {s: unit[s] * scale for s in signals}, peak * scale


# ------------------------------------------------------------------ the plan
def _block_signals(kind: str, surfaces: Sequence[str], targets: dict[str, float], opt: ExciteOptions,
                   ) -> tuple[dict[str, Signal], float | None]:
    if kind != "multisine":
        (s,) = surfaces
        dt = pulse_unit(kind, targets[s], opt)
        return {s: steps(kind, dt)}, dt
    w_max = max_frequency_rad_s(opt)
    bands = {s: (opt.band_low * targets[s], min(opt.band_high * targets[s], w_max)) for s in surfaces}
    harm = assign_harmonics(bands, opt.multisine_period_s)
    empty = [s for s, k in harm.items() if not k]
    if empty:
        raise ExciteError(f"multisine: no harmonic of 1/{opt.multisine_period_s:g} s falls in the band of "
                          f"{', '.join(empty)}; lengthen multisine_period_s or widen band_low/band_high")
    length = opt.multisine_period_s * opt.multisine_periods
    return {s: multisine(harm[s], opt.multisine_period_s, length) for s in surfaces}, None


def plan_excitation(params: FixedWingParams | None = None, opt: ExciteOptions | None = None) -> ExcitationPlan:
    """Plan identification manoeuvres for the fixed wing ``params`` (default: Aerosonde)."""
    opt = opt or ExciteOptions()
    params = params or FixedWingParams()
    bad = opt.problems()
    if bad:
        raise ExciteError("; ".join(bad))
    model = FixedWingModel(params)
    p = np.array(model.params.starts())
    try:
        tr = trim(model, p, opt.airspeed_m_s)
    except RuntimeError as err:
        raise ExciteError(f"cannot trim at {opt.airspeed_m_s} m/s: {err}") from None
    lin = linearise(model, p, tr)
    md = modes(lin)
    targets = target_frequencies(md, opt)
    specs = [(k, [s]) for k in opt.inputs if k != "multisine" for s in opt.surfaces]
    if "multisine" in opt.inputs:
        specs.append(("multisine", list(opt.surfaces)))
    blocks, t = [], 0.0
    for i, (kind, surfaces) in enumerate(specs, start=1):
        sig, dt = _block_signals(kind, surfaces, targets, opt)
        input_s = max(s.duration_s for s in sig.values())
        amp, peak = amplitudes(lin, tr, sig, input_s + opt.tail_s, opt)
        t_exc = t + opt.settle_s
        end = t_exc + input_s + opt.tail_s
        axis = surfaces[0] if len(surfaces) == 1 else "multi"
        blocks.append(Block(i, axis, kind, scale_signals(sig, amp), t, t_exc, end, dt,
                            {"roll": math.degrees(peak[0]), "pitch": math.degrees(peak[1])}))
        t = end + opt.recovery_s
    for k in range(opt.throttle_blocks):
        dt = throttle_pulse(md, opt)
        sig = {"throttle": steps("doublet", dt, sign=1.0 if k % 2 == 0 else -1.0)}
        input_s = sig["throttle"].duration_s
        amp, peak = amplitudes(lin, tr, sig, input_s + opt.tail_s, opt)
        t_exc = t + opt.settle_s
        end = t_exc + input_s + opt.tail_s
        blocks.append(Block(len(blocks) + 1, "throttle", "doublet", scale_signals(sig, amp), t, t_exc, end, dt,
                            {"roll": math.degrees(peak[0]), "pitch": math.degrees(peak[1])}))
        t = end + opt.recovery_s
    return ExcitationPlan(params, opt, tr, lin, md, targets, blocks)


def throttle_pulse(m: Modes, opt: ExciteOptions) -> float:
    """Throttle doublet time unit [s]: ``throttle_pulse_s``, or with 0 the doublet's spectrum centre on the
    phugoid (the speed mode the throttle moves), at least 2 s; rounded to whole samples."""
    dt = opt.throttle_pulse_s or max(2.0, spectrum_centre(PULSES["doublet"]) / m.phugoid.wn_rad_s)
    return max(round(dt * opt.rate_hz), 1) / opt.rate_hz


def as_dict(plan: ExcitationPlan) -> dict[str, Any]:
    """Modes, targets and blocks as plain data (for the plan JSON)."""
    return {"airspeed_m_s": plan.linear.va_m_s,
            "trim": {"alpha_rad": plan.trim.alpha_rad, "elevator_rad": plan.trim.elevator_rad,
                     "aileron_rad": plan.trim.aileron_rad, "rudder_rad": plan.trim.rudder_rad,
                     "throttle": plan.trim.throttle},
            "modes": [m.as_dict() for m in plan.modes.all()], "target_frequencies_rad_s": plan.targets_rad_s,
            "options": {k: (list(v) if isinstance(v, tuple | list) else v)
                        for k, v in dataclasses.asdict(plan.options).items()}}

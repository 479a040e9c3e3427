"""PNG figures of an excitation plan: the planned inputs, the closed-loop check flight, the input spectra."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from identification.common.plots import figure, save
from identification.excite.check import Flight
from identification.excite.design import SURFACES, ExcitationPlan


def _shade(ax, plan: ExcitationPlan) -> None:  # type: ignore[no-untyped-def]
    for b in plan.blocks:
        ax.axvspan(b.start_s, b.end_s, color="0.92", lw=0)
        ax.text(b.excitation_start_s, 1.0, f"{b.index}", transform=ax.get_xaxis_transform(), fontsize=7, va="top")


def plot_inputs(plan: ExcitationPlan, path: Path, title: str) -> Path:
    """Planned surface deflections about trim [deg] over the plan (blocks shaded)."""
    t = plan.times()
    du = np.degrees(plan.deflection(t))
    fig, axes = figure(3, 1, sharex=True, figsize=(7.5, 5.0))
    for k, (ax, s) in enumerate(zip(axes, SURFACES, strict=True)):
        _shade(ax, plan)
        ax.plot(t, du[:, k], lw=0.8)
        ax.set_ylabel(f"{s} [deg]")
    axes[-1].set_xlabel("time from the start of the plan [s]")
    axes[0].set_title(title, fontsize=9)
    return save(fig, path)


def plot_flight(plan: ExcitationPlan, flight: Flight, path: Path, title: str) -> Path:
    """Closed-loop check flight: roll, pitch and body rates."""
    fig, axes = figure(3, 1, sharex=True, figsize=(7.5, 5.0))
    y, names, t = flight.y, flight.output_names, flight.t_s
    for ax, group, unit in ((axes[0], ("roll_rad", "pitch_rad"), "deg"),
                            (axes[1], ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s"), "deg/s"),
                            (axes[2], ("beta_rad", "alpha_rad"), "deg")):
        _shade(ax, plan)
        for n in group:
            ax.plot(t, np.degrees(y[:, names.index(n)]), lw=0.8, label=n)
        ax.set_ylabel(unit)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(title, fontsize=9)
    return save(fig, path)


def plot_spectra(plan: ExcitationPlan, path: Path, title: str) -> Path:
    """Energy spectra of each block's inputs, with the model's mode frequencies marked."""
    fig, ax = figure(figsize=(7.5, 4.0))
    dt = 1.0 / plan.options.rate_hz
    for b in plan.blocks:
        t = np.arange(b.excitation_start_s - 1.0, b.end_s + 20.0, dt)
        for s in b.signals:
            u = plan.deflection(t)[:, SURFACES.index(s)]
            f = np.fft.rfftfreq(len(t), dt)
            e = np.abs(np.fft.rfft(u) * dt) ** 2
            ax.loglog(2 * math.pi * f[1:], e[1:] / e[1:].max(), lw=0.7, label=f"{b.index} {b.input} {s}")
    for m in (plan.modes.roll_subsidence, plan.modes.dutch_roll, plan.modes.short_period):
        ax.axvline(m.wn_rad_s, color="k", ls=":", lw=0.8)
        ax.text(m.wn_rad_s, 1.5, m.name, rotation=90, fontsize=7, va="bottom")
    ax.set_ylim(1e-4, 3)
    ax.set_xlim(0.3, 100)
    ax.set_xlabel("frequency [rad/s]")
    ax.set_ylabel("normalised energy")
    ax.legend(fontsize=6, ncol=2)
    ax.set_title(title, fontsize=9)
    return save(fig, path)

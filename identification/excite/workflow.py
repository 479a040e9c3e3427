"""``uavfmu excite`` as a library call: plan, optionally check in closed loop, and render the files.

:func:`excite` returns an :class:`ExciteResult` (plan, checks, file contents); :func:`write_files` writes them
beside a prefix: ``PREFIX.lua`` (ArduPilot script), ``PREFIX.rc_override.json`` / ``.csv`` (ground-station
RC-override steps), ``PREFIX.timeline.json`` (what ``identify aero`` reads), ``PREFIX.plan.json`` (modes,
design, checks).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from fmu_models.fixed_wing.params import FixedWingParams
from identification.excite.check import Flight, Gains, SetCheck, check_plan
from identification.excite.design import ExcitationPlan, ExciteError, ExciteOptions, as_dict, plan_excitation
from identification.excite.dry_run import DryRun, LuaScriptError, dry_run
from identification.excite.writers import OutputOptions, lua_script, rc_override, rc_override_csv, timeline_dict


class Rendered(Protocol):
    """A plan's rendered files, suffix -> text (``ExciteResult`` and the quadrotor's ``QuadExciteResult``)."""

    files: dict[str, str]


@dataclass
class ExciteResult:
    """The plan, its closed-loop checks (empty when not asked for) and the rendered files."""

    plan: ExcitationPlan
    checks: dict[str, SetCheck] = field(default_factory=dict)
    flight_peaks_deg: dict[str, float] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    flight: Flight | None = None
    warnings: list[str] = field(default_factory=list)
    dry_run: DryRun | None = None  #: the Lua script flown on the stand-in bindings (with ``check``)

    @property
    def well_conditioned(self) -> bool | None:
        """True/False after a check, None without one."""
        return all(c.ok for c in self.checks.values()) if self.checks else None

    @property
    def check_passed(self) -> bool | None:
        """After a check: every set well conditioned and the dry run of the script passed; None without one."""
        if not self.checks:
            return None
        return bool(self.well_conditioned) and (self.dry_run is None or self.dry_run.ok)

    def summary(self) -> str:
        lines = [self.plan.summary()]
        if self.checks:
            lines.append(f"closed-loop check (PD attitude hold + plan): peak roll {self.flight_peaks_deg['roll']:.1f}"
                         f" deg, peak pitch change {self.flight_peaks_deg['pitch']:.1f} deg")
            lines += [f"  {k}: {c.line()}" for k, c in self.checks.items()]
        if self.dry_run is not None:
            lines.append("dry run of the Lua script (Lua 5.3, stand-in ArduPilot bindings, ticks late by 0..8 ms):")
            lines += [f"  {x}" for x in self.dry_run.lines]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def plan_dict(self) -> dict[str, Any]:
        out = as_dict(self.plan)
        out["checks"] = {k: {"names": c.names, "condition_number": c.condition_number,
                             "condition_number_normalised_information": c.condition_number_info,
                             "max_abs_r": c.max_abs_r, "max_pair": list(c.max_pair), "blocks": c.blocks,
                             "well_conditioned": c.ok} for k, c in self.checks.items()}
        return out


def excite(params: FixedWingParams | None = None, opt: ExciteOptions | None = None,
           out: OutputOptions | None = None, check: bool = False, gains: Gains | None = None,
           command: str = "uavfmu excite") -> ExciteResult:
    """Plan the manoeuvres for ``params`` (default Aerosonde), check them if asked, render the files."""
    out = out or OutputOptions()
    bad = out.problems()
    if bad:
        raise ExciteError("; ".join(bad))
    plan = plan_excitation(params, opt)
    result = ExciteResult(plan)
    if check:
        flight, result.checks = check_plan(plan, gains or Gains())
        result.flight = flight
        result.flight_peaks_deg = {"roll": flight.max_roll_deg, "pitch": flight.max_pitch_dev_deg}
    rc = rc_override(plan, out)
    result.warnings = list(rc["warnings"])
    script = lua_script(plan, out, command)
    if check and result.flight is not None:
        names = result.flight.output_names
        attitude = (result.flight.t_s, result.flight.y[:, names.index("roll_rad")],
                    result.flight.y[:, names.index("pitch_rad")])
        try:
            result.dry_run = dry_run(plan, script, out, attitude)
        except LuaScriptError as err:
            result.dry_run = DryRun(False, [f"FAILED: {err}"])
    result.files = {
        ".lua": script,
        ".timeline.json": json.dumps(timeline_dict(plan, out), indent=1),
        ".rc_override.json": json.dumps(rc, indent=None, separators=(",", ":")),
        ".rc_override.csv": rc_override_csv(rc),
        ".plan.json": json.dumps(result.plan_dict(), indent=1),
    }
    return result


def write_files(result: Rendered, prefix: Path) -> list[Path]:
    """Write every rendered file of a plan (fixed wing or quadrotor) as ``prefix`` + its suffix; returns the
    paths."""
    prefix.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for suffix, text in result.files.items():
        path = prefix.parent / (prefix.name + suffix)
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths


def write_plots(result: ExciteResult, folder: Path, command: str = "uavfmu excite") -> list[Path]:
    """PNG figures of the plan (inputs, spectra) and, after a check, of the closed-loop flight."""
    from identification.excite.plots import plot_flight, plot_inputs, plot_spectra

    title = f"{command}"
    out = [plot_inputs(result.plan, folder / "excite_inputs.png", title),
           plot_spectra(result.plan, folder / "excite_spectra.png", title)]
    if result.flight is not None:
        out.append(plot_flight(result.plan, result.flight, folder / "excite_check_flight.png", title))
    return out

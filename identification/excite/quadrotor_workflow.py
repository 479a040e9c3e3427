"""``uavfmu excite --vehicle quadrotor`` as a library call: plan, optionally check in closed loop, render the files.

:func:`excite_quadrotor` returns a :class:`QuadExciteResult` (plan, checks, file contents); :func:`write_files`
writes them beside a prefix. The files fit the autopilot whose loops timed the plan: PX4 gets
``PREFIX.manual_control.json`` / ``.csv`` (MAVLink MANUAL_CONTROL steps, ALTCTL); ArduCopter gets
``PREFIX.rc_override.json`` / ``.csv`` (RC_CHANNELS_OVERRIDE steps, AltHold) and ``PREFIX.sid_<axis>.parm`` (SystemId
chirps). Both get ``PREFIX.plan.json`` (hover, loops, natural frequencies, blocks, options, checks).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from fmu_models.quadrotor.params import QuadrotorParams
from identification.excite.design import ExciteError
from identification.excite.quadrotor import QuadExcitationPlan, QuadExciteOptions, plan_quadrotor_excitation
from identification.excite.quadrotor_check import QuadFlight, QuadSetCheck, check_quadrotor_plan
from identification.excite.quadrotor_writers import (
    QuadOutputOptions,
    manual_control,
    manual_control_csv,
    rc_override,
    rc_override_csv,
    sid_parameters,
    sid_values,
)
from identification.excite.workflow import write_files


@dataclass
class QuadExciteResult:
    """The plan, its closed-loop checks (empty when not asked for), the rendered files and their warnings."""

    plan: QuadExcitationPlan
    checks: dict[str, QuadSetCheck] = field(default_factory=dict)
    flight: QuadFlight | None = None
    files: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def well_conditioned(self) -> bool | None:
        """True/False after a check, None without one."""
        return all(c.ok for c in self.checks.values()) if self.checks else None

    def summary(self) -> str:
        lines = [self.plan.summary()]
        if self.flight is not None:
            f = self.flight
            lines.append(f"closed-loop check ({self.plan.loops.name} loops + plan): peak tilt {f.max_tilt_deg:.1f} deg,"
                         f" peak yaw rate {f.max_yaw_rate_deg_s:.0f} deg/s, height range {f.height_range_m:.1f} m")
            lines += [f"  note: {n}" for n in f.notes]
            lines += [f"  {k}: {c.line()}" for k, c in self.checks.items()]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def plan_dict(self, out: QuadOutputOptions) -> dict[str, Any]:
        data = self.plan.as_dict()
        if self.plan.loops.name == "ardupilot":
            data["systemid"] = {a: sid_values(self.plan, a, out) for a in self.plan.options.axes}
        data["checks"] = {k: c.as_dict() for k, c in self.checks.items()}
        if self.flight is not None:
            data["check_flight"] = {"max_tilt_deg": self.flight.max_tilt_deg,
                                    "max_yaw_rate_deg_s": self.flight.max_yaw_rate_deg_s,
                                    "height_range_m": self.flight.height_range_m, "notes": self.flight.notes}
        return data


def excite_quadrotor(params: QuadrotorParams | None = None, opt: QuadExciteOptions | None = None,
                     out: QuadOutputOptions | None = None, check: bool = False,
                     command: str = "uavfmu excite --vehicle quadrotor", compile: bool = True) -> QuadExciteResult:
    """Plan the stick manoeuvres for ``params`` (default F450), check them if asked, render the files."""
    out = out or QuadOutputOptions()
    bad = out.problems()
    if bad:
        raise ExciteError("; ".join(bad))
    plan = plan_quadrotor_excitation(params, opt)
    result = QuadExciteResult(plan)
    if check:
        result.flight, result.checks = check_quadrotor_plan(plan, compile)
    if plan.loops.name == "px4":
        steps = manual_control(plan, out)
        result.files = {".manual_control.json": json.dumps(steps, separators=(",", ":")),
                        ".manual_control.csv": manual_control_csv(steps)}
    else:
        steps = rc_override(plan, out)
        result.files = {".rc_override.json": json.dumps(steps, separators=(",", ":")),
                        ".rc_override.csv": rc_override_csv(steps)}
        result.files.update({f".sid_{a}.parm": text for a, text in sid_parameters(plan, out, command).items()})
    result.warnings = list(steps["warnings"])
    if result.flight is not None and result.flight.max_tilt_deg > plan.options.roll_limit_deg:
        result.warnings.append(f"the check flight tilted {result.flight.max_tilt_deg:.0f} deg, beyond the "
                               f"{plan.options.roll_limit_deg:g} deg limit: the loops or the plan rate do not hold "
                               "this airframe (raise --rate, lower --max-stick)")
    result.files[".plan.json"] = json.dumps(result.plan_dict(out), indent=1)
    return result


__all__ = ["QuadExciteResult", "excite_quadrotor", "write_files"]

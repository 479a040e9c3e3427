"""``uavfmu excite --vehicle quadrotor``: plan stick 3-2-1-1s and doublets for a quadrotor from its rate dynamics.

``uavfmu excite --vehicle quadrotor --out flights/quad [--params quad.json] [--autopilot px4|ardupilot]
[--axes roll,pitch,yaw,throttle] [--inputs 3211,doublet,drag] [--check]`` finds the model's hover, its control
effectiveness, and the natural frequency of each stick axis under the autopilot's loops, prints them and the planned
blocks, and writes (PX4) ``quad.manual_control.json``/``.csv`` or (ArduCopter) ``quad.rc_override.json``/``.csv``
and one SystemId parameter file per axis ``quad.sid_<axis>.parm``, and ``quad.plan.json``. ``--check`` flies the
plan in closed loop on the model and prints the condition number, largest correlation and relative Cramér-Rao std
of the rotational set (inertia through the arm's effectiveness, motor time constant, yaw torque with Jz fixed) and
the drag set. The work is ``identification.excite.quadrotor_workflow``; exit status as ``uavfmu excite``.
"""

from __future__ import annotations

import argparse
import sys

from uavfmu.commands.common import EXCITE_EXIT_BAD_INPUT as EXIT_BAD_INPUT
from uavfmu.commands.common import EXCITE_EXIT_ILL_CONDITIONED as EXIT_ILL_CONDITIONED
from uavfmu.commands.common import EXCITE_EXIT_OK as EXIT_OK
from uavfmu.commands.common import comma_list, or_default


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The quadrotor's own options (the shared ones are ``uavfmu.commands.excite``'s)."""
    g = p.add_argument_group("quadrotor (--vehicle quadrotor)")
    g.add_argument("--autopilot", choices=("px4", "ardupilot"), default="px4",
                   help="loops that fly the sticks and files written: px4 (ALTCTL, MANUAL_CONTROL) or ardupilot "
                        "(AltHold, RC override, SystemId parameters)")
    g.add_argument("--axes", default="roll,pitch,yaw,throttle", help="stick axes to excite (all four)")
    g.add_argument("--tilt-limit", type=float, default=30.0, help="tilt limit [deg] (30); the plan peaks at half")
    g.add_argument("--yaw-rate-limit", type=float, default=90.0, help="yaw-rate limit [deg/s] (90); plan peaks at half")
    g.add_argument("--climb-limit", type=float, default=1.5, help="climb-rate limit [m/s] (1.5); plan peaks at half")
    g.add_argument("--max-stick", type=float, default=0.6, help="largest stick deflection, fraction of full (0.6)")
    g.add_argument("--max-hold", type=float, default=3.0, help="longest pulse unit of a drag doublet [s] (3)")
    g.add_argument("--speed-limit", type=float, default=3.0, help="speed a drag doublet may build [m/s] (3)")
    g.add_argument("--sid-injection", choices=("mixer", "rate"), default="mixer",
                   help="ArduCopter SystemId injection point: mixer (SID_AXIS 10-13) or rate set-point (7-9)")


def run(args: argparse.Namespace) -> int:
    """Plan, check, write, print; see the module docstring."""
    from fmu_models.common.errors import ParameterError
    from fmu_models.fmi.fmus import load_vehicle_params
    from identification.excite.quadrotor import QuadExciteOptions
    from identification.excite.quadrotor_workflow import excite_quadrotor, write_files
    from identification.excite.quadrotor_writers import QuadOutputOptions

    try:
        opt = QuadExciteOptions(autopilot=args.autopilot, inputs=comma_list(args.inputs or "3211,doublet,drag"),
                                axes=comma_list(args.axes), roll_limit_deg=args.tilt_limit,
                                yaw_rate_limit_deg_s=args.yaw_rate_limit, climb_limit_m_s=args.climb_limit,
                                max_stick=args.max_stick, max_hold_s=args.max_hold,
                                speed_limit_m_s=args.speed_limit, rate_hz=or_default(args.rate, 100.0),
                                settle_s=args.settle,
                                tail_s=args.tail, recovery_s=or_default(args.recovery, 6.0),
                                max_frequency_hz=or_default(args.max_frequency, 5.0))
        out = QuadOutputOptions(rc_rate_hz=or_default(args.rc_rate, 50.0), sid_injection=args.sid_injection)
        params = load_vehicle_params(args.params, "quadrotor") if args.params else None
        command = "uavfmu excite " + " ".join(sys.argv[2:])
        result = excite_quadrotor(params, opt, out, check=args.check, command=command)
    except (OSError, ValueError, ParameterError) as err:  # ExciteError, ConfigError, ...
        print(f"uavfmu excite: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    paths = write_files(result, args.out)
    print(result.summary())
    print("wrote " + ", ".join(str(p) for p in paths))
    return EXIT_ILL_CONDITIONED if result.well_conditioned is False else EXIT_OK

"""``uavfmu excite``: plan identification manoeuvres for a fixed wing from its own modes, or for a quadrotor
(``--vehicle quadrotor``, see ``uavfmu.commands.excite_quadrotor``) from its rate dynamics.

``uavfmu excite --out flights/exc [--params plane.json] [--airspeed 25] [--inputs 3211,doublet,multisine]
[--check]`` trims and linearises the model, prints its modes and the planned blocks, and writes
``exc.lua`` (ArduPilot script: started by an ``RCx_OPTION`` Scripting switch only when flying; attitude, airspeed
and height limits abort to the recovery mode; ``EXCT`` marks in the log for ``identify aero``),
``exc.rc_override.json``/``.csv`` (RC-override steps for a ground-station script, ArduPilot or PX4),
``exc.timeline.json`` (blocks for ``identify aero``) and ``exc.plan.json``. ``--check`` flies the plan in closed
loop on the model (PD attitude hold, plan on top) and prints the condition number and largest correlation
of the lateral and longitudinal derivative sets, and dry-runs the Lua script on stand-in ArduPilot bindings
(trigger refusals, marks, abort). The work is ``identification.excite.workflow``.

Exit status: 0 done, 2 bad input, 3 ``--check`` found a set not well conditioned or a failed dry run (files
still written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from uavfmu.commands.common import EXCITE_EXIT_BAD_INPUT as EXIT_BAD_INPUT
from uavfmu.commands.common import EXCITE_EXIT_ILL_CONDITIONED as EXIT_ILL_CONDITIONED
from uavfmu.commands.common import EXCITE_EXIT_OK as EXIT_OK
from uavfmu.commands.common import comma_list, or_default


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = __doc__.split("\n\n")[0]
    p.add_argument("--out", type=Path, required=True, help="output prefix: writes PREFIX.lua, .timeline.json, ...")
    p.add_argument("--vehicle", choices=("fixed_wing", "quadrotor"), default="fixed_wing",
                   help="vehicle to plan for (fixed_wing); quadrotor options below the fixed-wing ones")
    p.add_argument("--params", type=Path, help="parameter file of the vehicle (JSON; default: built-in Aerosonde, "
                                               "F450 for the quadrotor)")
    p.add_argument("--airspeed", type=float, default=25.0, help="trim airspeed [m/s] (25)")
    p.add_argument("--inputs", default=None, help="3211, doublet, multisine (all; quadrotor: 3211, doublet, drag)")
    p.add_argument("--surfaces", default="aileron,elevator,rudder", help="surfaces to excite (all three)")
    p.add_argument("--roll-limit", type=float, default=45.0, help="abort roll [deg] (45); plan peaks at half")
    p.add_argument("--pitch-limit", type=float, default=20.0, help="abort pitch change from trim [deg] (20)")
    p.add_argument("--surface-limit", type=float, default=20.0, help="surface range [deg] (20)")
    p.add_argument("--rate", type=float, default=None, help="plan sample rate [Hz] (50; quadrotor 100)")
    p.add_argument("--settle", type=float, default=2.0, help="trim hold before each input [s] (2)")
    p.add_argument("--tail", type=float, default=3.0, help="free response after each input [s] (3)")
    p.add_argument("--recovery", type=float, default=None, help="recovery between blocks [s] (10; quadrotor 6)")
    p.add_argument("--multisine-period", type=float, default=10.0, help="multisine period T [s] (10)")
    p.add_argument("--max-frequency", type=float, default=None,
                   help="highest planned frequency [Hz] (3; quadrotor 5)")
    p.add_argument("--throttle-blocks", type=int, default=2,
                   help="fixed wing: throttle doublets at attitude hold, alternating sign; 0: none (2)")
    p.add_argument("--throttle-amplitude", type=float, default=0.2,
                   help="fixed wing: throttle doublet amplitude, fraction (0.2)")
    p.add_argument("--throttle-pulse", type=float, default=2.0,
                   help="fixed wing: throttle doublet time unit [s]; 0: from the phugoid (2)")
    p.add_argument("--mode", default="MANUAL", help="ArduPlane mode the inputs are flown in (MANUAL)")
    p.add_argument("--recovery-mode", default="FBWA", help="ArduPlane mode between blocks and on abort (FBWA)")
    p.add_argument("--trigger-option", type=int, default=300,
                   help="RCx_OPTION of the trigger switch, 300..307 = Scripting1..8 (300)")
    p.add_argument("--min-height", type=float, default=40.0, help="abort below this height above home [m] (40)")
    p.add_argument("--rc-rate", type=float, default=None, help="RC-override row rate [Hz] (20; quadrotor 50)")
    p.add_argument("--mapping", type=Path, help="PWM mapping TOML (default: ArduPlane SERVO1-4, +/-0.35 rad)")
    p.add_argument("--check", action="store_true", help="fly the plan in closed loop and check identifiability")
    p.add_argument("--plots", type=Path, help="folder for PNG figures (inputs, spectra, check flight)")
    from uavfmu.commands import excite_quadrotor

    excite_quadrotor.add_arguments(p)


def _options(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from identification.excite.design import ExciteOptions
    from identification.excite.writers import OutputOptions

    opt = ExciteOptions(airspeed_m_s=args.airspeed, inputs=comma_list(args.inputs or "3211,doublet,multisine"),
                        surfaces=comma_list(args.surfaces),
                        roll_limit_deg=args.roll_limit, pitch_limit_deg=args.pitch_limit,
                        surface_limit_deg=args.surface_limit, rate_hz=or_default(args.rate, 50.0), settle_s=args.settle,
                        tail_s=args.tail, recovery_s=or_default(args.recovery, 10.0),
                        multisine_period_s=args.multisine_period,
                        max_frequency_hz=or_default(args.max_frequency, 3.0), throttle_blocks=args.throttle_blocks,
                        throttle_amplitude=args.throttle_amplitude, throttle_pulse_s=args.throttle_pulse)
    out = OutputOptions(excite_mode=args.mode, recovery_mode=args.recovery_mode,
                        trigger_option=args.trigger_option, min_height_m=args.min_height,
                        rc_rate_hz=or_default(args.rc_rate, 20.0))
    return opt, out


def run(args: argparse.Namespace) -> int:
    """Plan, check, write, print; see the module docstring."""
    import dataclasses

    if args.vehicle == "quadrotor":
        from uavfmu.commands import excite_quadrotor

        return excite_quadrotor.run(args)

    from fmu_models.common.errors import ParameterError
    from fmu_models.fmi.fmus import load_vehicle_params
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.excite.workflow import excite, write_files, write_plots

    try:
        opt, out = _options(args)
        if args.mapping:
            out = dataclasses.replace(out, mapping=PwmMapping.load(args.mapping))
        params = load_vehicle_params(args.params, "fixed_wing") if args.params else None
        command = "uavfmu excite " + " ".join(sys.argv[2:])
        result = excite(params, opt, out, check=args.check, command=command)
    except (OSError, ValueError, ParameterError) as err:  # ExciteError, ConfigError, MappingError, ...
        print(f"uavfmu excite: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    paths = write_files(result, args.out)
    if args.plots:
        paths += write_plots(result, args.plots, command)
    print(result.summary())
    print("wrote " + ", ".join(str(p) for p in paths))
    return EXIT_ILL_CONDITIONED if result.check_passed is False else EXIT_OK

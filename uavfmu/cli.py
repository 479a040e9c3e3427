"""The `uavfmu` command: one entry point, sub-commands living beside the code they drive.

Each sub-command module exposes ``add_arguments(parser)`` and ``run(args) -> int``; this file only
dispatches, so it imports a sub-command's module (and its heavy dependencies) only when it is used.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from uavfmu import __version__

#: sub-command -> (module, one-line help). A module listed here must exist.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "build": ("uavfmu.commands.build", "build dist/quadrotor.fmu and dist/fixed_wing.fmu (native or pythonfmu)"),
    "identify": ("uavfmu.commands.identify", "identify a thrust map (thrust) or aero derivatives (aero) from a log"),
    "excite": ("uavfmu.commands.excite", "plan identification manoeuvres (3-2-1-1, doublets, multisines) for a fixed "
               "wing: ArduPilot Lua, RC-override steps, timeline; or for a quadrotor (--vehicle quadrotor): "
               "MANUAL_CONTROL or RC-override steps, ArduCopter SystemId parameters"),
    "validate": ("uavfmu.commands.validate", "replay a flight log through an FMU with FMPy and score it"),
    "discrepancy": ("uavfmu.commands.discrepancy", "learn an FMU's replay error from logs into its parameter file "
                    "(prediction bands of validate --mc)"),
    "hil": ("uavfmu.commands.hil", "drive an FMU from an autopilot (PX4, ArduPilot JSON, MAVLink, NMEA)"),
    "autopilot-params": ("uavfmu.commands.autopilot_params",
                         "write ArduPlane, ArduCopter or PX4 parameters computed from an FMU's model"),
    "demo": ("uavfmu.demo", "end-to-end demo on simulated data"),
}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Return the top-level parser; with ``only`` set, import just that sub-command."""
    parser = argparse.ArgumentParser(prog="uavfmu", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"uavfmu {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        sp = sub.add_parser(name, help=help_text)
        if only is None or name == only:
            try:
                module = importlib.import_module(module_name)
            except ModuleNotFoundError as err:
                if err.name != module_name:
                    raise
                continue
            module.add_arguments(sp)
            sp.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the chosen sub-command; return its exit status."""
    argv = sys.argv[1:] if argv is None else argv
    first = next((a for a in argv if not a.startswith("-")), None)
    only = first if first in SUBCOMMANDS else "" if "--version" in argv else None  # --version: import nothing
    parser = build_parser(only=only)
    args = parser.parse_args(argv)
    if not hasattr(args, "_run"):
        parser.error(f"sub-command '{args.command}' is not available in this installation")
    return int(args._run(args) or 0)


if __name__ == "__main__":
    raise SystemExit(main())

"""``uavfmu autopilot-params FMU --autopilot arduplane|arducopter|px4 [-o FILE] [--mission FILE]``.

Writes the autopilot's parameter file computed from the FMU's own parameters (default or identified): the
work is ``hil_adapter.autopilot_params.autopilot_params``; every value carries the formula it came from.
ArduPlane: ``--mission FILE`` also writes the circuit mission whose final approach follows the glide path derived
from the model. Exit status: 0 written, 2 bad FMU, vehicle/autopilot mismatch, servo time constant or --mission
for another autopilot.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil_adapter.autopilot_params import AUTOPILOTS, SERVO_TAU_S


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path)
    parser.add_argument("--autopilot", choices=AUTOPILOTS, required=True)
    parser.add_argument("-o", "--output", type=Path, help="file to write (default: print)")
    parser.add_argument("--servo-tau-s", type=float, default=SERVO_TAU_S,
                        help=f"surface servo time constant of the ArduPlane rate design (default {SERVO_TAU_S} s)")
    parser.add_argument("--mission", type=Path, help="ArduPlane: also write the circuit mission (QGC WPL 110)")


def run(args: argparse.Namespace) -> int:
    from hil_adapter.autopilot_params import autopilot_params

    if args.mission is not None and args.autopilot != "arduplane":
        print(f"uavfmu autopilot-params: error: --mission: only arduplane has a mission, not {args.autopilot}",
              file=sys.stderr)
        return 2
    if not args.fmu.is_file():
        print(f"uavfmu autopilot-params: error: {args.fmu}: no such FMU", file=sys.stderr)
        return 2
    try:
        result = autopilot_params(args.fmu, args.autopilot, servo_tau_s=args.servo_tau_s)
    except (ValueError, OSError) as err:
        print(f"uavfmu autopilot-params: error: {args.fmu}: {err}", file=sys.stderr)
        return 2
    if args.output is None:
        print(result.text(), end="")
    else:
        result.write(args.output)
        print(f"wrote {args.output} ({len(result.values)} {args.autopilot} parameters from {args.fmu.name})")
    if args.mission is not None:
        args.mission.write_text(result.mission)
        print(f"wrote {args.mission} (circuit, {result.glide_deg:g} deg glide path to the landing point)")
    for w in result.warnings:  # also in the file as '# WARNING' lines
        print(f"uavfmu autopilot-params: warning: {w}", file=sys.stderr)
    return 0

"""``uavfmu hil FMU --interface px4|ardupilot-json|mavlink|nmea [--config bench.toml]``.

Serves an autopilot from the FMU until Ctrl-C/SIGTERM (or ``--duration-s`` of wall time), printing a live
status line and a summary at exit. The bench config (TOML, every section optional, unknown keys are errors)
is described in ``hil_adapter/config.py``; the work is ``hil_adapter.session.serve``.

Exit status: 0 after a clean stop (Ctrl-C included), 1 when the FMU failed beyond recovery, 2 bad config,
FMU, port or device.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from hil_adapter.config import INTERFACES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path)
    parser.add_argument("--interface", choices=INTERFACES, required=True)
    parser.add_argument("--config", type=Path, help="bench TOML (see hil_adapter/config.py)")
    parser.add_argument("--host", help="bind address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, help="PX4 TCP port (4560) or JSON UDP port (9002)")
    parser.add_argument("--record", type=Path, help="CSV log of every step (overrides [record] path)")
    parser.add_argument("--record-band", action="store_true", help="also record each output's 5-95 %% prediction "
                        "band, from the discrepancy in the FMU's embedded parameter file (uavfmu discrepancy)")
    parser.add_argument("--band-params", type=Path, help="parameter file holding the discrepancy for --record-band "
                        "(implies it)")
    parser.add_argument("--duration-s", type=float, help="stop after this much wall time")
    parser.add_argument("--speed", help="lockstep pace: simulation seconds per wall second (default 1, or "
                        "[timing] speed), 'max' for as fast as the autopilot answers")
    parser.add_argument("--seed", type=int, help="sensor noise seed (default [sensors] seed, else a fresh one, "
                        "printed in the summary)")
    parser.add_argument("--quiet", action="store_true", help="no live status line")


def run(args: argparse.Namespace) -> int:
    from hil_adapter.session import HilSetupError, parse_speed, serve

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.port is not None and not 0 <= args.port <= 65535:
        print(f"uavfmu hil: error: --port {args.port}; allowed 0..65535", file=sys.stderr)
        return 2
    try:
        speed = parse_speed(args.speed) if args.speed is not None else None
    except ValueError as err:
        print(f"uavfmu hil: error: {err}", file=sys.stderr)
        return 2

    def live(line: str) -> None:
        print("\r" + line, end="", flush=True)

    print(f"uavfmu hil: {args.interface} serving {args.fmu.name}", flush=True)
    try:
        result = serve(args.fmu, args.interface, args.config, host=args.host, port=args.port, record=args.record,
                       duration_s=args.duration_s, status=None if args.quiet else live, speed=speed,
                       seed=args.seed, record_band=args.record_band, band_params=args.band_params)
    except HilSetupError as err:
        print(f"uavfmu hil: error: {err}", file=sys.stderr)
        return 2
    print()
    for line in result.lines():
        print(line)
    return 1 if result.error else 0

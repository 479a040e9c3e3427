"""``uavfmu identify quadrotor``: a quadrotor's inertia, motor lag, yaw torque and drag from its logs.

``uavfmu identify quadrotor LOG [LOG ...] [--params FILE.json] --out identified.json [--segments t0:t1,...]
[--blocks FILE.blocks.json] [--window-s 1.0] [--score-window-s 0.5] [--rate-hz 250] [--motor-mass-kg 0.06]
[--battery-mass-kg 0.18]``

Output error on the body rates and the specific force along z (``identification.quadrotor.identify``; method in
``identification/quadrotor/readme.md``): roll and pitch inertia through the arm's moment effectiveness, the
motor time constant, the yaw torque constant with the yaw inertia (the data fix their ratio; the airframe
inertia prior from mass, arm length, motor and battery masses fixes Jz), drag per axis from the logged
velocity, per-window initial rates and accelerometer bias. Inputs are the four motor PWMs; the thrust map is
the one of ``--params`` (``uavfmu identify thrust`` writes it) or the FMU default. Segments: ``--segments``,
else the excitation blocks (``--blocks``, or ``LOG.blocks.json`` beside the log), else the airborne time;
every third is held out and replayed from the logged state every ``--score-window-s`` against persistence.
The parameter file (``--out``) carries the whole quadrotor with the estimates and their covariance in its
``uncertainty`` block: ``uavfmu build --params`` embeds it. This module parses and prints.

Exit status: 0 done; 2 bad input (unreadable log or parameter file, missing signals, bad segments); 3 the
estimation failed; 4 done, but persistence beats the model on a held-out output; 5 estimates written but the
held-out scoring failed; 6 done, but the log cannot determine some parameters (motor commands logged slower
than 50 Hz: inertia, yaw torque and motor lag; no velocity: drag) - they are named, kept at their start values
and what the log can determine is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _positive(lo: float, hi: float):  # type: ignore[no-untyped-def]
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{v:g} is outside {lo:g}..{hi:g}")
        return v
    return parse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", nargs="+", type=Path, help="flight logs of one quadrotor (.ulg, .bin, .csv)")
    parser.add_argument("--params", type=Path, help="start parameter file (thrust map from identify thrust; its "
                                                     "covariance of the map, when there, goes into Jx's and Jy's "
                                                     "intervals)")
    parser.add_argument("--out", type=Path, required=True, help="parameter file to write")
    parser.add_argument("--metrics", type=Path, help="metrics JSON (default: OUT with .metrics.json)")
    parser.add_argument("--segments", help="fit and held-out segments t0:t1,... [s from log start]")
    parser.add_argument("--blocks", type=Path, help="excitation blocks file (default: LOG.blocks.json beside it)")
    parser.add_argument("--window-s", type=_positive(0.2, 10.0), default=1.0,
                        help="fit windows, each replayed from the logged state [s] (0.2..10, default 1)")
    parser.add_argument("--score-window-s", type=_positive(0.1, 5.0), default=0.5,
                        help="held-out replays restart from the logged state this often [s] (0.1..5, default 0.5)")
    parser.add_argument("--rate-hz", type=_positive(10.0, 1000.0), default=250.0,
                        help="output-error sample rate, capped at the motor command rate [Hz] (default 250)")
    parser.add_argument("--motor-mass-kg", type=_positive(0.0, 5.0), default=0.06,
                        help="mass of one motor with propeller and ESC, for the inertia prior [kg] (default 0.06)")
    parser.add_argument("--battery-mass-kg", type=_positive(0.0, 20.0), default=0.18,
                        help="battery mass, for the inertia prior [kg] (default 0.18)")
    parser.add_argument("--force", action="store_true", help="use a log damaged beyond the quality limit")


def run(args: argparse.Namespace) -> int:
    from fmu_models.common.errors import ParameterError
    from fmu_models.common.params import read_json, uncertainty_of
    from fmu_models.quadrotor.params import QuadrotorParams
    from identification.estimation.oem import EstimationError
    from identification.logs.readers import read_log
    from identification.quadrotor import identify as q
    from identification.quadrotor.segments import parse_windows

    try:
        base = read_json(args.params) if args.params else None
        init = QuadrotorParams.from_dict(base.get("quadrotor", base), str(args.params)) if base else QuadrotorParams()
        opt = q.QuadrotorOptions(rate_hz=args.rate_hz, window_s=args.window_s, score_window_s=args.score_window_s,
                                 segments=parse_windows(args.segments) if args.segments else None,
                                 blocks=args.blocks, motor_mass_kg=args.motor_mass_kg,
                                 battery_mass_kg=args.battery_mass_kg, force=args.force)
        # the map's covariance (identify thrust writes it): the inertias inherit the map's slope error
        unc = uncertainty_of(base, str(args.params)) if base and "uncertainty" in base else None
        logs = [read_log(p) for p in args.log]
        result = q.identify_quadrotor(logs, init, opt, map_uncertainty=unc)
    except EstimationError as err:
        print(f"uavfmu identify quadrotor: estimation failed, nothing written: {err}", file=sys.stderr)
        return q.EXIT_FAILED
    except (OSError, ValueError, KeyError, ParameterError) as err:  # LogError, SegmentError, input errors
        print(f"uavfmu identify quadrotor: {str(err).strip(chr(39) + chr(34))}", file=sys.stderr)
        return q.EXIT_BAD_INPUT
    metrics = args.metrics or args.out.with_suffix(".metrics.json")
    q.write_results(result, args.out, metrics, base, [str(p) for p in args.log])
    print(result.summary())
    print(f"parameters: {args.out}\nmetrics: {metrics}\nexit status {result.exit_code}")
    return result.exit_code

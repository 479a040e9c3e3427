"""``uavfmu validate``: replay flight logs through FMUs with FMPy and score them against the logs and against
the simplest rivals (persistence, the window mean).

``uavfmu validate FMU LOG [--map FILE.toml] [--report DIR]`` or ``uavfmu validate --batch manifest.toml``.

Inputs: quadrotor motor PWM, or fixed-wing surface and throttle commands through the PWM mapping
(``--mapping FILE.toml``, else the log's ArduPilot ``SERVOn_*`` parameters). Compared signals and their pass
rules come from the output map (``--map``; defaults per vehicle in ``identification.output_map``). Windows
of ``--window-s`` seconds are each re-initialised from the logged state (0: one full-length replay);
windows with the vehicle on the ground are left out unless ``--include-ground``. The work is done by
``identification.validation_workflow``; this module parses and prints.

Exit status: 0 every gated signal of every run passes, 1 a signal fails (or a batch run errors), 2 bad input,
3 nothing fails but a signal ties with persistence (its skill interval reaches zero) or nothing was scored.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

EXIT_PASS, EXIT_FAIL, EXIT_BAD_INPUT, EXIT_TIE = 0, 1, 2, 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path, nargs="?", help="the FMU to validate")
    parser.add_argument("log", type=Path, nargs="?", help="flight log (.bin/.log, .tlog, .ulg, .csv)")
    parser.add_argument("--batch", type=Path, help="manifest TOML of FMU x log runs (instead of FMU LOG)")
    parser.add_argument("--map", type=Path, help="output map TOML (FMU output <- log signal, units, pass rules)")
    parser.add_argument("--mapping", type=Path, help="PWM mapping TOML for fixed-wing surfaces and throttle")
    parser.add_argument("--window-s", type=float, help="replay windows [s] (0: full length; default 2)")
    parser.add_argument("--rate-hz", type=float, help="replay sample rate [Hz] (default 50, at most 2000)")
    parser.add_argument("--horizons-s", type=str, help="prediction horizons [s], comma separated "
                                                       "(default 0.1,0.5,1,2)")
    parser.add_argument("--include-ground", action="store_true", default=None,
                        help="also score windows where the vehicle is on the ground")
    parser.add_argument("--max-memory-mb", type=float, help="stop before a replay needs more memory (default 2048)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter")
    parser.add_argument("--max-theil", type=float, help="pass threshold on Theil's U for every signal")
    parser.add_argument("--report", type=Path, help="folder for report.html and metrics.json")
    parser.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] for the log's outputs")
    parser.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), help="batch worker processes")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _parse_set(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--set {item!r}: expected NAME=NUMBER") from None
    return out


def _option_values(args: argparse.Namespace) -> dict[str, object]:
    horizons = None
    if args.horizons_s:
        try:
            horizons = [float(x) for x in args.horizons_s.split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"--horizons-s {args.horizons_s!r}: expected numbers separated by commas") from None
    return {"window_s": args.window_s, "rate_hz": args.rate_hz, "horizons_s": horizons,
            "include_ground": args.include_ground, "max_memory_mb": args.max_memory_mb}


def run(args: argparse.Namespace) -> int:
    from fmu_models.config import ConfigError
    from identification.validation import check_options
    from identification.validation_workflow import ValidationJob, load_manifest

    try:
        if args.jobs is not None and not 1 <= args.jobs <= 64:
            raise ValueError(f"--jobs = {args.jobs}: allowed 1..64")
        if args.max_theil is not None and not 0 < args.max_theil < 1e6:
            raise ValueError(f"--max-theil = {args.max_theil:g}: allowed > 0")
        values = {k: v for k, v in _option_values(args).items() if v is not None}
        opts = check_options(**values)
        if args.batch:
            jobs = load_manifest(args.batch, values, args.report)
        elif args.fmu is None or args.log is None:
            raise ValueError("give FMU and LOG, or --batch manifest.toml")
        else:
            jobs = [ValidationJob(args.fmu, args.log, opts, args.map, args.mapping, args.channel_map,
                                  _parse_set(args.set), args.max_theil, args.report)]
    except (ValueError, ConfigError) as err:
        print(f"uavfmu validate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return _run_batch(jobs, args) if args.batch else _run_one(jobs[0], args)


def _run_one(job: object, args: argparse.Namespace) -> int:
    from fmu_models.fmi.host import FmuRunError
    from identification.validation_workflow import validate

    try:
        res = validate(job)  # type: ignore[arg-type]
    except (FmuRunError, OSError, ValueError, KeyError) as err:
        print(f"uavfmu validate: error: {str(err).strip(chr(39) + chr(34))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(res.lines()))
    if res.report:
        print(f"report: {res.report}")
    return exit_status([res.status])


def _run_batch(jobs: list, args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from identification.validation_workflow import batch_summary, validate_batch, write_batch_report

    with tqdm(total=len(jobs), desc="validate", disable=args.quiet) as bar:
        results = validate_batch(jobs, args.jobs, progress=lambda done, total: bar.update(1))
    for r in results:
        print("\n".join(r.lines()))
    print(batch_summary(results))
    if args.report:
        print(f"report: {write_batch_report(results, args.report)}")
    return exit_status([r.status for r in results])


def exit_status(statuses: list[str]) -> int:
    """0 all pass; 1 any fails or errors; else 3 (a tie or nothing scored: not shown better than persistence)."""
    if any(s in ("fail", "error") for s in statuses):
        return EXIT_FAIL
    return EXIT_PASS if all(s == "pass" for s in statuses) else EXIT_TIE

"""``uavfmu validate``: replay flight logs through FMUs with FMPy and score them against the logs and against
the simplest rivals (persistence, the window mean).

``uavfmu validate FMU LOG [--map FILE.toml] [--report DIR]`` or ``uavfmu validate --batch manifest.toml``.

Inputs: quadrotor motor PWM, or fixed-wing surface and throttle commands through the PWM mapping
(``--mapping FILE.toml``, else the log's ArduPilot ``SERVOn_*`` parameters). Compared signals and their pass
rules come from the output map (``--map``; defaults per vehicle in ``identification.validation.output_map``). Windows
of ``--window-s`` seconds are each re-initialised from the logged state (0: one full-length replay);
windows with the vehicle on the ground are left out unless ``--include-ground``; ``--segments t0:t1,...`` or
``--segments-from METRICS.json`` (the held-out segments of ``identify quadrotor``) score only the windows that lie
wholly inside those spans. The work is done by
``identification.validation.workflow``; this module parses and prints.

Runs go through ``identification.common.parallel`` (dask.distributed): local worker processes (``--jobs``), or a running
cluster (``--scheduler tcp://HOST:PORT`` or ``UAVFMU_SCHEDULER``; docs/scale-out.md). ``--mc N --uncertainty
PARAMS`` adds Monte Carlo bands: N replays with parameters drawn from the parameter file's ``uncertainty``
block (default: the file the FMU was built from), restart states and sensor noise from the log; each signal's
band coverage is printed beside its skill.
``--params PARAMS`` (an ``identify thrust`` parameter file; manifest key ``params``) drives the quadrotor's
``battery_voltage_V`` from its battery-state model: the logged voltage, else the hover state computed from the
log (``identification.validation.replay_battery``); the source is printed and in ``metrics.json``. Without ``--params``
the
parameter file the FMU was built from (``build --params`` embeds it) does the same; ``--no-embedded-params``
holds the input at its start value instead.

``--mc`` also adds the model's learned discrepancy (the ``discrepancy`` key of the same parameter file, written by
``uavfmu discrepancy``; ``--no-discrepancy`` leaves it out), so the band is parameters + discrepancy + sensor noise.

Exit status: 0 every gated signal of every run passes, 1 a signal fails (or a batch run errors), 2 bad input,
3 nothing fails but a signal ties with persistence (its skill interval reaches zero) or nothing was scored,
4 (with ``--mc``) nothing fails but a gated signal's 90 % band covers less than 80 % or more than 98 % of its
logged samples and the replay's windows show it (``identification.validation.mc_bands``: the band does not say how
far the replay can be trusted).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

EXIT_PASS, EXIT_FAIL, EXIT_BAD_INPUT, EXIT_TIE, EXIT_BAND = 0, 1, 2, 3, 4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path, nargs="?", help="the FMU to validate")
    parser.add_argument("log", type=Path, nargs="?", help="flight log (.bin/.log, .tlog, .ulg, .csv)")
    parser.add_argument("--batch", type=Path, help="manifest TOML of FMU x log runs (instead of FMU LOG)")
    parser.add_argument("--map", type=Path, help="output map TOML (FMU output <- log signal, units, pass rules)")
    parser.add_argument("--mapping", type=Path, help="PWM mapping TOML for fixed-wing surfaces and throttle")
    parser.add_argument("--window-s", type=float, help="replay windows [s] (0: full length; default 2)")
    parser.add_argument("--rate-hz", type=float, help="replay sample rate [Hz] (default 50, at most 2000)")
    parser.add_argument("--segments", help="score only windows inside these spans t0:t1,... [s from the log start]")
    parser.add_argument("--segments-from", type=Path, metavar="METRICS",
                        help="score only windows inside the held-out segments of an identify quadrotor metrics "
                             "JSON (its held_out_segments)")
    parser.add_argument("--horizons-s", type=str, help="prediction horizons [s], comma separated "
                                                       "(default 0.1,0.5,1,2)")
    parser.add_argument("--include-ground", action="store_true", default=None,
                        help="also score windows where the vehicle is on the ground")
    parser.add_argument("--start-velocity", choices=("force", "logged"), default=None,
                        help="fixed wing: each window's start body velocity v, w matching the logged specific force "
                             "at the restart (force, default) or the GPS velocity's as logged")
    parser.add_argument("--max-memory-mb", type=float, help="stop before a replay needs more memory (default 2048)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter")
    parser.add_argument("--max-theil", type=float, help="pass threshold on Theil's U for every signal")
    parser.add_argument("--report", type=Path, help="folder for report.html and metrics.json")
    parser.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] for the log's outputs")
    parser.add_argument("--params", type=Path, metavar="PARAMS",
                        help="parameter file of `identify thrust`: its battery-state model drives the quadrotor's "
                             "battery_voltage_V (logged voltage, else the hover state from the log; default with "
                             "--mc: the --uncertainty file)")
    parser.add_argument("--no-embedded-params", action="store_true",
                        help="without --params, do not read the battery-state model from the parameter file the "
                             "FMU was built from (embedded by `build --params`)")
    parser.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1),
                        help="local worker processes (batch and --mc; ignored with --scheduler)")
    parser.add_argument("--scheduler", default=os.environ.get("UAVFMU_SCHEDULER"),
                        help="dask scheduler of a running cluster, tcp://HOST:PORT (default: $UAVFMU_SCHEDULER, "
                             "else local workers); see docs/scale-out.md")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--mc", type=int, metavar="N", help="Monte Carlo bands: N replays with parameters drawn from "
                                                            "--uncertainty (a wrong N names the allowed range)")
    parser.add_argument("--uncertainty", type=Path, metavar="PARAMS",
                        help="parameter file (JSON/TOML) whose 'uncertainty' key gives names, mean, covariance "
                             "(default: the file embedded in the FMU by `build --params`)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo draws (default 0)")
    parser.add_argument("--no-discrepancy", action="store_true",
                        help="--mc without the learned model discrepancy of the parameter file (parameters and "
                             "sensor noise only)")


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
            "include_ground": args.include_ground, "start_velocity": args.start_velocity,
            "max_memory_mb": args.max_memory_mb,
            "segments_s": _segments(args)}


def _segments(args: argparse.Namespace) -> list[tuple[float, float]] | None:
    """``--segments t0:t1,...`` and the ``held_out_segments`` of ``--segments-from`` as (t0, t1) pairs."""
    import json

    items = [s for s in (getattr(args, "segments", None) or "").split(",") if s.strip()]
    src = getattr(args, "segments_from", None)
    if src is not None:
        try:
            held = json.loads(Path(src).read_text()).get("held_out_segments")
        except (OSError, ValueError, AttributeError) as err:
            raise ValueError(f"--segments-from {src}: not a readable metrics JSON ({err})") from None
        if not isinstance(held, list) or not all(isinstance(h, str) for h in held):
            raise ValueError(f"--segments-from {src}: no held_out_segments list of 't0:t1' strings in it")
        items += held
    if not items:
        return None
    from identification.logs.timeline import parse_spans

    return parse_spans(items, "--segments")


def run(args: argparse.Namespace) -> int:
    from fmu_models.config import ConfigError
    from identification.validation.replay import check_options
    from identification.validation.workflow import ValidationJob, load_manifest

    try:
        if args.jobs is not None and not 1 <= args.jobs <= 64:
            raise ValueError(f"--jobs = {args.jobs}: allowed 1..64")
        if args.max_theil is not None and not 0 < args.max_theil < 1e6:
            raise ValueError(f"--max-theil = {args.max_theil:g}: allowed > 0")
        values = {k: v for k, v in _option_values(args).items() if v is not None}
        opts = check_options(**values)
        if args.batch and args.params:
            raise ValueError("--params applies to FMU LOG; in a --batch manifest give params = \"FILE\" per job")
        if args.batch:
            jobs = load_manifest(args.batch, values, args.report)
        elif args.fmu is None or args.log is None:
            raise ValueError("give FMU and LOG, or --batch manifest.toml")
        else:
            jobs = [ValidationJob(args.fmu, args.log, opts, args.map, args.mapping, args.channel_map,
                                  _parse_set(args.set), args.max_theil, args.report,
                                  params_file=args.params or (args.uncertainty if args.mc else None),
                                  embedded_params=not args.no_embedded_params)]
        uncertainty = _uncertainty(args)
        discrepancy = _discrepancy(args) if uncertainty is not None else None
    except (ValueError, ConfigError) as err:
        print(f"uavfmu validate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.batch:
        return _run_batch(jobs, args, uncertainty, discrepancy)
    return _run_one(jobs[0], args, uncertainty, discrepancy)


def _discrepancy(args: argparse.Namespace) -> object:
    """The learned model discrepancy for ``--mc``: of the --uncertainty file, else the FMU's embedded file."""
    from identification.validation.workflow import mc_discrepancy

    if args.no_discrepancy:
        return None
    return mc_discrepancy(args.uncertainty, None if args.batch else args.fmu)


def _uncertainty(args: argparse.Namespace) -> object:
    """The parameter file's uncertainty block for ``--mc`` (None without ``--mc``)."""
    from identification.validation.mc_bands import MAX_DRAWS, MIN_DRAWS
    from identification.validation.workflow import mc_uncertainty

    if args.mc is None:
        if args.uncertainty is not None:
            raise ValueError("--uncertainty is read by --mc N; give both")
        return None
    if not MIN_DRAWS <= args.mc <= MAX_DRAWS:
        raise ValueError(f"--mc = {args.mc}: allowed {MIN_DRAWS}..{MAX_DRAWS}")
    if not 0 <= args.seed < 2**63:
        raise ValueError(f"--seed = {args.seed}: allowed 0..2**63-1")
    if args.batch and args.uncertainty is None:
        raise ValueError("--batch with --mc needs --uncertainty PARAMS (one parameter file with an 'uncertainty' "
                         "key for every run): the FMUs' embedded files are read only for a single FMU LOG run")
    return mc_uncertainty(args.uncertainty, None if args.batch else args.fmu)


def _run_one(job: object, args: argparse.Namespace, uncertainty: object = None, discrepancy: object = None) -> int:
    from fmu_models.fmi.host import FmuRunError
    from identification.common.parallel import ParallelError
    from identification.validation.workflow import validate, validate_mc

    try:
        if uncertainty is None:
            res = validate(job)  # type: ignore[arg-type]
        else:
            res = validate_mc(job, uncertainty, args.mc, args.seed, workers=args.jobs,  # type: ignore[arg-type]
                              scheduler=args.scheduler, progress=not args.quiet,
                              discrepancy=discrepancy)  # type: ignore[arg-type]
    except (FmuRunError, OSError, ValueError, KeyError, ParallelError) as err:
        print(f"uavfmu validate: error: {str(err).strip(chr(39) + chr(34))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(res.lines()))
    if res.report:
        print(f"report: {res.report}")
    return exit_status([res.status])


def _run_batch(jobs: list, args: argparse.Namespace, uncertainty: object = None, discrepancy: object = None) -> int:
    from identification.common.parallel import ParallelError
    from identification.validation.workflow import batch_summary, validate_batch, validate_mc_batch, write_batch_report

    try:
        if uncertainty is None:
            results = validate_batch(jobs, args.jobs, progress=not args.quiet, scheduler=args.scheduler)
        else:  # every run's draws on the same cluster, one run after another
            results = validate_mc_batch(jobs, uncertainty, args.mc, args.seed, workers=args.jobs,  # type: ignore[arg-type]
                                        scheduler=args.scheduler, progress=not args.quiet,
                                        discrepancy=discrepancy)  # type: ignore[arg-type]
    except ParallelError as err:
        print(f"uavfmu validate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for r in results:
        print("\n".join(r.lines()))
    print(batch_summary(results))
    if args.report:
        print(f"report: {write_batch_report(results, args.report)}")
    return exit_status([r.status for r in results])


def exit_status(statuses: list[str]) -> int:
    """0 all pass; 1 any fails or errors; 4 a band misses its nominal coverage; else 3 (a tie or nothing scored:
    not shown better than persistence)."""
    if any(s in ("fail", "error") for s in statuses):
        return EXIT_FAIL
    if "band" in statuses:
        return EXIT_BAND
    return EXIT_PASS if all(s == "pass" for s in statuses) else EXIT_TIE

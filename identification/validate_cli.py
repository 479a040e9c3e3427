"""``uavfmu validate``: replay flight logs through FMUs with FMPy and score them against the logs.

``uavfmu validate FMU LOG [--map FILE.toml] [--report DIR]`` or ``uavfmu validate --batch manifest.toml``.

Inputs: quadrotor motor PWM, or fixed-wing surface and throttle commands through the HIL adapter's PWM
mapping (``--mapping FILE.toml``, else the log's ArduPilot ``SERVOn_*`` parameters). Compared signals come
from the output map (``--map``; defaults per vehicle in ``identification.output_map``, including paper
000's Fig. 5 thrust check for the quadrotor). Windows of ``--window-s`` seconds are each re-initialised
from the logged state (0: one full-length replay).

Batch manifest (TOML; paths relative to it; ``fmu`` and ``log`` may be lists: every pair runs)::

    [defaults]
    window_s = 2.0
    [[job]]
    fmu = ["dist/quadrotor.fmu", "dist/quadrotor_identified.fmu"]
    log = "flight.bin"
    set = { mass_kg = 1.2 }

Exit status: 0 every signal of every run passes, 1 a signal fails or a batch run errors, 2 bad input.
"""

from __future__ import annotations

import argparse
import os
import sys
import tomllib
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

EXIT_PASS, EXIT_FAIL, EXIT_BAD_INPUT = 0, 1, 2
JOB_KEYS = {"fmu", "log", "map", "mapping", "set", "window_s", "rate_hz", "max_theil", "channel_map"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path, nargs="?", help="the FMU to validate")
    parser.add_argument("log", type=Path, nargs="?", help="flight log (.bin/.log, .tlog, .ulg, .csv)")
    parser.add_argument("--batch", type=Path, help="manifest TOML of FMU x log runs (instead of FMU LOG)")
    parser.add_argument("--map", type=Path, help="output map TOML (FMU output <- log signal, units, thresholds)")
    parser.add_argument("--mapping", type=Path, help="PWM mapping TOML for fixed-wing surfaces and throttle")
    parser.add_argument("--window-s", type=float, default=2.0, help="replay windows [s] (0: full length)")
    parser.add_argument("--rate-hz", type=float, default=50.0, help="replay sample rate [Hz]")
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


def validate_one(job: dict[str, Any]) -> dict[str, Any]:
    """One FMU against one log; never raises for bad input or a failing FMU (the batch must go on).

    Returns ``{"fmu", "log", "status": pass|fail|error, "signals", "failed", "worst_theil", "error", "report"}``.
    """
    from dataclasses import replace

    from fmu_models.fmi.host import FmuHost, FmuRunError
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification import output_map, report
    from identification.jsonio import write_json
    from identification.readers import read_log
    from identification.validation import replay, vehicle_of

    fmu, log_path = Path(job["fmu"]), Path(job["log"])
    out: dict[str, Any] = {"fmu": str(fmu), "log": str(log_path), "status": "error", "failed": [], "error": ""}
    try:
        log = read_log(log_path, channel_map=job.get("channel_map"))
        with FmuHost(fmu) as host:
            maps = output_map.load(job.get("map"), vehicle_of(host))
            if job.get("max_theil") is not None:
                maps = tuple(replace(m, max_theil=float(job["max_theil"])) for m in maps)
            mapping = PwmMapping.load(job["mapping"]) if job.get("mapping") else None
            res = replay(host, log, log_path, maps, rate_hz=float(job.get("rate_hz", 50.0)),
                         window_s=float(job.get("window_s", 2.0)) or None, start_values=job.get("set") or {},
                         mapping=mapping)
    except (FmuRunError, OSError, ValueError, KeyError) as err:  # LogError, MappingError, ... are ValueErrors
        out["error"] = str(err).strip("'\"")
        return out
    out["signals"] = {m.fmu: {**res.overall[m.fmu].as_dict(), "max_theil": m.max_theil, "max_rmse": m.max_rmse,
                              "log_signal": m.log}
                      for m in res.maps}
    out["failed"] = res.failed
    out["status"] = "fail" if res.failed else "pass"
    out["worst_theil"] = max(r.theil_u for r in res.overall.values())
    if job.get("report"):
        rdir = Path(job["report"])
        rdir.mkdir(parents=True, exist_ok=True)
        (rdir / "report.html").write_text(report.validation_page(res))
        write_json(rdir / "metrics.json",
                   {"fmu": res.fmu, "log": res.log, "window_s": job.get("window_s"), "rate_hz": job.get("rate_hz"),
                    "windows": res.windows, "signals": out["signals"], "failed": res.failed,
                    "per_window": [{k: v.as_dict() for k, v in w.items()} for w in res.window_metrics]})
        out["report"] = str(rdir / "report.html")
    return out


def _table(results: list[dict[str, Any]]) -> str:
    lines = []
    for r in results:
        if r["status"] == "error":
            lines.append(f"{Path(r['fmu']).name} x {Path(r['log']).name}: ERROR {r['error']}")
            continue
        lines.append(f"{Path(r['fmu']).name} x {Path(r['log']).name}: {r['status'].upper()}")
        lines.append(f"  {'signal':<20} {'RMSE':>10} {'Theil U':>8} {'fit %':>8} {'R^2':>8}  pass when")
        for s, m in r["signals"].items():
            flag = "" if s not in r["failed"] else "  FAIL"
            rule = f"U < {m['max_theil']:g}" + (f" or RMSE < {m['max_rmse']:g}" if m.get("max_rmse") else "")
            lines.append(f"  {s:<20} {m['rmse']:10.4g} {m['theil_u']:8.3f} {m['fit_percent']:8.1f} {m['r2']:8.3f}  "
                         f"{rule}{flag}")
    return "\n".join(lines)


def _jobs_from_manifest(path: Path, args: argparse.Namespace) -> list[dict[str, Any]]:
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ValueError(f"{path}: cannot read the manifest ({err})") from err
    base = path.parent
    defaults = data.get("defaults", {})
    problems, jobs = [], []
    for i, raw in enumerate(data.get("job", [])):
        entry = {**defaults, **raw}
        unknown = sorted(set(entry) - JOB_KEYS)
        if unknown:
            problems.append(f"job[{i}]: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(JOB_KEYS))})")
        if "fmu" not in entry or "log" not in entry:
            problems.append(f"job[{i}]: needs 'fmu' and 'log'")
            continue
        fmus = entry["fmu"] if isinstance(entry["fmu"], list) else [entry["fmu"]]
        logs = entry["log"] if isinstance(entry["log"], list) else [entry["log"]]
        for f in fmus:
            for lg in logs:
                job = {k: v for k, v in entry.items() if k not in ("fmu", "log")}
                job.update(fmu=str(base / f), log=str(base / lg))
                for key in ("map", "mapping", "channel_map"):
                    if job.get(key):
                        job[key] = str(base / job[key])
                job.setdefault("window_s", args.window_s)
                job.setdefault("rate_hz", args.rate_hz)
                if args.max_theil is not None:
                    job["max_theil"] = args.max_theil
                jobs.append(job)
    if problems:
        raise ValueError(f"{path}: " + "; ".join(problems))
    if not jobs:
        raise ValueError(f"{path}: no [[job]] entries")
    return jobs


def run(args: argparse.Namespace) -> int:
    try:
        overrides = _parse_set(args.set)
        if args.batch:
            jobs = _jobs_from_manifest(args.batch, args)
        elif args.fmu is None or args.log is None:
            raise ValueError("give FMU and LOG, or --batch manifest.toml")
        else:
            jobs = [{"fmu": str(args.fmu), "log": str(args.log), "map": args.map, "mapping": args.mapping,
                     "set": overrides, "window_s": args.window_s, "rate_hz": args.rate_hz,
                     "max_theil": args.max_theil, "channel_map": args.channel_map, "report": args.report}]
    except ValueError as err:
        print(f"uavfmu validate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.batch:
        return _run_batch(jobs, args)
    res = validate_one(jobs[0])
    if res["status"] == "error":
        print(f"uavfmu validate: error: {res['error']}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(_table([res]))
    if res.get("report"):
        print(f"report: {res['report']}")
    return EXIT_FAIL if res["failed"] else EXIT_PASS


def _run_batch(jobs: list[dict[str, Any]], args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from identification import report
    from identification.jsonio import write_json

    root = args.report
    for k, job in enumerate(jobs):
        if root:
            job["report"] = str(root / f"{k:03d}_{Path(job['fmu']).stem}__{Path(job['log']).stem}")
    results: list[dict[str, Any]] = [{}] * len(jobs)
    # each run in its own process: FMUs are native code and one that misbehaves must not take the batch down
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = {pool.submit(validate_one, job): k for k, job in enumerate(jobs)}
        for fut in tqdm(as_completed(futures), total=len(jobs), desc="validate", disable=args.quiet):
            k = futures[fut]
            try:
                results[k] = fut.result()
            except Exception as err:  # a worker that died (segfault in an FMU) raises BrokenProcessPool here
                results[k] = {"fmu": jobs[k]["fmu"], "log": jobs[k]["log"], "status": "error", "failed": [],
                              "error": f"worker process failed: {type(err).__name__}: {err}"}
    print(_table(results))
    bad = [r for r in results if r["status"] != "pass"]
    print(f"{len(results)} runs: {len(results) - len(bad)} pass, "
          f"{sum(r['status'] == 'fail' for r in results)} fail, {sum(r['status'] == 'error' for r in results)} error")
    if root:
        root.mkdir(parents=True, exist_ok=True)
        for r in results:
            if r.get("report"):
                r["report"] = str(Path(r["report"]).relative_to(root.resolve()) if Path(r["report"]).is_absolute()
                                  else Path(r["report"]).relative_to(root))
        (root / "index.html").write_text(report.index_page(results))
        write_json(root / "results.json", results)
        print(f"report: {root / 'index.html'}")
    return EXIT_FAIL if bad else EXIT_PASS

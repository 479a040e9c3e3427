"""The validation workflow as library functions: one FMU against one log (:func:`validate`), with Monte Carlo
bands (:func:`validate_mc`), a job that never raises (:func:`validate_job`), a batch of FMU x log jobs on the
workers of ``identification.common.parallel`` (:func:`validate_batch`) and the batch manifest (:func:`load_manifest`).
Each returns
:class:`ValidationResult` objects; ``uavfmu validate`` only parses arguments and prints their ``lines()``.

Batch manifest (TOML; paths relative to it; ``fmu`` and ``log`` may be lists: every pair runs)::

    [defaults]
    window_s = 2.0
    [[job]]
    fmu = ["dist/quadrotor.fmu", "dist/quadrotor_identified.fmu"]
    log = "flight.bin"
    params = "thrust.json"   # optional: its battery-state model drives battery_voltage_V
    set = { mass_kg = 1.2 }
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field

from fmu_models.common.params import Uncertainty
from fmu_models.config import (
    ConfigError,
    FiniteFloat,
    PositiveFiniteFloat,
    Schema,
    read_config_file,
    validate_config,
)
from fmu_models.fmi.host import FmuRunError
from identification.validation.job import ValidationJob, job_files, load_maps
from identification.validation.replay import Horizon, ReplayResult, ValidationInputError, options

if TYPE_CHECKING:
    import numpy as np

    from fmu_models.common.params import Discrepancy
    from identification.common.parallel import Executor
    from identification.validation.discrepancy import DiscrepancyResult

MAX_JOBS = 10_000
#: band verdicts (``identification.validation.mc_bands.Bands.verdict``) that make a run's status ``band``
BAND_MISSES = ("not explained", "wide")


class ManifestError(ConfigError):
    """A bad batch manifest; one line per problem with job, field, value and allowed range."""


class JobEntry(Schema):
    """One ``[[job]]`` (or the ``[defaults]``) of a batch manifest."""

    fmu: str | list[str] | None = None
    log: str | list[str] | None = None
    map: str | None = None
    mapping: str | None = None
    channel_map: str | None = None
    params: str | None = None  #: ``identify thrust`` parameter file whose battery state drives battery_voltage_V
    set: dict[str, FiniteFloat] = Field(default_factory=dict)
    window_s: float | None = Field(None, ge=0, le=86400, allow_inf_nan=False)
    rate_hz: float | None = Field(None, gt=0, le=2000, allow_inf_nan=False)
    horizons_s: list[Horizon] | None = Field(None, max_length=32)
    include_ground: bool | None = None
    start_velocity: Literal["force", "logged"] | None = None
    max_memory_mb: PositiveFiniteFloat | None = None
    max_theil: PositiveFiniteFloat | None = None


class Manifest(Schema):
    defaults: JobEntry = JobEntry()
    job: list[JobEntry] = Field(min_length=1, max_length=MAX_JOBS)


@dataclass
class ValidationResult:
    """Outcome of one job: ``status`` pass | fail | tie | unscored | error (see ``ReplayResult.status``),
    per-signal pooled scores with verdicts and
    reasons, window counts, log warnings; ``replay`` holds the full arrays (None across processes)."""

    fmu: str
    log: str
    status: str = "error"
    error: str = ""
    signals: dict[str, dict[str, Any]] = field(default_factory=dict)
    failed: list[str] = field(default_factory=list)
    windows: int = 0
    excluded: int = 0
    ground: dict[str, int] = field(default_factory=dict)
    gaps: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    one_step: dict[str, dict[str, Any]] = field(default_factory=dict)
    horizons: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    report: str | None = None
    replay: ReplayResult | None = None
    retried: str = ""
    battery: dict[str, Any] | None = None  #: where ``battery_voltage_V`` came from (with ``params_file``)
    #: logged inputs outside what the FMU was built for (``identification.validation.input_check``), as dicts
    input_checks: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays)."""
        keys = ("fmu", "log", "status", "error", "signals", "failed", "windows", "excluded", "ground", "gaps",
                "warnings", "one_step", "horizons", "report", "retried", "battery", "input_checks")
        return {k: getattr(self, k) for k in keys}

    def lines(self) -> list[str]:
        """The console summary: verdict per signal with skills and reason, exclusions and log warnings."""
        return summary_lines(self)


def validate(job: ValidationJob, progress: Callable[[int, int], None] | None = None) -> ValidationResult:
    """Replay, score and (with ``job.report_dir``) write ``report.html`` and ``metrics.json``.

    Raises ``ValidationInputError``, ``ConfigError`` (output map, PWM mapping), ``LogError`` or ``FmuRunError``
    naming the file and what is wrong.
    """
    from fmu_models.fmi.host import FmuHost
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.logs.readers import read_log
    from identification.validation.replay import replay, vehicle_of
    from identification.validation.replay_battery import job_battery_state

    log = read_log(job.log, channel_map=job.channel_map)
    o = job.options
    with FmuHost(job.fmu) as host:  # names a missing or broken FMU before its resources are read
        vehicle = vehicle_of(host)
        battery = job_battery_state(job.fmu, job.params_file, job.embedded_params, vehicle)
        maps = load_maps(job, vehicle)
        mapping = PwmMapping.load(job.mapping) if job.mapping else None
        res = replay(host, log, job.log, maps, rate_hz=o.rate_hz, window_s=o.window_s or None,
                     start_values=dict(job.start_values), mapping=mapping, progress=progress,
                     include_ground=o.include_ground, horizons_s=o.horizons_s, max_memory_mb=o.max_memory_mb,
                     battery=battery, t_range=job.t_range_s, segments_s=o.segments_s,
                     start_velocity=o.start_velocity)
    out = result_of(res, job)
    if job.report_dir is not None:
        write_report(res, out, Path(job.report_dir))
    return out


def result_of(res: ReplayResult, job: ValidationJob) -> ValidationResult:
    """The summary object of a scored replay."""
    signals = {}
    for m in res.maps:
        s = res.scores[m.fmu]
        signals[m.fmu] = {**s.as_dict(), "log_signal": m.log, "max_theil": m.max_theil, "max_rmse": m.max_rmse,
                          "min_skill_persistence": m.min_skill_persistence, "min_skill_mean": m.min_skill_mean,
                          "windows": res.window_counts(m.fmu)}
        if res.bands is not None:
            verdict, why = res.bands.verdict(m.fmu)
            b = res.bands.bounds.get(m.fmu)
            signals[m.fmu] |= {"band_coverage": res.bands.coverage[m.fmu], "band_verdict": verdict,
                               "band_reason": why, **({"band_coverage_bounds": b.as_dict()} if b else {})}
    warnings = list(dict.fromkeys([*res.log["warnings"], *res.log.get("quality_lines", [])]))  # once each
    return ValidationResult(str(job.fmu), str(job.log), res.status, "", signals,
                            res.failed, len(res.windows), res.excluded, dict(res.ground), dict(res.gaps), warnings,
                            {k: v.as_dict() for k, v in res.one_step.items()},
                            {k: [r.as_dict() for r in rows] for k, rows in res.horizons.items()}, None, res,
                            battery=res.battery, input_checks=[f.as_dict() for f in res.input_checks])


def metrics_document(res: ReplayResult, out: ValidationResult) -> dict[str, Any]:
    """``metrics.json``: identities, options, pooled and per-window scores with skills and verdicts,
    horizons, the one-step force check, ground exclusions and the log's data quality."""
    return {
        "fmu": res.fmu, "log": res.log, "options": res.options, "status": out.status, "failed": out.failed,
        "windows": res.windows, "included": res.included,
        "excluded": {"windows": res.excluded, "by_reason": {**res.ground, **res.gaps},
                     "note": "a window is excluded when the vehicle is on the ground at any of its samples, or an "
                             "input or compared signal has no data in it"},
        "signals": out.signals,
        "per_window": [{"t_s": list(w), "included": inc, "signals": {k: v.as_dict() for k, v in ws.items()}}
                       for w, inc, ws in zip(res.windows, res.included, res.window_scores, strict=True)],
        "horizons": {k: [r.as_dict() for r in rows] for k, rows in res.horizons.items()},
        "one_step": out.one_step,
        "battery_voltage_V": res.battery,
        "input_checks": out.input_checks,
        "quality": res.log.get("quality"),
        **({"monte_carlo": res.bands.info} if res.bands is not None else {}),
    }


def write_report(res: ReplayResult, out: ValidationResult, rdir: Path) -> None:
    from identification.validation import report

    _write_files(rdir, metrics_document(res, out), report.validation_page(res))
    out.report = str(rdir / "report.html")


def mc_uncertainty(params_file: Path | None, fmu: Path | None = None) -> Uncertainty:
    """The parameter uncertainty of a Monte Carlo run: the ``uncertainty`` block of ``params_file``, else of the
    parameter file embedded in ``fmu`` by ``build --params``. ``ParameterError`` naming the file when it is
    malformed; ``ValidationInputError`` when there is none, or ``fmu`` is missing."""
    from fmu_models.common.params import read_uncertainty, uncertainty_of
    from fmu_models.fmi.fmuzip import embedded_params

    if params_file is not None:
        return read_uncertainty(params_file)
    if fmu is not None and not Path(fmu).is_file():
        raise ValidationInputError(f"{fmu}: FMU not found")
    found = embedded_params(Path(fmu)) if fmu is not None else None
    if found is None or "uncertainty" not in found[0]:
        raise ValidationInputError("--mc needs --uncertainty PARAMS (a parameter file with an 'uncertainty' key); "
                                   "the FMU carries none (build it with `uavfmu build --params` from an identified "
                                   "file)")
    unc = uncertainty_of(*found)
    from fmpy import read_model_description

    names = {v.name for v in read_model_description(str(fmu)).modelVariables}
    foreign = [n for n in unc.names if n not in names]
    if foreign:  # build --params embeds one file in every FMU: its uncertainty belongs to one model
        raise ValidationInputError(f"{found[1]}: its uncertainty is over parameters this FMU does not have "
                                   f"({', '.join(foreign[:3])}{' ...' if len(foreign) > 3 else ''}); give --mc an "
                                   "--uncertainty file for this model")
    return unc


def mc_discrepancy(params_file: Path | None, fmu: Path | None = None) -> Discrepancy | None:
    """The model discrepancy of a Monte Carlo run: the ``discrepancy`` block of ``params_file``, else of the
    parameter file embedded in ``fmu``; None when there is none (the bands then carry parameters and noise only)."""
    from identification.validation.discrepancy import read_discrepancy

    return read_discrepancy(params_file, fmu)


def validate_mc(job: ValidationJob, uncertainty: Uncertainty, draws: int, seed: int = 0, *,
                workers: int | None = None, scheduler: str | None = None, progress: Any = False,
                executor: Executor | None = None, discrepancy: Discrepancy | None = None,
                keep: dict[str, np.ndarray] | None = None) -> ValidationResult:
    """:func:`validate` with Monte Carlo bands: the nominal replay with the uncertainty's mean as parameters,
    then ``draws`` replays with parameters and restart states drawn (``identification.validation.mc_bands``) on
    ``identification.common.parallel``; each signal's band coverage beside its skill, in the summary, ``metrics.json``
    and
    the report (``executor``: an open one, kept open). ``discrepancy``: the model's learned error added to every
    draw (``identification.validation.discrepancy``; :func:`mc_discrepancy` reads it). Raises like
    :func:`validate`."""
    from fmu_models.fmi.host import FmuHost
    from identification.common.parallel import Executor
    from identification.logs.readers import read_log
    from identification.validation import mc_bands

    clash = sorted(set(job.start_values) & set(uncertainty.names))
    if clash:
        raise ValidationInputError(f"--set {', '.join(clash)}: drawn from the uncertainty in --mc runs; leave it out")
    mc_bands.check_draws(draws, 3, 1, job.options.max_memory_mb)  # the count, before anything runs
    with FmuHost(job.fmu) as host:
        real = {n for n, v in host.variables.items() if v.causality == "parameter" and v.type == "Real"}
        unknown = [n for n in uncertainty.names if n not in real]
        if unknown:
            raise ValidationInputError(f"uncertainty: {', '.join(unknown)} not real parameters of {job.fmu.name}")
        units = {n: host.unit(n) for n in host.variables}
    job = replace(job, start_values={**dict(zip(uncertainty.names, uncertainty.mean, strict=True)),
                                     **job.start_values})
    nominal = validate(replace(job, report_dir=None))
    res = nominal.replay
    assert res is not None
    mc_bands.check_draws(draws, len(res.t_s) + 1, len(res.maps), job.options.max_memory_mb)  # before the cluster
    log = read_log(job.log, channel_map=job.channel_map)
    with nullcontext(executor) if executor is not None else Executor(scheduler, workers) as ex:
        res.bands = mc_bands.monte_carlo(job, uncertainty, res, log, draws, seed, ex, units, progress,
                                         discrepancy=discrepancy, keep=keep)
    out = result_of(res, job)
    if job.report_dir is not None:
        write_report(res, out, Path(job.report_dir))
    return out


def learn_discrepancy(job: ValidationJob, logs: Sequence[Path], params_out: Path | None = None,
                      uncertainty: Uncertainty | None = None, draws: int = 0, seed: int = 0,
                      workers: int | None = 2, *, executor: Executor | None = None) -> DiscrepancyResult:
    """Replay each of ``logs`` as ``job`` (its ``log`` replaced) and learn the model's discrepancy; see
    :func:`learn_discrepancy_jobs`."""
    return learn_discrepancy_jobs([replace(job, log=Path(log)) for log in logs], params_out, uncertainty, draws,
                                  seed, workers, executor=executor)


def learn_discrepancy_jobs(jobs: Sequence[ValidationJob], params_out: Path | None = None,
                           uncertainty: Uncertainty | None = None, draws: int = 0, seed: int = 0,
                           workers: int | None = 2, scaled: bool = True,
                           weights: Sequence[float] = (1.0, 0.0), *,
                           executor: Executor | None = None) -> DiscrepancyResult:
    """Replay each job (same FMU and options; e.g. one log each, each at its own ``--set`` mass) and learn the
    model's discrepancy (``identification.validation.discrepancy``); with ``uncertainty`` and ``draws`` (>= the
    Monte Carlo minimum) also ``draws`` parameter draws of each, on which the combined band is calibrated
    (``mc_bands.calibrate``: the ``band_factor`` that brings the learning replays' band to its level). With
    ``params_out`` (a JSON parameter file) store it there under ``discrepancy``. ``scaled``, ``weights``: as
    ``discrepancy.learn`` and ``mc_bands.calibrate`` take them (studies of their choices). ``executor``: an open
    one for the parameter draws, kept open (else one of ``workers`` local workers for this call). Raises like
    :func:`validate`."""
    from identification.common.parallel import Executor
    from identification.validation.discrepancy import DiscrepancyResult, learn, write_discrepancy
    from identification.validation.mc_bands import calibrate, check_draws

    if not jobs:
        raise ValidationInputError("discrepancy: no replay to learn from")
    if uncertainty is not None and draws:
        check_draws(draws, 3, 1, jobs[0].options.max_memory_mb)  # the count, before anything runs
    mean = dict(zip(uncertainty.names, uncertainty.mean, strict=True)) if uncertainty is not None else {}
    results = []
    for job in jobs:  # the nominal replays at the estimate, as validate_mc's
        res = validate(replace(job, report_dir=None, start_values={**mean, **job.start_values})).replay
        assert res is not None
        results.append(res)
    names = [str(j.log) + (f" {j.t_range_s[0]:g}-{j.t_range_s[1]:g} s" if j.t_range_s else "") for j in jobs]
    disc = learn(results, names, scaled=scaled)
    if uncertainty is not None and draws:
        kept = []
        with nullcontext(executor) if executor is not None else Executor(None, workers) as ex:
            for job in jobs:
                keep: dict[str, np.ndarray] = {}
                out = validate_mc(replace(job, report_dir=None), uncertainty, draws, seed, executor=ex,
                                  discrepancy=disc, keep=keep)
                kept.append((out.replay, keep))
        disc = calibrate(disc, kept, weights=weights)
    written = None
    if params_out is not None:
        write_discrepancy(params_out, disc)
        written = params_out
    summary = tuple({"log": n, "windows_scored": len(r.windows) - r.excluded} for n, r in zip(names, results,
                                                                                            strict=True))
    return DiscrepancyResult(disc, summary, written)


def validate_mc_batch(jobs: Sequence[ValidationJob], uncertainty: Uncertainty, draws: int, seed: int = 0, *,
                      workers: int | None = None, scheduler: str | None = None,
                      progress: Any = False, discrepancy: Discrepancy | None = None) -> list[ValidationResult]:
    """:func:`validate_mc` of every job on one cluster (the same ``seed``: every job sees the same parameter
    draws); a job with bad input or a failing FMU is an ``error`` result naming why, and the rest runs."""
    from identification.common.parallel import Executor

    out = []
    with Executor(scheduler, workers) as ex:
        for job in jobs:
            try:
                out.append(validate_mc(job, uncertainty, draws, seed, progress=progress, executor=ex,
                                       discrepancy=discrepancy))
            except (FmuRunError, OSError, ValueError, KeyError) as err:
                out.append(ValidationResult(str(job.fmu), str(job.log), "error", error=str(err).strip("'\"")))
            out[-1].replay = None  # one replay's arrays in memory at a time
    return out


def _attempt(job: ValidationJob) -> ValidationResult:
    """:func:`validate`, with bad input or a failing FMU as an ``error`` result instead of an exception."""
    try:
        return validate(job)
    except (FmuRunError, OSError, ValueError, KeyError) as err:  # LogError, ConfigError, ... are ValueErrors
        return ValidationResult(str(job.fmu), str(job.log), "error", error=str(err).strip("'\""))


def validate_job(job: ValidationJob) -> ValidationResult:
    """:func:`validate` that never raises for bad input or a failing FMU (a batch must go on); the arrays
    are dropped (results cross process boundaries)."""
    out = _attempt(job)
    out.replay = None
    return out


def batch_task(job: ValidationJob) -> dict[str, Any]:
    """One batch run on a worker: the job on the worker's copies of its files; the summary, and with a report
    folder ``metrics.json`` and ``report.html`` as data (the client writes them: a worker may be another
    machine). Paths come back as the client's (``identification.common.parallel``)."""
    from identification.common.parallel import local_path
    from identification.validation import report

    files = {k: local_path(getattr(job, k)) for k in ("fmu", "log", "output_map", "mapping", "channel_map",
                                                      "params_file")
             if getattr(job, k) is not None}
    out = _attempt(replace(job, report_dir=None, **files))
    doc: dict[str, Any] = {"result": out.as_dict()}
    if job.report_dir is not None and out.replay is not None:
        doc |= {"metrics": metrics_document(out.replay, out),
                "html": report.validation_page(out.replay) if job.report_html else None}
    return doc


def validate_batch(jobs: Sequence[ValidationJob], workers: int | None = 2,
                   progress: Callable[[int, int], None] | bool = False, *, scheduler: str | None = None,
                   executor: Executor | None = None) -> list[ValidationResult]:
    """Every job as a task of ``identification.common.parallel`` (worker processes: an FMU is native code, and one that
    crashes costs its task one retry, not the batch); results in the order of ``jobs``, reports written
    here as each run's result is read back. A run that failed twice is an ``error`` result naming why; a
    retried run says so in ``retried``."""
    from identification.common.parallel import Executor

    with nullcontext(executor) if executor is not None else Executor(scheduler, workers) as ex:  # theirs: kept open
        run = ex.map_tasks(batch_task, list(jobs), files=job_files, progress=progress, desc="validate")
        results = []
        for (i, got), job in zip(run.results(), jobs, strict=True):
            if got is None:
                results.append(ValidationResult(str(job.fmu), str(job.log), "error",
                                                error=f"worker failed twice: {run.failures.get(i, '?')}"))
                continue
            out = ValidationResult(**got["result"])
            if "metrics" in got and job.report_dir is not None:
                _write_files(Path(job.report_dir), got["metrics"], got["html"])
                out.report = str(Path(job.report_dir) / ("report.html" if got["html"] else "metrics.json"))
            out.retried = run.retried.get(i, "")
            results.append(out)
    return results


def _write_files(rdir: Path, metrics: dict[str, Any], page: str | None) -> None:
    from identification.common.jsonio import write_json

    rdir.mkdir(parents=True, exist_ok=True)
    if page is not None:
        (rdir / "report.html").write_text(page)
    write_json(rdir / "metrics.json", metrics)


def load_manifest(path: Path, base_options: Mapping[str, Any] | None = None,
                  report_root: Path | None = None) -> list[ValidationJob]:
    """Jobs of a batch manifest (every ``fmu`` x ``log`` pair of each ``[[job]]``; paths relative to the
    manifest); ``ManifestError`` lists every problem."""
    try:
        data = read_config_file(path)
    except ConfigError as err:
        raise ManifestError(err.source, err.problems) from None
    try:
        man = validate_config(data, Manifest, str(path))
    except ConfigError as err:
        raise ManifestError(str(path), err.problems) from None
    base, problems, jobs = path.parent, [], []
    for i, raw in enumerate(man.job):
        entry = {**man.defaults.model_dump(exclude_none=True), **raw.model_dump(exclude_none=True)}
        if "fmu" not in entry or "log" not in entry:
            problems.append(f"job.{i}: needs 'fmu' and 'log'")
            continue
        try:
            opts = options(str(path), **{**(base_options or {}), **{k: entry[k] for k in _OPTION_KEYS if k in entry}})
        except ConfigError as err:
            problems += [f"job.{i}: {p}" for p in err.problems]
            continue
        for f in _as_list(entry["fmu"]):
            for lg in _as_list(entry["log"]):
                jobs.append(ValidationJob(
                    base / f, base / lg, opts, *(base / entry[k] if k in entry else None
                                                 for k in ("map", "mapping", "channel_map")),
                    dict(entry.get("set", {})), entry.get("max_theil"),
                    params_file=base / entry["params"] if "params" in entry else None))
    if problems:
        raise ManifestError(str(path), problems)
    if report_root is not None:
        jobs = [replace(j, report_dir=report_root / f"{k:03d}_{j.fmu.stem}__{j.log.stem}")
                for k, j in enumerate(jobs)]
    return jobs


_OPTION_KEYS = ("window_s", "rate_hz", "horizons_s", "include_ground", "start_velocity", "max_memory_mb")


def _as_list(v: str | list[str]) -> list[str]:
    return v if isinstance(v, list) else [v]


def _fmt(x: Any, spec: str) -> str:
    return "-" if x is None or (isinstance(x, float) and x != x) else format(x, spec)


def _band_words(r: ValidationResult) -> str:
    return "; ".join(f"{k} {100 * v['band_coverage']:.0f} % ({v['band_verdict']})" for k, v in r.signals.items()
                     if v.get("gated") and v.get("band_verdict") in BAND_MISSES)


def summary_lines(r: ValidationResult) -> list[str]:
    """Console lines of one result (see :meth:`ValidationResult.lines`)."""
    head = f"{Path(r.fmu).name} x {Path(r.log).name}: "
    if r.status == "error":
        return [head + f"ERROR {r.error}"]
    ungated = [s for s, v in r.signals.items() if v["verdict"] == "FAIL" and not v["gated"]]
    na = [s for s, v in r.signals.items() if v["verdict"] == "n/a"]
    ties = [s for s, v in r.signals.items() if v["verdict"] == "tie" and v["gated"]]
    verdict = {"pass": "PASS",
               "fail": f"FAIL ({len(r.failed)} of {len(r.signals)} signals fail: {', '.join(r.failed)})",
               "tie": f"TIE ({', '.join(ties)} not better than persistence with confidence; nothing fails)",
               "unscored": "NOT SCORED (no gated signal has a verdict: nothing was shown)",
               "band": "BANDS MISCALIBRATED (nothing fails, but a gated signal's prediction band covers "
                       f"{_band_words(r)})"}[r.status]
    out = [head + verdict]
    if r.retried:
        out.append(f"  run twice: the first attempt failed ({r.retried})")
    if r.battery:
        out.append(f"  battery_voltage_V: {r.battery['source']} ({r.battery['detail']}; model from "
                   f"{r.battery.get('params', '?')})")
    for f in r.input_checks:
        out.append(f"  INPUT CHECK {f['input']}: {f['check']}: logged {f['logged']}; the FMU expects {f['expected']}; "
                   f"fed {f['fed']}")
    scored = r.windows - r.excluded
    why = ", ".join(f"{k}: {n}" for k, n in {**r.ground, **r.gaps}.items())
    out.append(f"  {scored} of {r.windows} replay windows scored"
               + (f"; {r.excluded} excluded ({why})" if r.excluded else ""))
    if r.replay is not None and r.replay.start_std:
        out.append(f"  {START_WORDS}")
    if r.ground and not r.excluded:
        out.append(f"  left out with the vehicle on the ground: {why}")
    if r.ground:
        out.append("  ground windows/samples are left out by default; --include-ground scores them")
    out += [f"  log warning: {w}" for w in r.warnings]
    bands = any("band_coverage" in v for v in r.signals.values())
    out.append(f"  {'signal':<18} {'verdict':<7} {'skill/pers':>10} {'skill/mean':>10} {'RMSE':>9} {'Theil U':>7} "
               f"{'R^2':>7}{_BAND_HEAD if bands else ''} {'windows pass/FAIL/n/a':>21}  reason")
    # per-window verdicts are point verdicts (one window has no interval); the pooled verdict has the margin
    for s, v in r.signals.items():
        w = v["windows"]
        tag = v["verdict"] + ("" if v["gated"] or v["verdict"] != "FAIL" else "*")
        cover = f" {_fmt(100 * v['band_coverage'], '9.0f')} % {_bounds_text(v):>12}" if bands else ""
        out.append(f"  {s:<18} {tag:<7} {_fmt(v['skill_persistence'], '+10.2f')} {_fmt(v['skill_mean'], '+10.2f')} "
                   f"{_fmt(v['rmse'], '9.3g')} {_fmt(v['theil_u'], '7.3f')} {_fmt(v['r2'], '7.2f')}{cover} "
                   f"{w['pass']:>9}/{w['FAIL']}/{w['n/a']:<6}  {v['reason']}")
    out += _band_lines(r) if bands else []
    if ungated:
        out.append(f"  * not gated (reported only): {', '.join(ungated)}")
    if na:
        out.append(f"  n/a: {', '.join(na)} stayed within tolerance of persistence: neither pass nor fail")
    for name, v in r.one_step.items():
        out.append(f"  one-step force check {name}: RMSE {_fmt(v['rmse'], '.3g')} m/s2, {v['reason']}")
    return out


#: the band columns' header, as wide as their values (:func:`_bounds_text`)
_BAND_HEAD = f"{'band cover':>12}{'95 % bounds':>13}"


def _bounds_text(v: dict[str, Any]) -> str:
    """A signal's band coverage bounds from the replay's windows as ``[lo, hi] %`` (``-`` without them)."""
    b = v.get("band_coverage_bounds")
    if not b or not isinstance(b.get("lower"), float) or not math.isfinite(b["lower"]):  # None once through JSON
        return "-"
    return f"[{100 * b['lower']:.0f}, {100 * b['upper']:.0f}] %"


#: how a fixed wing's window starts were made, where their velocity was read from the specific force
START_WORDS = ("window starts: the body velocity v, w whose specific force matches the log's at the restart "
               "(--start-velocity logged: the GPS's)")


def _band_lines(r: ValidationResult) -> list[str]:
    """What the Monte Carlo bands say: signals the model and its stated uncertainty do not explain."""
    bad = {s: v for s, v in r.signals.items() if v.get("band_verdict") == "not explained"}
    wide = {s: v for s, v in r.signals.items() if v.get("band_verdict") == "wide"}
    unresolved = {s: v for s, v in r.signals.items() if v.get("band_verdict") == "unresolved"}
    out = ["  band cover: share of logged samples inside the 5-95 % Monte Carlo band (nominal 90 %: parameters drawn "
           "from the identified covariance, restart states from the log, convolved with the learned model discrepancy "
           "where the parameter file has one, else plus sensor noise); a gated signal below 80 % or above 98 % is a "
           "finding (status band, exit 4) when the replay's windows show it (the coverage's one-sided 95 % bound is "
           "past the threshold too), else unresolved"]
    disc = (r.replay.bands.info.get("discrepancy") if r.replay is not None and r.replay.bands is not None
            else None) or {}
    alone = [k for k, w in (disc.get("parameter_weight") or {}).items() if w == 0.0]
    if alone:
        out.append(f"  the discrepancy alone on {', '.join(alone)} (the parameter draws' spread widened the band of "
                   "learning replays left out more than it helped: parameter_weight 0)")
    offsets = disc.get("offset") or {}
    if offsets:
        out.append("  band centred off the FMU on " + ", ".join(f"{k} ({v})" for k, v in offsets.items())
                   + ": logged - FMU at the window restarts of every learning replay, where the model has not yet "
                   "erred: a bias the FMU does not have (a sensor's calibration, e.g. an airspeed ratio)")
    if disc.get("signals") and not disc.get("same_windows", True):
        out.append(f"  note: the discrepancy was learned with {disc['window_s']:g} s windows at another window length "
                   "or rate than this replay: its horizons do not match (learn it with the same --window-s, --rate-hz)")
    if disc.get("signals") and not disc.get("same_starts", True):
        out.append(f"  note: the discrepancy was learned from replays started with --start-velocity "
                   f"{disc['start_velocity']}, this replay uses another: its early-horizon errors do not match")
    out += [f"  NOT EXPLAINED {s}: {v['band_reason']}" for s, v in bad.items()]
    out += [f"  WIDE {s}: {v['band_reason']} (or the log's signal carries no noise)" for s, v in wide.items()]
    out += [f"  UNRESOLVED {s}: {v['band_reason']}" for s, v in unresolved.items()]
    return out


def batch_summary(results: Sequence[ValidationResult]) -> str:
    n = {k: sum(r.status == k for r in results) for k in ("pass", "fail", "band", "tie", "unscored", "error")}
    n_retry = sum(bool(r.retried) for r in results)
    return (f"{len(results)} runs: " + ", ".join(f"{v} {k}" for k, v in n.items() if v or k in ("pass", "fail"))
            + (f"; {n_retry} retried after a failed first attempt" if n_retry else ""))


def write_batch_report(results: Sequence[ValidationResult], root: Path) -> Path:
    """``index.html`` (one row per run, failures with their reasons, links) and ``results.json`` in ``root``."""
    from identification.common.jsonio import write_json
    from identification.validation import report

    root.mkdir(parents=True, exist_ok=True)
    rows = [r.as_dict() for r in results]
    for row in rows:
        if row.get("report"):
            row["report"] = str(Path(row["report"]).resolve().relative_to(root.resolve()))
    (root / "index.html").write_text(report.index_page(rows))
    write_json(root / "results.json", rows)
    return root / "index.html"


def failure_lines(results: Sequence[ValidationResult]) -> list[str]:
    """What failed, in plain words: one line per failing gated signal or erroring run (empty when all pass)."""
    out = []
    for r in results:
        run = f"{Path(r.fmu).name} against {Path(r.log).name}"
        if r.status == "error":
            out.append(f"{run} could not be validated: {r.error}")
        if r.status == "unscored":
            out.append(f"{run}: no gated signal could be scored (every one n/a or ungated): not a pass")
        for s in (k for k, v in r.signals.items() if v["verdict"] == "tie" and v["gated"]):
            out.append(f"{run}: {s} ties with persistence - {r.signals[s]['reason']}")
        for s in r.failed:
            out.append(f"{run}: {s} fails - {r.signals[s]['reason']}{_horizon_words(r.horizons.get(s, []))}")
    return out


def _horizon_words(rows: Sequence[Mapping[str, Any]]) -> str:
    """How far ahead the model still beats persistence, from the horizon table."""
    if not rows:
        return ""
    k = next((i for i, r in enumerate(rows) if not (r["skill_persistence"] or -1.0) > 0), len(rows))
    if k == 0:
        return f"; it loses to persistence already {rows[0]['horizon_s']:g} s ahead"
    if k == len(rows):
        return f"; it beats persistence at each horizon up to {rows[-1]['horizon_s']:g} s, not pooled over windows"
    return f"; it beats persistence up to {rows[k - 1]['horizon_s']:g} s ahead, loses from {rows[k]['horizon_s']:g} s"

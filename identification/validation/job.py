"""One validation job (an FMU against a log, with what shapes the run) and the files it reads: shared by the
single, batch and Monte Carlo runs, so none of them imports another's module."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from identification.validation import output_map
from identification.validation.replay import ValidationOptions


@dataclass(frozen=True)
class ValidationJob:
    """One FMU against one log, with everything that shapes the run."""

    fmu: Path
    log: Path
    options: ValidationOptions = field(default_factory=ValidationOptions)
    output_map: Path | None = None
    mapping: Path | None = None
    channel_map: Path | None = None
    start_values: Mapping[str, float] = field(default_factory=dict)
    max_theil: float | None = None
    report_dir: Path | None = None
    #: with ``report_dir``: also ``report.html`` (plots: about a second a run), else ``metrics.json`` alone
    report_html: bool = True
    #: parameter file of ``identify thrust`` whose battery-state model drives ``battery_voltage_V``
    #: (``identification.validation.replay_battery``; None: the one embedded in the FMU, else the input is logged or
    #: held
    #: at its start value)
    params_file: Path | None = None
    #: without ``params_file``, read the battery-state model from the parameter file embedded in the FMU
    #: (``build --params`` embeds it); False holds the input at its start value unless logged
    embedded_params: bool = True
    #: replay only this span of the log [s, log time] (None: the whole log); e.g. a held-out segment
    t_range_s: tuple[float, float] | None = None



def load_maps(job: ValidationJob, vehicle: str) -> tuple:
    """The job's output map for ``vehicle``, with its Theil limit applied."""
    maps = output_map.load(job.output_map, vehicle)
    if job.max_theil is not None:
        maps = tuple(replace(m, max_theil=float(job.max_theil)) for m in maps)
    return maps


def job_files(job: ValidationJob) -> list[Path]:
    """The files a job reads (shipped to the worker that runs it)."""
    return [p for p in (job.fmu, job.log, job.output_map, job.mapping, job.channel_map, job.params_file)
            if p is not None]

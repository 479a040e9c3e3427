"""The build workflow: a parameter file in, ``quadrotor.fmu`` and ``fixed_wing.fmu`` out, native or pythonfmu.

Both backends are built from the same equations (the models' CasADi functions) and the same parameter
file: ``native`` (default) compiles the generated C with the shared FMI layer (FMI 2.0 or 3.0, Co-Simulation
and/or Model Exchange) for linux64, win64 and darwin64 (no Python needed by the importer), every
(model, platform) compile in parallel with a progress line each; ``python`` packages the pythonfmu slave
(FMI 2.0 Co-Simulation only).
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from fmu_models.common.params import VEHICLES

MODELS = VEHICLES  #: every model the build makes: one per vehicle
BACKENDS = ("native", "python")
Backend = Literal["native", "python"]
HERE = Path(__file__).resolve().parents[1]
#: parallel compiles at most (each zig process is single-threaded)
MAX_JOBS = 8

WARNINGS = {
    "quadrotor": {
        "thrust_map_out_of_range": "a motor's summed-equivalent PWM left the thrust map's trained band; "
        "thrust is extrapolated physically (zero at idle, linear above the band)",
    },
}


@dataclass(frozen=True)
class BuildResult:
    """What ``build_fmus`` made: the FMU paths (in ``MODELS`` order), the backend and the wall time (s)."""

    fmus: tuple[Path, ...]
    backend: str
    seconds: float


@dataclass(frozen=True)
class BuildOptions:
    """Native build choices: FMI version (2 or 3), kinds (``cs``, ``me``), platforms (FMI 2.0 folder names:
    linux64, win64, darwin64), parallel compiles (``jobs``, default the CPU count), a progress callback."""

    fmi_version: int = 2
    kinds: tuple[str, ...] = ("cs", "me")
    platforms: tuple[str, ...] = ("linux64", "win64", "darwin64")
    jobs: int | None = None
    progress: Callable[[str], None] | None = None

    def __post_init__(self) -> None:
        j = self.jobs
        if j is not None and (isinstance(j, bool) or not isinstance(j, int) or not 1 <= j <= MAX_JOBS):
            raise ValueError(f"jobs = {j!r}: parallel compiles must be an integer in 1..{MAX_JOBS} (None: the CPU "
                             "count, at most that)")


def split_params(data: dict[str, Any], source: str = "parameter file") -> dict[str, dict[str, Any]]:
    """Sections per model from a parameter file (:func:`fmu_models.common.params.vehicle_sections`): one section per
    model, a flat set whose keys tell its model, or a bare thrust map (the quadrotor's). ``ParameterError``
    naming ``source`` and the keys when the model cannot be told or keys would be left unused."""
    from fmu_models.common.params import vehicle_sections
    from fmu_models.fixed_wing.params import FLAT_FILE_KEYS as FIXED_WING_KEYS
    from fmu_models.quadrotor.params import FLAT_FILE_KEYS as QUADROTOR_KEYS

    if isinstance(data, dict) and data.get("type") == "anfis" and not any(k in data for k in MODELS):
        return {"quadrotor": {"thrust_map": data}}
    return vehicle_sections(data, {"quadrotor": QUADROTOR_KEYS, "fixed_wing": FIXED_WING_KEYS}, source)


def sections_to_build(data: dict[str, Any], only: Sequence[str], source: str) -> dict[str, dict[str, Any]]:
    """The sections of parameter-file contents ``data`` for the models ``only``: ``ParameterError`` naming
    ``source`` and the file's keys when none of its parameters is for a model being built."""
    from fmu_models.common.errors import ParameterError

    sections = split_params(data, source)
    used = {k: v for k, v in sections.items() if k in only}
    if not used:
        held = "; ".join(f"{name}: {', '.join(sorted(map(str, v))) or 'an empty section'}"
                         for name, v in sections.items())
        raise ParameterError(source, [f"holds parameters of {', '.join(sections)} only ({held}), and the build "
                                      f"makes {', '.join(only)}: build {', '.join(sections)} (--only), or give "
                                      f"a file for {', '.join(only)}"])
    return used


def load_vehicle_params(path: str | Path, vehicle: str) -> Any:
    """The parameters of ``vehicle`` (``QuadrotorParams`` or ``FixedWingParams``) in the parameter file ``path``, read
    as ``build`` reads it (:func:`split_params`): ``ParameterError`` naming the file and its keys when its vehicle
    cannot be told or it holds nothing for ``vehicle``."""
    from fmu_models.common.params import read_json

    if vehicle not in MODELS:
        raise ValueError(f"vehicle = {vehicle!r} is not one of {', '.join(MODELS)}")
    section = sections_to_build(read_json(path), [vehicle], str(path))[vehicle]
    return make_model_params(vehicle, section, str(path))


def make_model_params(name: str, values: dict[str, Any] | None, source: str) -> Any:
    """The parameter dataclass of model ``name`` with ``values`` over its defaults."""
    if name == "quadrotor":
        from fmu_models.quadrotor.params import QuadrotorParams

        return QuadrotorParams.from_dict(values or {}, source=source)
    if name == "fixed_wing":
        from fmu_models.fixed_wing.params import FixedWingParams

        return FixedWingParams.from_dict(values or {}, source=source)
    raise ValueError(f"model = {name!r} is not one of {', '.join(MODELS)}")


def make_model(name: str, values: dict[str, Any] | None, source: str) -> Any:
    """The ``VehicleModel`` of ``name`` with ``values`` over its defaults."""
    params = make_model_params(name, values, source)
    if name == "quadrotor":
        from fmu_models.quadrotor.model import QuadrotorModel

        return QuadrotorModel(params)
    from fmu_models.fixed_wing.model import FixedWingModel

    return FixedWingModel(params)


def _platforms(names: Sequence[str]) -> tuple[Any, ...]:
    from fmu_models.fmi import zigcc

    unknown = [n for n in names if n not in zigcc.BY_NAME]
    if unknown or not names:
        raise ValueError(f"platforms = {list(names)!r}: each must be one of {', '.join(zigcc.BY_NAME)}")
    return tuple(zigcc.BY_NAME[n] for n in dict.fromkeys(names))


def _build_native(models: list[tuple[Any, Path]], out_dir: Path, params_file: Path | None,
                  options: BuildOptions) -> list[Path]:
    """Generate every model's sources, compile all (model, platform) pairs in parallel, write the FMUs."""
    from fmu_models.fmi import fmuzip
    from fmu_models.fmi.native_build import Interface, prepare

    interface = Interface(options.fmi_version, tuple(options.kinds))
    plats = _platforms(options.platforms)
    say = options.progress or (lambda _msg: None)
    jobs = options.jobs or max(1, min(MAX_JOBS, os.cpu_count() or 1))
    with tempfile.TemporaryDirectory(prefix="uavfmu_native_") as tmp:
        built = []
        for model, readme in models:
            t0 = time.perf_counter()
            built.append(prepare(model, Path(tmp) / model.name, warnings=WARNINGS.get(model.name),
                                 documentation=readme, params_file=params_file, interface=interface))
            say(f"generated {model.name} C sources ({time.perf_counter() - t0:.1f} s)")
        total, done = len(built) * len(plats), 0
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(job.compile, plat): (job, plat) for job in built for plat in plats}
            for fut in as_completed(futures):
                job, plat = futures[fut]
                arc, data = fut.result()
                job.files[arc] = data
                done += 1
                say(f"[{done}/{total}] compiled {job.model.name} for {plat.fmi_name}")
        return [fmuzip.write_fmu(Path(out_dir) / f"{job.model.name}.fmu", job.files, job.epoch) for job in built]


def build_fmus(
    params_file: Path | None,
    out_dir: Path,
    only: Sequence[str] | None = None,
    backend: Backend = "native",
    options: BuildOptions | None = None,
) -> BuildResult:
    """Build the FMUs of ``only`` (default: all) into ``out_dir`` with ``backend`` (native: ``options``).

    Raises ``ValueError`` (bad parameters, unknown model, backend, FMI version, kind or platform),
    ``FileNotFoundError`` and ``codegen.CompileError`` (the C compiler failed).
    """
    from fmu_models.common.params import read_json

    options = options or BuildOptions()
    if backend not in BACKENDS:
        raise ValueError(f"backend = {backend!r} is not one of {', '.join(BACKENDS)}")
    if backend == "python" and (options.fmi_version != 2 or "cs" not in options.kinds):
        raise ValueError("the python backend builds FMI 2.0 Co-Simulation only (--fmi 2 --kind cs)")
    t0 = time.perf_counter()
    names = list(only or MODELS)
    unknown = [n for n in names if n not in MODELS]
    if unknown:
        raise ValueError(f"model = {unknown[0]!r} is not one of {', '.join(MODELS)}")
    sections = sections_to_build(read_json(params_file), names, str(params_file)) if params_file else {}
    models = [(make_model(name, sections.get(name), f"{params_file or 'defaults'} [{name}]"),
               HERE / name / "readme.md") for name in names]
    if backend == "native":
        from fmu_models.fmi.native_build import Interface

        Interface(options.fmi_version, tuple(options.kinds))  # refuse a bad choice before any work
        _platforms(options.platforms)
        out = _build_native(models, out_dir, params_file, options)
    else:
        from fmu_models.fmi.build import build_fmu

        out = [build_fmu(model, out_dir, warnings=WARNINGS.get(model.name), documentation=readme,
                         params_file=params_file) for model, readme in models]
    return BuildResult(tuple(out), backend, time.perf_counter() - t0)

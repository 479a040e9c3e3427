"""The build workflow: a parameter file in, ``quadrotor.fmu`` and ``fixed_wing.fmu`` out, native or pythonfmu.

Both backends are built from the same equations (the models' CasADi functions) and the same parameter
file: ``native`` (default) compiles the generated C with the shared FMI layer for linux64, win64 and
darwin64 (no Python needed by the importer); ``python`` packages the pythonfmu slave.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

MODELS = ("quadrotor", "fixed_wing")
BACKENDS = ("native", "python")
Backend = Literal["native", "python"]
HERE = Path(__file__).resolve().parents[1]

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


def split_params(data: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Sections per model from a parameter file; a bare thrust map or flat set goes to the model it fits."""
    if any(k in data for k in MODELS):
        return {k: data[k] for k in MODELS if k in data}
    if "thrust_map" in data or data.get("type") == "anfis":
        return {"quadrotor": data if "thrust_map" in data else {"thrust_map": data}}
    return {"fixed_wing": data}


def make_model(name: str, values: dict[str, Any] | None, source: str) -> Any:
    """The ``VehicleModel`` of ``name`` with ``values`` over its defaults."""
    if name == "quadrotor":
        from fmu_models.quadrotor.model import QuadrotorModel
        from fmu_models.quadrotor.params import QuadrotorParams

        return QuadrotorModel(QuadrotorParams.from_dict(values or {}, source=source))
    if name == "fixed_wing":
        from fmu_models.fixed_wing.model import FixedWingModel
        from fmu_models.fixed_wing.params import FixedWingParams

        return FixedWingModel(FixedWingParams.from_dict(values or {}, source=source))
    raise ValueError(f"model = {name!r} is not one of {', '.join(MODELS)}")


def build_fmus(
    params_file: Path | None,
    out_dir: Path,
    only: Sequence[str] | None = None,
    backend: Backend = "native",
) -> BuildResult:
    """Build the FMUs of ``only`` (default: all) into ``out_dir`` with ``backend``.

    Raises ``ValueError`` (bad parameters, unknown model or backend), ``FileNotFoundError`` and
    ``codegen.CompileError`` (the C compiler failed).
    """
    from fmu_models.common.params import read_json

    if backend not in BACKENDS:
        raise ValueError(f"backend = {backend!r} is not one of {', '.join(BACKENDS)}")
    t0 = time.perf_counter()
    sections = split_params(read_json(params_file)) if params_file else {}
    out = []
    for name in only or MODELS:
        model = make_model(name, sections.get(name), f"{params_file or 'defaults'} [{name}]")
        readme = HERE / name / "readme.md"
        if backend == "native":
            from fmu_models.fmi.native_build import build_native_fmu

            out.append(build_native_fmu(model, out_dir, warnings=WARNINGS.get(name), documentation=readme,
                                        params_file=params_file))
        else:
            from fmu_models.fmi.build import build_fmu

            out.append(build_fmu(model, out_dir, warnings=WARNINGS.get(name), documentation=readme,
                                 params_file=params_file))
    return BuildResult(tuple(out), backend, time.perf_counter() - t0)

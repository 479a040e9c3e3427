"""The main job: parameters in, ``dist/quadrotor.fmu`` and ``dist/fixed_wing.fmu`` out.

``python build_fmus.py [--params FILE.json] [--out DIR] [--only quadrotor|fixed_wing]`` (same as
``uavfmu build``). A parameter file may hold a ``quadrotor`` and/or a ``fixed_wing`` section; missing
sections and keys keep the published defaults (paper 000 Tables 1-3, the Aerosonde set of Beard & McLain).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
MODELS = ("quadrotor", "fixed_wing")


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
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.params import FixedWingParams

    return FixedWingModel(FixedWingParams.from_dict(values or {}, source=source))


WARNINGS = {
    "quadrotor": {
        "thrust_map_out_of_range": "a motor's summed-equivalent PWM left the thrust map's trained band; "
        "thrust is extrapolated physically (zero at idle, linear above the band)",
    },
}


def build(params_file: Path | None, out_dir: Path, only: list[str] | None = None) -> list[Path]:
    """Build the FMUs; return their paths."""
    from fmu_models.common.params import read_json
    from fmu_models.fmi.build import build_fmu

    sections = split_params(read_json(params_file)) if params_file else {}
    out = []
    for name in only or MODELS:
        model = make_model(name, sections.get(name), f"{params_file or 'defaults'} [{name}]")
        readme = HERE / "fmu_models" / name / "readme.md"
        out.append(build_fmu(model, out_dir, warnings=WARNINGS.get(name), documentation=readme))
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", type=Path, help="parameter JSON (e.g. from `uavfmu identify`)")
    parser.add_argument("--out", type=Path, default=Path("dist"), help="output folder (default: dist)")
    parser.add_argument("--only", choices=MODELS, action="append", help="build only this model (repeatable)")


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    t0 = time.perf_counter()
    try:
        paths = build(args.params, args.out, args.only)
    except (ValueError, FileNotFoundError) as err:
        print(f"build_fmus: error: {err}", file=sys.stderr)
        return 2
    for p in paths:
        print(f"built {p} ({p.stat().st_size / 1024:.0f} KiB)")
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="build_fmus.py", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    raise SystemExit(main())

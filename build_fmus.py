"""The main job: parameters in, ``dist/quadrotor.fmu`` and ``dist/fixed_wing.fmu`` out.

``python build_fmus.py [--params FILE.json] [--out DIR] [--only quadrotor|fixed_wing] [--backend native|python]
[--fmi 2|3] [--kind cs|me|both] [--platforms linux64,win64,darwin64] [--jobs N]`` (same as ``uavfmu build``).
A parameter file may hold a ``quadrotor`` and/or a ``fixed_wing`` section, or one vehicle's keys flat at the
top level (the keys tell the vehicle; a file that does not tell it, or has nothing for the models built, is
refused naming its keys); missing sections and keys keep the published defaults (paper 000 Tables 1-3,
the Aerosonde set of Beard & McLain). The workflow is ``fmu_models.fmi.fmus.build_fmus``; the CLI is
``uavfmu/commands/build.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from fmu_models.fmi.fmus import (  # noqa: E402
    MODELS,
    WARNINGS,
    Backend,
    BuildOptions,
    build_fmus,
    make_model,
    split_params,
)

__all__ = ["MODELS", "WARNINGS", "BuildOptions", "build", "main", "make_model", "split_params"]


def build(params_file: Path | None, out_dir: Path, only: list[str] | None = None,
          backend: Backend = "native", options: BuildOptions | None = None) -> list[Path]:
    """Build the FMUs; return their paths (``build_fmus(...).fmus`` as a list)."""
    if backend == "python" and options is None:
        options = BuildOptions(kinds=("cs",))
    return list(build_fmus(params_file, out_dir, only, backend, options).fmus)


def main(argv: list[str] | None = None) -> int:
    import argparse

    from uavfmu.commands import build as command

    parser = argparse.ArgumentParser(prog="build_fmus.py", description=__doc__.splitlines()[0])
    command.add_arguments(parser)
    return command.run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())

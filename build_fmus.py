"""The main job: parameters in, ``dist/quadrotor.fmu`` and ``dist/fixed_wing.fmu`` out.

``python build_fmus.py [--params FILE.json] [--out DIR] [--only quadrotor|fixed_wing] [--backend native|python]``
(same as ``uavfmu build``). A parameter file may hold a ``quadrotor`` and/or a ``fixed_wing`` section;
missing sections and keys keep the published defaults (paper 000 Tables 1-3, the Aerosonde set of Beard &
McLain). The workflow is ``fmu_models.fmi.fmus.build_fmus``; the CLI is ``uavfmu/commands/build.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from fmu_models.fmi.fmus import MODELS, WARNINGS, Backend, build_fmus, make_model, split_params  # noqa: E402

__all__ = ["MODELS", "WARNINGS", "build", "main", "make_model", "split_params"]


def build(params_file: Path | None, out_dir: Path, only: list[str] | None = None,
          backend: Backend = "native") -> list[Path]:
    """Build the FMUs; return their paths (``build_fmus(...).fmus`` as a list)."""
    return list(build_fmus(params_file, out_dir, only, backend).fmus)


def main(argv: list[str] | None = None) -> int:
    import argparse

    from uavfmu.commands import build as command

    parser = argparse.ArgumentParser(prog="build_fmus.py", description=__doc__.splitlines()[0])
    command.add_arguments(parser)
    return command.run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())

"""``uavfmu build``: parameters in, ``dist/quadrotor.fmu`` and ``dist/fixed_wing.fmu`` out.

``uavfmu build [--params FILE.json] [--out DIR] [--only quadrotor|fixed_wing] [--backend native|python]``.
Native FMUs (default) carry C binaries for linux64, win64 and darwin64 and their sources; ``--backend
python`` builds the pythonfmu FMUs. The work is done by ``fmu_models.fmi.fmus.build_fmus``; this module
parses and prints. Exit status: 0 built, 2 bad input or a failed compilation.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from fmu_models.fmi.codegen import CompileError
from fmu_models.fmi.fmus import BACKENDS, MODELS, build_fmus


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", type=Path, help="parameter JSON (e.g. from `uavfmu identify`)")
    parser.add_argument("--out", type=Path, default=Path("dist"), help="output folder (default: dist)")
    parser.add_argument("--only", choices=MODELS, action="append", help="build only this model (repeatable)")
    parser.add_argument("--backend", choices=BACKENDS, default="native",
                        help="native C FMUs for linux64/win64/darwin64 (default) or pythonfmu FMUs")


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        result = build_fmus(args.params, args.out, args.only, args.backend)
    except (ValueError, FileNotFoundError, CompileError) as err:
        print(f"build: error: {err}", file=sys.stderr)
        return 2
    for p in result.fmus:
        print(f"built {p} ({result.backend}, {p.stat().st_size / 1024:.0f} KiB)")
    print(f"done in {result.seconds:.1f} s")
    return 0

"""``uavfmu build``: parameters in, ``dist/quadrotor.fmu`` and ``dist/fixed_wing.fmu`` out.

``uavfmu build [--params FILE.json] [--out DIR] [--only quadrotor|fixed_wing] [--backend native|python]
[--fmi 2|3] [--kind cs|me|both] [--platforms linux64,win64,darwin64] [--jobs N]``.
Native FMUs (default: FMI 2.0 Co-Simulation + Model Exchange in one FMU) carry C binaries for the chosen
platforms (default all three, compiled in parallel, one progress line per compile) and their sources;
``--backend python`` builds the pythonfmu FMUs (FMI 2.0 Co-Simulation). The work is done by
``fmu_models.fmi.fmus.build_fmus``; this module parses and prints. ``--params`` takes a file with a section per
vehicle or one vehicle's keys flat (its keys tell which); a file whose vehicle cannot be told, or with nothing
for the models built, is bad input. Exit status: 0 built, 2 bad input or a failed compilation.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from fmu_models.fmi.codegen import CompileError
from fmu_models.fmi.fmus import BACKENDS, MAX_JOBS, MODELS, BuildOptions, build_fmus

KINDS = {"cs": ("cs",), "me": ("me",), "both": ("cs", "me")}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--params", type=Path, help="parameter JSON (e.g. from `uavfmu identify`)")
    parser.add_argument("--out", type=Path, default=Path("dist"), help="output folder (default: dist)")
    parser.add_argument("--only", choices=MODELS, action="append", help="build only this model (repeatable)")
    parser.add_argument("--backend", choices=BACKENDS, default="native",
                        help="native C FMUs (default) or pythonfmu FMUs (FMI 2.0 Co-Simulation)")
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default 2)")
    parser.add_argument("--kind", choices=tuple(KINDS), default=None,
                        help="Co-Simulation, Model Exchange or both in one FMU (default: both; python: cs)")
    parser.add_argument("--platforms", default="linux64,win64,darwin64",
                        help="comma-separated binary platforms (default: linux64,win64,darwin64)")
    parser.add_argument("--jobs", type=int, default=None,
                        help=f"parallel compiles (default: CPU count, max {MAX_JOBS})")


def options(args: argparse.Namespace) -> BuildOptions:
    """The native build options of parsed arguments."""
    kind = args.kind or ("cs" if args.backend == "python" else "both")
    plats = tuple(p.strip() for p in str(args.platforms).split(",") if p.strip())
    return BuildOptions(fmi_version=args.fmi, kinds=KINDS[kind], platforms=plats, jobs=args.jobs,
                        progress=lambda msg: print(f"build: {msg}", flush=True))


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        result = build_fmus(args.params, args.out, args.only, args.backend, options(args))
    except (ValueError, FileNotFoundError, CompileError) as err:
        print(f"build: error: {err}", file=sys.stderr)
        return 2
    for p in result.fmus:
        print(f"built {p} ({result.backend}, {p.stat().st_size / 1024:.0f} KiB)")
    print(f"done in {result.seconds:.1f} s")
    return 0

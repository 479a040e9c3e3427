"""CasADi functions compiled to C once and cached, for the estimator's inner loops.

CasADi's own ``jit`` option recompiles on every process start; the estimator evaluates the same
sensitivity function for every iteration of every run, so the generated C is compiled once into a
library under the user's cache directory, keyed by the hash of its source, and loaded with
``casadi.external``. Without a C compiler the CasADi virtual machine evaluates the same function.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from pathlib import Path

import casadi as ca

from fmu_models.fmi.codegen import CompileError, compile_library, find_compiler

log = logging.getLogger(__name__)


def cache_dir() -> Path:
    """``$UAVFMU_CACHE`` or ``$XDG_CACHE_HOME/uavfmu`` (default ``~/.cache/uavfmu``)."""
    env = os.environ.get("UAVFMU_CACHE")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "uavfmu"


def compiled(functions: list[ca.Function], tag: str) -> list[ca.Function]:
    """The same functions, compiled (or unchanged when no compiler is available or compiling fails)."""
    compiler = os.environ.get("CC") or find_compiler()
    if compiler is None:
        log.info("no C compiler found: evaluating %s in the CasADi virtual machine", tag)
        return functions
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{tag}.c", {"with_header": False})
        for f in functions:
            gen.add(f)
        gen.generate(tmp + os.sep)
        src = Path(tmp) / f"{tag}.c"
        digest = hashlib.sha256(src.read_bytes()).hexdigest()[:16]
        lib = cache_dir() / f"{tag}_{digest}.so"
        if not lib.exists():
            lib.parent.mkdir(parents=True, exist_ok=True)
            partial = lib.with_suffix(f".{os.getpid()}.tmp")
            log.info("compiling %s (%d kB of C) into %s", tag, src.stat().st_size // 1024, lib)
            try:
                # -O1: these files are large and straight-line; -O2 triples the compile time for ~10 % speed
                compile_library(src, partial, compiler, optimisation="-O1")
            except CompileError as exc:
                log.warning("compiling %s failed, using the CasADi virtual machine: %s", tag, exc)
                return functions
            partial.replace(lib)  # atomic: concurrent runs never load a half-written library
    return [ca.external(f.name(), str(lib)) for f in functions]

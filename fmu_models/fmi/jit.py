"""CasADi functions compiled to C once and cached, for the estimator's inner loops.

CasADi's own ``jit`` option recompiles on every process start; the estimator evaluates the same
sensitivity function for every iteration of every run, so the generated C is compiled once into a
library under the user's cache directory and loaded with ``casadi.external``. The library is keyed by the
functions' own serialization (with CasADi's version, the compiler and its flags): a cached one is loaded
without eliminating common subexpressions or generating C again, which on the estimator's sensitivity
function costs more than building it. Without a C compiler the CasADi virtual machine evaluates the same
function.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from collections.abc import Callable
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


#: what the key hashes besides the functions; change it when the library built from the same functions changes
KEY_FORMAT = "jit-1 -O1"


def jit_context() -> tuple[str | None, str, str]:
    """What decides, besides the functions, what :func:`compiled` returns in this process: the compiler (``$CC``
    or the machine's; None: the virtual machine), the cache folder and :data:`KEY_FORMAT`. A caller keeping
    compiled functions per process keys them by this too."""
    return os.environ.get("CC") or find_compiler(), str(cache_dir()), KEY_FORMAT


def compiled(functions: list[ca.Function], tag: str,
             build: Callable[[], list[ca.Function]] | None = None) -> list[ca.Function]:
    """The same functions, compiled (or unchanged when no compiler is available or compiling fails).
    ``build``: the same functions in the form to generate C from (e.g. with common subexpressions eliminated,
    same names and values), called only when no library of ``functions`` is cached yet; without a compiler its
    functions are returned (the virtual machine evaluates them)."""
    compiler = jit_context()[0]
    if compiler is None:
        log.info("no C compiler found: evaluating %s in the CasADi virtual machine", tag)
        return build() if build is not None else functions
    key = hashlib.sha256()
    for part in (KEY_FORMAT, ca.__version__, compiler, *(f.serialize() for f in functions)):
        key.update(part.encode())
        key.update(b"\0")
    lib = cache_dir() / f"{tag}_{key.hexdigest()[:16]}.so"
    if not lib.exists():
        source = build() if build is not None else functions
        if [f.name() for f in source] != [f.name() for f in functions]:
            raise ValueError(f"compiled {tag}: build gave {[f.name() for f in source]}, "
                             f"not {[f.name() for f in functions]}")
        with tempfile.TemporaryDirectory() as tmp:
            gen = ca.CodeGenerator(f"{tag}.c", {"with_header": False})
            for f in source:
                gen.add(f)
            gen.generate(tmp + os.sep)
            src = Path(tmp) / f"{tag}.c"
            lib.parent.mkdir(parents=True, exist_ok=True)
            partial = lib.with_suffix(f".{os.getpid()}.tmp")
            log.info("compiling %s (%d kB of C) into %s", tag, src.stat().st_size // 1024, lib)
            try:
                # -O1: these files are large and straight-line; -O2 triples the compile time for ~10 % speed
                compile_library(src, partial, compiler, optimisation="-O1")
            except CompileError as exc:
                log.warning("compiling %s failed, using the CasADi virtual machine: %s", tag, exc)
                return source
            partial.replace(lib)  # atomic: concurrent runs never load a half-written library
    return [ca.external(f.name(), str(lib)) for f in functions]

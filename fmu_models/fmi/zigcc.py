"""Cross-compile C into shared libraries for linux64, win64 and darwin64 with zig's ``cc`` (the ``ziglang`` wheel).

zig bundles clang, lld and the C libraries of every target, so one Linux machine builds all three FMI
platforms with nothing but ``pip install ziglang``. Libraries are cached under ``jit.cache_dir()`` by the
hash of their sources, flags and target, so a rebuild of unchanged code costs a file copy.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from fmu_models.fmi.codegen import CompileError
from fmu_models.fmi.jit import cache_dir


@dataclass(frozen=True)
class Platform:
    """One binary platform: FMI 2.0 folder name, zig target triple, library suffix, FMI 3.0 folder name."""

    fmi_name: str
    target: str
    suffix: str
    fmi3_name: str


PLATFORMS: tuple[Platform, ...] = (
    Platform("linux64", "x86_64-linux-gnu.2.17", ".so", "x86_64-linux"),
    Platform("win64", "x86_64-windows-gnu", ".dll", "x86_64-windows"),
    Platform("darwin64", "x86_64-macos", ".dylib", "x86_64-darwin"),
)
BY_NAME = {p.fmi_name: p for p in PLATFORMS}


def host_platform() -> Platform:
    """The platform of this machine (``make demo`` builds only this one)."""
    import platform as _platform

    key = {"linux": "linux64", "win32": "win64", "darwin": "darwin64"}.get(sys.platform)
    if key is None or _platform.machine().lower() not in ("x86_64", "amd64"):
        raise CompileError(f"no native FMU platform for {sys.platform}/{_platform.machine()} "
                           f"(built: {', '.join(BY_NAME)})")
    return BY_NAME[key]

#: flags of every native FMU library: only the fmi2 functions are exported, no build paths leak in
CFLAGS = ("-O2", "-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT=", "-ffp-contract=off", "-fno-fast-math")


def zig_cc() -> list[str]:
    """The command that runs zig's C compiler (``python -m ziglang cc``); raises CompileError without it."""
    try:
        import ziglang  # noqa: F401
    except ImportError as err:
        raise CompileError("the ziglang wheel is not installed (pip install ziglang; `make` installs it)") from err
    return [sys.executable, "-m", "ziglang", "cc"]


def compile_shared(sources: list[Path], include_dirs: list[Path], platform: Platform, out: Path) -> Path:
    """Compile ``sources`` into the shared library ``out`` for ``platform`` (cached by content hash)."""
    flags = [*CFLAGS, "-target", platform.target, "-shared"]
    if platform.fmi_name != "win64":
        flags.append("-fPIC")
    digest = hashlib.sha256()
    for part in [*flags, *(s.name for s in sources)]:
        digest.update(part.encode() + b"\0")
    for src in sources:
        digest.update(src.read_bytes())
    for inc in include_dirs:
        for h in sorted(inc.glob("*.h")):
            digest.update(h.name.encode() + h.read_bytes())
    cached = cache_dir() / "native" / f"{platform.fmi_name}_{digest.hexdigest()[:20]}{platform.suffix}"
    if not cached.exists():
        cached.parent.mkdir(parents=True, exist_ok=True)
        # in a private folder: zig writes an import library and a .pdb beside a DLL; only the library is kept
        with tempfile.TemporaryDirectory(dir=cached.parent, prefix=".build_") as tmp:
            partial = Path(tmp) / f"{platform.fmi_name}{platform.suffix}"
            incs = [f"-I{d}" for d in include_dirs]
            cmd = [*zig_cc(), *flags, *incs, "-o", str(partial), *(str(s) for s in sources)]
            if platform.fmi_name == "linux64":
                cmd.append("-lm")
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False, cwd=tmp)
            if proc.returncode != 0:
                raise CompileError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-4000:]}")
            partial.replace(cached)  # atomic: concurrent builds never see a half-written library
    out.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(cached, out)
    return out

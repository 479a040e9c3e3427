"""Reproducible FMU archives: fixed member order, timestamps and permissions; the build date from
``SOURCE_DATE_EPOCH`` (reproducible-builds.org) or the parameter file; the package version.

Two builds from the same sources and parameters give byte-identical ``.fmu`` files.
"""

from __future__ import annotations

import os
import time
import zipfile
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

#: the earliest time a zip member can carry (1980-01-01 00:00:00 UTC)
ZIP_EPOCH = 315532800


def package_version() -> str:
    """The installed uavfmu version (the FMU's ``version`` attribute)."""
    try:
        return metadata.version("uavfmu")
    except metadata.PackageNotFoundError:
        return "0.0.0+unknown"


def build_epoch(params_file: Path | None = None) -> int:
    """Build time in s since 1970: ``$SOURCE_DATE_EPOCH``, else the parameter file's mtime, else 1980-01-01."""
    env = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if env:
        try:
            return max(ZIP_EPOCH, int(env))
        except ValueError as err:
            raise ValueError(f"SOURCE_DATE_EPOCH = {env!r} is not an integer number of seconds") from err
    if params_file is not None and Path(params_file).exists():
        return max(ZIP_EPOCH, int(Path(params_file).stat().st_mtime))
    return ZIP_EPOCH


def iso_date(epoch: int) -> str:
    """``generationDateAndTime`` of ``epoch`` (xs:dateTime, UTC)."""
    return datetime.fromtimestamp(epoch, UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def write_fmu(path: Path, files: dict[str, bytes], epoch: int) -> Path:
    """Write ``files`` (archive name -> bytes) to ``path`` sorted by name with one fixed timestamp."""
    stamp = time.gmtime(max(ZIP_EPOCH, epoch))[:6]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.{os.getpid()}.part")
    with zipfile.ZipFile(partial, "w") as z:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, date_time=stamp)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.create_system = 3
            info.external_attr = 0o644 << 16
            z.writestr(info, files[name], compresslevel=9)
    partial.replace(path)
    return path

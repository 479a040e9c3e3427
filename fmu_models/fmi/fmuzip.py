"""Reproducible FMU archives: fixed member order, timestamps and permissions; the build date from
``SOURCE_DATE_EPOCH`` (reproducible-builds.org) or the parameter file; the package version.

Two builds from the same sources and parameters give byte-identical ``.fmu`` files.
"""

from __future__ import annotations

import json
import os
import time
import zipfile
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

#: the earliest time a zip member can carry (1980-01-01 00:00:00 UTC)
ZIP_EPOCH = 315532800
#: the parameter file an FMU was built from (``build --params``), carried in its resources (JSON verbatim, TOML as JSON)
EMBEDDED_PARAMS = "resources/uavfmu_parameters.json"
#: largest parameter file embedded or read back [bytes] (identified files are a few kB)
MAX_EMBEDDED_BYTES = 4 * 1024 * 1024


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


def embedded_params_bytes(params_file: Path) -> bytes:
    """The bytes to embed as :data:`EMBEDDED_PARAMS`: a JSON file verbatim, a TOML file as the JSON of what the
    build read from it (the member is JSON either way); ValueError naming the file when too large."""
    from fmu_models.config import read_config_file

    size = Path(params_file).stat().st_size
    if size > MAX_EMBEDDED_BYTES:
        raise ValueError(f"{params_file}: {size} bytes; a parameter file embedded in an FMU may have at most "
                         f"{MAX_EMBEDDED_BYTES} bytes")
    if Path(params_file).suffix.lower() != ".toml":
        return Path(params_file).read_bytes()
    data = json.dumps(read_config_file(params_file), indent=1, default=str).encode("utf-8")
    if len(data) > MAX_EMBEDDED_BYTES:
        raise ValueError(f"{params_file}: {len(data)} bytes as JSON; allowed at most {MAX_EMBEDDED_BYTES}")
    return data


def read_embedded_params(fmu: Path) -> bytes | None:
    """The parameter file embedded in ``fmu`` (:data:`EMBEDDED_PARAMS`), or None when it has none.

    ValueError naming the FMU when the archive cannot be read or the member is larger than
    :data:`MAX_EMBEDDED_BYTES`."""
    try:
        with zipfile.ZipFile(fmu) as z:
            try:
                info = z.getinfo(EMBEDDED_PARAMS)
            except KeyError:
                return None
            if info.file_size > MAX_EMBEDDED_BYTES:
                raise ValueError(f"{fmu}: {EMBEDDED_PARAMS} has {info.file_size} bytes; allowed at most "
                                 f"{MAX_EMBEDDED_BYTES}")
            return z.read(info)
    except (OSError, zipfile.BadZipFile) as err:
        raise ValueError(f"{fmu}: cannot read the FMU archive ({err})") from None


def embedded_params(fmu: Path) -> tuple[dict, str] | None:
    """The parsed parameter file embedded in ``fmu`` and the name to cite it by (``FMU (member)``), or None when
    the FMU carries none. :class:`ParameterError` naming the FMU and member when it cannot be read or parsed."""
    from fmu_models.common.errors import ParameterError
    from fmu_models.config import ConfigError, parse_config_text

    source = f"{fmu} ({EMBEDDED_PARAMS})"
    try:
        raw = read_embedded_params(Path(fmu))
    except ValueError as err:
        raise ParameterError(source, [str(err)]) from None
    if raw is None:
        return None
    try:
        return parse_config_text(raw.decode("utf-8"), source), source  # the parser of every parameter file
    except UnicodeDecodeError as err:
        raise ParameterError(source, [f"not a JSON parameter file: {err}"]) from None
    except ConfigError as err:
        raise ParameterError(source, [f"not a JSON parameter file: {'; '.join(err.problems)}"]) from None


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

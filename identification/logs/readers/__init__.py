"""Flight-log readers: ``read_log(path)`` picks the reader by the file's suffix."""

from __future__ import annotations

from pathlib import Path

from identification.logs.flightlog import FlightLog, LogError


def read_log(path: str | Path, *, channel_map: dict | str | Path | None = None, fmt: str | None = None) -> FlightLog:
    """Read a flight log into a :class:`FlightLog`.

    ArduPilot DataFlash ``.bin``/``.log``, PX4 ``.ulg``, CSV (``channel_map`` renames columns to canonical
    names). For DataFlash, ``channel_map`` maps canonical names to output channels (``{"motor_1_pwm_us": 3}``)
    and overrides the log's SERVOn_FUNCTION mapping.
    """
    from identification.logs.channel_map import load_channel_map, validate_channel_map

    if isinstance(channel_map, str | Path):
        channel_map = load_channel_map(channel_map)
    elif channel_map is not None:
        channel_map = validate_channel_map(channel_map, "channel_map argument")
    p = Path(path)
    if not p.exists():
        raise LogError(f"{p}: no such file")
    if p.is_dir() or fmt == "px4_csv":
        from identification.logs.readers.px4_csv import read_px4_csv

        return read_px4_csv(p)
    if p.stat().st_size == 0:
        raise LogError(f"{p}: the file is empty")
    kind = fmt or p.suffix.lower().lstrip(".")
    if kind in ("bin", "log", "dataflash"):
        from identification.logs.readers.dataflash import read_dataflash

        columns = sorted(k for k, v in (channel_map or {}).items() if isinstance(v, str))
        if columns:
            raise LogError(f"{p}: channel map entries {', '.join(columns)} name CSV columns; a DataFlash log needs "
                           "output channel numbers 1..32")
        return read_dataflash(p, channel_map=channel_map)  # type: ignore[arg-type]
    if kind in ("ulg", "ulog"):
        from identification.logs.readers.ulog import read_ulog

        return read_ulog(p)
    if kind == "tlog":
        from identification.logs.readers.tlog import read_tlog

        return read_tlog(p)
    if kind == "csv":
        from identification.logs.readers.csv_log import read_csv

        return read_csv(p, column_map=channel_map)
    raise LogError(
        f"{p}: unsupported log format {kind!r}; supported: .bin, .log (ArduPilot DataFlash), .ulg, .tlog, .csv"
    )

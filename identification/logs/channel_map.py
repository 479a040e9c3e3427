"""Channel-map config files (TOML or JSON) that override the vehicle mapping found in a log.

``[channels]`` maps canonical names to output channels (DataFlash, 1-based) or columns (CSV)::

    [channels]
    motor_1_pwm_us = 3
    motor_2_pwm_us = 4

A file may also hold the bare table (no ``[channels]`` header). Validated by the :class:`ChannelMapFile`
schema (fmu_models.config): every problem is named with file, field, value and allowed range.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from pydantic import PlainValidator, StringConstraints
from pydantic_core import PydanticCustomError

from fmu_models.config import ConfigError, Schema, read_config_file, validate_config
from identification.logs.flightlog import LogError

MAX_CHANNEL = 32  #: ArduPilot SERVO1..SERVO32


class ChannelMapError(ConfigError, LogError):
    """A channel map that is not valid (a ConfigError, and a LogError for the log-reading callers)."""


def _channel(value: Any) -> int | str:
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise PydanticCustomError("channel_type", f"expected an output channel 1..{MAX_CHANNEL} or a CSV column name "
                                  f"(allowed: an integer 1..{MAX_CHANNEL} or a string)")
    if isinstance(value, int) and not 1 <= value <= MAX_CHANNEL:
        raise PydanticCustomError("channel_range", f"output channel out of range (allowed: 1..{MAX_CHANNEL})")
    if isinstance(value, str) and not value.strip():
        raise PydanticCustomError("channel_empty", "empty column name (allowed: a CSV column name)")
    return value


Channel = Annotated[int | str, PlainValidator(_channel)]
SignalName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z_][A-Za-z0-9_.\[\]]{0,63}$")]


class ChannelMapFile(Schema):
    """``channels``: canonical signal name -> output channel (1..32) or CSV column name."""

    channels: dict[SignalName, Channel]


def validate_channel_map(data: Any, source: str) -> dict[str, int | str]:
    """Check a decoded channel map (``{"channels": {...}}`` or the bare table)."""
    if isinstance(data, dict) and "channels" not in data:
        data = {"channels": data}
    try:
        return dict(validate_config(data, ChannelMapFile, source).channels)
    except ConfigError as err:
        raise ChannelMapError(err.source, err.problems) from None


def load_channel_map(path: str | Path) -> dict[str, int | str]:
    """Read and check a channel map; errors name the file, the key and the bad value."""
    try:
        data = read_config_file(path)
    except ConfigError as err:
        raise ChannelMapError(err.source, err.problems) from None
    return validate_channel_map(data, str(path))

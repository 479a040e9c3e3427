"""Channel-map config files (TOML or JSON) that override the vehicle mapping found in a log.

``[channels]`` maps canonical names to output channels (DataFlash, 1-based) or columns (CSV)::

    [channels]
    motor_1_pwm_us = 3
    motor_2_pwm_us = 4
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from identification.flightlog import LogError


def load_channel_map(path: str | Path) -> dict[str, int | str]:
    """Read and check a channel map; errors name the file, the key and the bad value."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text()) if p.suffix.lower() == ".toml" else json.loads(p.read_text())
    except (OSError, tomllib.TOMLDecodeError, json.JSONDecodeError) as err:
        raise LogError(f"{p}: cannot read channel map ({err})") from err
    channels = data.get("channels", data)
    if not isinstance(channels, dict):
        raise LogError(f"{p}: expected a [channels] table of name = channel")
    for k, v in channels.items():
        if isinstance(v, bool) or not isinstance(v, int | str) or (isinstance(v, int) and not 1 <= v <= 32):
            raise LogError(f"{p}: channels.{k} = {v!r}; expected an output channel 1..32 or a CSV column name")
    return dict(channels)

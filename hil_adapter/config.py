"""The bench config of ``uavfmu hil`` (TOML, every section optional), as typed pydantic schemas.

Declared with the project's one config mechanism (``fmu_models.config``: unknown keys, booleans or strings
for numbers, NaN/inf are errors). Every value that sizes memory or time (rates, timeouts, busy poll, channel
and start-value counts) is bounded here, before anything is allocated. ``[sensors]`` and ``[mapping]`` are
checked by their own modules (``hil_adapter.sensors.SensorConfig``, ``fmu_models.signals.pwm_mapping``) and
their problems reported the same way: one line per problem with file, field, value and allowed range.

::

    [network]    host = "127.0.0.1"   port = 4560       # PX4 TCP / JSON UDP; 127.0.0.1 unless told otherwise
    [timing]     mode = "lockstep"    rate_hz = 250     # PX4: lockstep or realtime; MAVLink/NMEA: realtime
                 speed = 1.0                             # lockstep: sim seconds per wall second, or "max"
                 busy_poll_us = 500                      # lockstep: poll this long before a blocking receive
    [watchdog]   timeout_s = 0.5      mode = "throttle_off"   # or "hold"
    [record]     path = "hil_log.csv"                    # every step in and out, readable by our readers
                 band = false  band_params = "params.json"  # each output's prediction band (record_band)
    [mavlink]    url = "udpin:127.0.0.1:14560"  baud = 57600
    [nmea]       port = "/dev/ttyUSB0"  baud = 38400  rate_hz = 5     # GPS sentences beside any interface
    [px4]        rc_channels = [1500, 1500, 1000, 1500]  # RC_CHANNELS sent with each heartbeat (PWM)
                 wing_controls = {"1" = 0, "2" = 1, "3" = 3, "4" = 2}  # fixed wing: output channel -> control
    [start]      init_pos_down_m = 0.0                    # FMU start values
    [sensors]    seed = 7  profile = "px4_gazebo"  [sensors.gps] ...   # hil_adapter.sensors (PROFILES);
                                                         # no seed: a fresh one per run, printed in the summary
    [mapping.channels.aileron_rad] source = 1 ...                    # fmu_models.signals.pwm_mapping
"""

from __future__ import annotations

import secrets
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, StringConstraints

from fmu_models.config import ConfigError, FiniteFloat, Schema, read_config_file, validate_config

__all__ = ["DEFAULT_PORTS", "INTERFACES", "ConfigError", "HilConfig", "load_hil_config", "sensor_suite"]

INTERFACES = ("px4", "ardupilot-json", "mavlink", "nmea")
DEFAULT_PORTS = {"px4": 4560, "ardupilot-json": 9002}
Text = Annotated[str, StringConstraints(min_length=1, max_length=256)]
Port = Annotated[int, Field(ge=0, le=65535)]
OutputChannel = Annotated[str, StringConstraints(pattern=r"^([1-9]|1[0-6])$")]  #: TOML keys are strings
ControlIndex = Annotated[int, Field(ge=0, le=15)]
#: allowed lockstep speed factors (simulation seconds per wall second); "max" runs unpaced
SPEED_RANGE = (0.01, 1000.0)
#: lockstep speed factor: simulation seconds per wall second, or "max" (unpaced)
Speed = Annotated[float, Field(ge=SPEED_RANGE[0], le=SPEED_RANGE[1], allow_inf_nan=False)] | Literal["max"]
#: a fresh sensor seed is drawn below this (short enough to type back with --seed)
FRESH_SEED_BOUND = 2**32


class NetworkSection(Schema):
    host: Text = "127.0.0.1"
    port: Port | None = None


class TimingSection(Schema):
    mode: Literal["lockstep", "realtime"] = "lockstep"
    rate_hz: float = Field(250.0, ge=1.0, le=10000.0, allow_inf_nan=False)
    #: lockstep interfaces (PX4 lockstep, ArduPilot JSON): simulation seconds per wall second, "max" unpaced
    speed: Speed = 1.0
    #: busy poll before a blocking receive [us]; 0 turns it off
    busy_poll_us: float = Field(500.0, ge=0.0, le=100_000.0, allow_inf_nan=False)


class WatchdogSection(Schema):
    timeout_s: float = Field(0.5, gt=0.0, le=60.0, allow_inf_nan=False)
    mode: Literal["throttle_off", "hold"] = "throttle_off"


class RecordSection(Schema):
    path: Text
    #: also write each output's 5-95 % prediction band (``hil_adapter.record_band``)
    band: bool = False
    #: parameter file whose ``discrepancy`` block gives the band (default: the one embedded in the FMU)
    band_params: Text | None = None


class MavlinkSection(Schema):
    url: Text = "udpin:127.0.0.1:14560"
    baud: int = Field(57600, ge=300, le=4_000_000)


class NmeaSection(Schema):
    port: Text
    baud: int = Field(38400, ge=300, le=4_000_000)
    rate_hz: float = Field(5.0, ge=0.1, le=50.0, allow_inf_nan=False)


class Px4Section(Schema):
    #: RC_CHANNELS PWM [us] sent with each heartbeat (MAVLink holds 18 channels)
    rc_channels: list[Annotated[int, Field(ge=800, le=2200)]] | None = Field(None, min_length=1, max_length=18)
    #: fixed wing: output channel ("1".."16") -> PX4 control index (0..15)
    wing_controls: dict[OutputChannel, ControlIndex] | None = Field(None, min_length=1, max_length=16)


class HilConfig(Schema):
    """The whole bench config; ``sensors`` and ``mapping`` stay tables, checked by their own modules."""

    network: NetworkSection = NetworkSection()
    timing: TimingSection = TimingSection()
    watchdog: WatchdogSection = WatchdogSection()
    record: RecordSection | None = None
    mavlink: MavlinkSection = MavlinkSection()
    nmea: NmeaSection | None = None
    px4: Px4Section = Px4Section()
    #: FMU start values by variable name
    start: dict[Annotated[str, StringConstraints(max_length=64)], FiniteFloat] = Field(default_factory=dict,
                                                                                        max_length=64)
    sensors: dict[str, Any] | None = None
    mapping: dict[str, Any] | None = None

    @property
    def speed(self) -> float | None:
        """``[timing] speed`` as a factor, None for "max" (unpaced)."""
        return None if self.timing.speed == "max" else float(self.timing.speed)

    @property
    def wing_controls(self) -> dict[int, int] | None:
        """``[px4] wing_controls`` as output channel -> control index."""
        wc = self.px4.wing_controls
        return {int(k): v for k, v in wc.items()} if wc else None


def load_hil_config(path: str | Path | None) -> HilConfig:
    """The bench config at ``path`` (defaults for None), its ``[sensors]`` and ``[mapping]`` checked too;
    :class:`ConfigError` lists every problem (file, field, value, allowed range), never a traceback."""
    if path is None:
        return HilConfig()
    data = read_config_file(path)
    cfg = validate_config(data, HilConfig, str(path))
    problems: list[str] = []
    if cfg.sensors is not None:
        try:
            sensor_suite(cfg)
        except (ValueError, TypeError) as err:
            problems += _lines("[sensors]", err)
    if cfg.mapping is not None:
        from fmu_models.signals.pwm_mapping import PwmMapping

        try:
            PwmMapping.from_dict(cfg.mapping, "[mapping]")
        except (ValueError, TypeError, AttributeError) as err:
            problems += _lines("[mapping]", err)
    if problems:
        raise ConfigError(str(path), problems)
    return cfg


def _lines(section: str, err: Exception) -> list[str]:
    """One line per problem of a section checked by its own module (a ``ConfigError`` already has them)."""
    if isinstance(err, ConfigError):
        return [f"{section} {p}" for p in err.problems]
    return [f"{section} " + " ".join(str(err).split())]


def sensor_suite(cfg: HilConfig, seed: int | None = None) -> Any:
    """The seeded ``SensorSuite`` of ``[sensors]`` (``seed`` beside the per-sensor tables). ``seed`` (``--seed``)
    overrides the table's; with neither, a fresh seed is drawn (``suite.seed`` says which, for the summary), so
    runs differ unless asked to repeat."""
    from hil_adapter.sensors import SensorConfig, SensorSuite

    table = dict(cfg.sensors or {})
    table_seed = table.pop("seed", None)
    seed = seed if seed is not None else table_seed
    if seed is None:
        seed = secrets.randbelow(FRESH_SEED_BOUND)
    profile = table.pop("profile", "px4_gazebo")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        source = "sensors.seed" if table_seed is seed else "seed"
        raise ValueError(f"{source} = {seed!r}: needs an integer; allowed 0..2^63-1")
    if not isinstance(profile, str):
        raise ValueError(f"sensors.profile = {profile!r}: needs a string")
    return SensorSuite(SensorConfig.from_dict(table, "sensors", profile=profile), seed=seed)

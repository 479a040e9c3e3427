"""Sensor models for the HIL adapter: IMU, magnetometer, barometer, pitot and GPS from FMU outputs.

Pure Python/numpy, no I/O. Every random number comes from ``numpy.random.Generator`` streams derived from
one seed (one independent stream per sensor, so changing e.g. the GPS settings does not change the IMU
noise); ``SensorSuite.reset()`` restarts them and a rerun repeats exactly.

Each sensor reads ``truth + bias + drift + noise``: ``bias`` is constant, ``drift`` a random walk whose
increment over ``dt`` seconds has the std ``drift_std * sqrt(dt)`` (so it grows like ``sqrt(t)``), and
``noise`` is white with the std ``noise_std`` per sample (a per-sample std, not a density: it does not
change with the sample rate). A configuration with every std and bias 0 reproduces the FMU outputs exactly.

Frames and conventions follow the FMUs: body FRD, NED world, ``quat_w/x/y/z`` rotates body vectors into NED,
the accelerometer reads specific force (``-9.80665`` on z at rest, level). Configurations are pydantic schemas
(``fmu_models.config``); ``SensorConfig.from_dict(data, source)`` checks a dict (a TOML table) and lists every
problem with field, value and allowed range.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, NamedTuple

import numpy as np
from pydantic import BeforeValidator, Field

# Both helpers are written once for CasADi but take and return plain floats for float arguments, which is
# all we use here (checked: ``isa(1000.0)`` and ``radii_of_curvature(0.8)`` return Python floats).
from fmu_models.common.atmosphere import EXPONENT, LAPSE_K_M, P0_PA, T0_K, isa
from fmu_models.common.wgs84 import radii_of_curvature
from fmu_models.config import ConfigError, Schema, validate_config

KELVIN_OFFSET = 273.15  #: 0 degC in K
#: FMU outputs every sample needs; ``airspeed_m_s`` (fixed wing only) is optional
REQUIRED_OUTPUTS = (
    "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2",
    "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
    "quat_w", "quat_x", "quat_y", "quat_z",
    "lat_deg", "lon_deg", "height_m",
    "vel_north_m_s", "vel_east_m_s", "vel_down_m_s",
)
AIRSPEED_OUTPUT = "airspeed_m_s"
_TIME_EPS_S = 1e-9  #: float slack when comparing sample times with the GPS schedule


class SensorConfigError(ConfigError):
    """An invalid sensor configuration: one line per problem naming the field, the value and the allowed range
    (``fmu_models.config.ConfigError``, prefixed by the source)."""


class MissingOutputError(KeyError):
    """A required FMU output is not in the outputs given to ``SensorSuite.sample``; the message names it."""

    def __str__(self) -> str:  # KeyError would print the repr of the message, quotes and all
        return str(self.args[0]) if self.args else ""


# ------------------------------------------------------------------------------------------ configuration
def _three(value: Any) -> Any:
    """A bias given as one number for all axes, or a list (TOML) of three, as a 3-tuple; anything else is left
    for the schema to reject."""
    if isinstance(value, list):
        return tuple(value)
    if isinstance(value, int | float) and not isinstance(value, bool):
        return (value, value, value)
    return value


def _num(lo: float, hi: float, default: float) -> Any:
    return Field(default, ge=lo, le=hi, allow_inf_nan=False)


def _vec3(lo: float, hi: float) -> Any:
    """A per-axis bound vector [lo, hi] (a number means the same on all three axes)."""
    axis = Annotated[float, Field(ge=lo, le=hi, allow_inf_nan=False)]
    return Annotated[tuple[axis, axis, axis], BeforeValidator(_three)]


def _validated(cls: type[Schema], data: Mapping[str, Any], source: str) -> Any:
    """``cls`` checked from ``data``; ``SensorConfigError`` lists every problem, prefixed by ``source``."""
    try:
        return validate_config(data, cls, source)
    except ConfigError as err:
        raise SensorConfigError(err.source, err.problems) from None


class _Section(Schema):
    """One sensor's settings (a pydantic schema of the project's one config mechanism)."""

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "sensor config") -> Any:
        """This section from its table (``[accel]`` ...); missing keys keep their defaults."""
        return _validated(cls, data, source)

    def replace(self, **changes: Any) -> Any:
        """A validated copy with ``changes``."""
        return type(self).model_validate({**self.model_dump(), **changes})


class AccelConfig(_Section):
    """Accelerometer [m/s^2]; drift_std in m/s^2 per sqrt(s)."""

    noise_std: float = _num(0.0, 10.0, 0.02)
    bias: _vec3(-10.0, 10.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _num(0.0, 1.0, 0.0006)


class GyroConfig(_Section):
    """Gyroscope [rad/s]; drift_std in rad/s per sqrt(s)."""

    noise_std: float = _num(0.0, 1.0, 0.003)
    bias: _vec3(-1.0, 1.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _num(0.0, 0.1, 4e-5)


class MagConfig(_Section):
    """Magnetometer [gauss] and the Earth field it measures: total intensity [gauss] (the Earth's is 0.22..0.67),
    declination (east of true north, positive) and inclination (below the horizon, positive) [deg]; constant
    over the flight."""

    noise_std: float = _num(0.0, 1.0, 0.005)
    bias: _vec3(-2.0, 2.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _num(0.0, 0.1, 0.0)
    intensity_gauss: float = _num(0.1, 1.0, 0.5)
    declination_deg: float = _num(-180.0, 180.0, 0.0)
    inclination_deg: float = _num(-90.0, 90.0, 60.0)

    def field_ned_gauss(self) -> np.ndarray:
        """The Earth field in NED [gauss]."""
        inc, dec = math.radians(self.inclination_deg), math.radians(self.declination_deg)
        horizontal = self.intensity_gauss * math.cos(inc)
        return np.array([horizontal * math.cos(dec), horizontal * math.sin(dec),
                         self.intensity_gauss * math.sin(inc)])


class BaroConfig(_Section):
    """Barometer static pressure [Pa]; drift_std in Pa per sqrt(s). The temperature is the noise-free ISA one."""

    noise_std: float = _num(0.0, 1000.0, 2.0)
    bias: float = _num(-5000.0, 5000.0, 0.0)
    drift_std: float = _num(0.0, 100.0, 0.1)


class DiffPressureConfig(_Section):
    """Pitot differential pressure [Pa]; drift_std in Pa per sqrt(s). Used only when the FMU has airspeed."""

    noise_std: float = _num(0.0, 100.0, 0.5)
    bias: float = _num(-100.0, 100.0, 0.0)
    drift_std: float = _num(0.0, 10.0, 0.0)


class GpsConfig(_Section):
    """GPS receiver: fix rate [Hz], latency [s] (a fix delivered at t describes the state at t - latency),
    the reported accuracies eph/epv [m], fix type (MAVLink GPS_FIX_TYPE: 3 = 3D), satellites.

    Position error = a first-order Gauss-Markov process per axis (what receivers show: errors that wander
    slowly, from atmosphere and multipath) plus white noise: ``e(t+dt) = exp(-dt/tau) e(t) + std *
    sqrt(1 - exp(-2 dt/tau)) n``, stationary std ``pos_gm_std_h_m`` (north and east) / ``pos_gm_std_v_m``
    (down) [m], time constant ``pos_gm_tau_s`` [s], started in its stationary distribution. The defaults
    follow PX4's Gazebo GPS plugin: correlation time 60 s; its random walk of 2 (horizontal) and 4 (vertical)
    (m/s)/sqrt(Hz) at 5 Hz settles to a std of about 1 m and 2 m; its white noise (2e-4 m/sqrt(Hz)) is
    negligible. White position noise (``pos_noise_std_*``) trips PX4's preflight drift check, so it is 0 by
    default. NED velocity: white noise std [m/s]."""

    rate_hz: float = _num(0.1, 100.0, 5.0)
    latency_s: float = _num(0.0, 1.0, 0.1)
    eph_m: float = _num(0.0, 600.0, 1.0)
    epv_m: float = _num(0.0, 600.0, 2.0)
    fix_type: int = Field(3, ge=0, le=8)
    satellites: int = Field(10, ge=0, le=255)
    pos_gm_std_h_m: float = _num(0.0, 100.0, 1.0)
    pos_gm_std_v_m: float = _num(0.0, 100.0, 2.0)
    pos_gm_tau_s: float = _num(0.1, 3600.0, 60.0)
    pos_noise_std_h_m: float = _num(0.0, 100.0, 0.0)
    pos_noise_std_v_m: float = _num(0.0, 100.0, 0.0)
    vel_noise_std_m_s: float = _num(0.0, 10.0, 0.05)


class SensorConfig(Schema):
    """All sensors; the defaults are plausible small-MEMS/u-blox values. TOML layout: one table per sensor,
    ``[accel] [gyro] [mag] [baro] [diff_pressure] [gps]``, each optional, missing keys keep their defaults."""

    accel: AccelConfig = AccelConfig()
    gyro: GyroConfig = GyroConfig()
    mag: MagConfig = MagConfig()
    baro: BaroConfig = BaroConfig()
    diff_pressure: DiffPressureConfig = DiffPressureConfig()
    gps: GpsConfig = GpsConfig()

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "sensor config") -> SensorConfig:
        """Check every field of every table; ``SensorConfigError`` lists all problems, prefixed by ``source``."""
        return _validated(cls, data, source)

    def replace(self, **sections: Any) -> SensorConfig:
        """A copy with whole sections replaced."""
        return type(self).model_validate({**{k: getattr(self, k) for k in type(self).model_fields}, **sections})

    @classmethod
    def noise_free(cls) -> SensorConfig:
        """Every noise, bias and drift 0 (GPS rate, latency and the Earth field keep their defaults)."""
        zero = {"noise_std": 0.0, "bias": 0.0, "drift_std": 0.0}
        d = cls()
        return cls(accel=d.accel.replace(**zero), gyro=d.gyro.replace(**zero), mag=d.mag.replace(**zero),
                   baro=d.baro.replace(**zero), diff_pressure=d.diff_pressure.replace(**zero),
                   gps=d.gps.replace(pos_noise_std_h_m=0.0, pos_noise_std_v_m=0.0, vel_noise_std_m_s=0.0,
                                     pos_gm_std_h_m=0.0, pos_gm_std_v_m=0.0))


# ------------------------------------------------------------------------------------------ frames
@dataclass(frozen=True)
class GpsFix:
    """One GPS solution. ``time_s`` is the time the fix describes (delivery time minus the latency, no
    earlier than the first sample); ``alt_msl_m`` is the FMU's ellipsoidal height (see ``SensorSuite``)."""

    time_s: float
    lat_deg: float
    lon_deg: float
    alt_msl_m: float
    vel_ned_m_s: tuple[float, float, float]
    ground_speed_m_s: float
    course_deg: float
    eph_m: float
    epv_m: float
    fix_type: int
    satellites: int


class SensorFrame(NamedTuple):
    """All sensor readings of one sample; ``gps`` is None unless a new fix is due at this sample (a named
    tuple: built once per lockstep step, it costs a third of a frozen dataclass)."""

    accel_body_m_s2: tuple[float, float, float]
    gyro_body_rad_s: tuple[float, float, float]
    mag_body_gauss: tuple[float, float, float]
    abs_pressure_pa: float
    temperature_degc: float
    diff_pressure_pa: float
    pressure_alt_m: float
    gps: GpsFix | None


class _GpsState(NamedTuple):
    t_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    vel_ned_m_s: tuple[float, float, float]


# ------------------------------------------------------------------------------------------ physics helpers
def _ned_to_body(q: tuple[float, float, float, float], v: list[float]) -> tuple[float, float, float]:
    """``R_b2nᵀ v`` for the (normalised) quaternion ``q`` in plain floats: the per-sample path of ``sample``."""
    w, x, y, z = q
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not norm > 0.0:
        raise ValueError(f"attitude quaternion {q} has no direction")
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    r00, r01, r02 = w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)
    r10, r11, r12 = 2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)
    r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z
    return (r00 * v[0] + r10 * v[1] + r20 * v[2], r01 * v[0] + r11 * v[1] + r21 * v[2],
            r02 * v[0] + r12 * v[1] + r22 * v[2])


def pressure_altitude_m(pressure_pa: float) -> float:
    """ISA troposphere altitude [m] of a static pressure: the inverse of ``atmosphere.isa``'s pressure
    (written here because the atmosphere module only goes from altitude to pressure)."""
    return T0_K / LAPSE_K_M * (1.0 - (pressure_pa / P0_PA) ** (1.0 / EXPONENT))


def _wrap_deg(angle_deg: float) -> float:
    return (angle_deg + 180.0) % 360.0 - 180.0


# ------------------------------------------------------------------------------------------ the suite
_BLOCK = 6 * 256  #: normal draws fetched per numpy call and stream


class SensorSuite:
    """Sensor readings from FMU outputs: ``sample(t_s, outputs) -> SensorFrame``, seeded and repeatable.

    Call ``sample`` with increasing ``t_s`` (the drift random walks integrate over the time steps). If
    ``t_s`` goes backwards the simulation restarted: the GPS history and schedule start afresh (the noise
    streams go on; ``reset()`` restarts them too).

    Barometer: ISA static pressure and temperature at ``height_m``. The FMUs give WGS-84 ellipsoidal height;
    we treat it as height above mean sea level (the geoid undulation, up to about +-100 m, is ignored), so
    ``pressure_alt_m`` and the GPS ``alt_msl_m`` are ellipsoidal heights too. The ISA model is the
    troposphere, valid up to 11 km. Pitot: ``0.5 * rho * airspeed^2`` with the ISA density at that height
    (``airspeed_m_s`` taken as true airspeed); exactly 0 when the FMU has no airspeed (no pitot).
    """

    _STREAMS = ("accel", "gyro", "mag", "baro", "diff_pressure", "gps")

    def __init__(self, config: SensorConfig | None = None, seed: int = 0) -> None:
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        self.config = config if config is not None else SensorConfig()
        self.seed = int(seed)
        self._mag_ned = self.config.mag.field_ned_gauss()
        self._mag_ned_list = [float(v) for v in self._mag_ned]
        self.reset()

    def reset(self) -> None:
        """Back to the state right after construction: same seed, zero drift, empty GPS history."""
        children = np.random.SeedSequence(self.seed).spawn(len(self._STREAMS))
        self._rng = {name: np.random.default_rng(s) for name, s in zip(self._STREAMS, children, strict=True)}
        #: per stream: the block drawn ahead and the position of the next draw in it
        self._buffers: dict[str, list[Any]] = {name: [[], 0] for name in self._STREAMS}
        self._drift: dict[str, Any] = {"accel": [0.0, 0.0, 0.0], "gyro": [0.0, 0.0, 0.0], "mag": [0.0, 0.0, 0.0],
                                       "baro": 0.0, "diff_pressure": 0.0}
        self._bias3 = {name: [float(v) for v in np.broadcast_to(getattr(self.config, name).bias, 3)]
                       for name in ("accel", "gyro", "mag")}
        gps = self.config.gps
        z = self._normals("gps", 3)  # the Gauss-Markov errors start in their stationary distribution
        self._gps_err = [gps.pos_gm_std_h_m * z[0], gps.pos_gm_std_h_m * z[1], gps.pos_gm_std_v_m * z[2]]
        self._gps_err_t: float | None = None
        self._restart_clock()

    def _restart_clock(self) -> None:
        self._t_prev: float | None = None
        self._history: deque[_GpsState] = deque()
        self._gps_t0: float | None = None
        self._gps_k = 0

    # ------------------------------------------------------------------ per sensor
    def _normals(self, name: str, n: int) -> list[float]:
        """The next ``n`` standard normal draws of a stream, taken from blocks drawn ahead (numpy calls cost
        microseconds each: one per block instead of several per sample keeps a 1 kHz loop cheap)."""
        state = self._buffers[name]
        buf, pos = state
        if pos + n > len(buf):
            buf, pos = self._rng[name].standard_normal(_BLOCK).tolist(), 0
            state[0] = buf
        state[1] = pos + n
        return buf[pos:pos + n]

    def _vector(self, name: str, truth: tuple[float, float, float], sqrt_dt: float) -> tuple[float, float, float]:
        cfg = getattr(self.config, name)
        z = self._normals(name, 6)  # always 6 draws: the stream does not depend on the settings
        walk = cfg.drift_std * sqrt_dt
        d = self._drift[name]
        d[0] += walk * z[3]
        d[1] += walk * z[4]
        d[2] += walk * z[5]
        b = self._bias3[name]
        sigma = cfg.noise_std
        return (truth[0] + b[0] + d[0] + sigma * z[0], truth[1] + b[1] + d[1] + sigma * z[1],
                truth[2] + b[2] + d[2] + sigma * z[2])

    def _scalar(self, name: str, truth: float, sqrt_dt: float) -> float:
        cfg = getattr(self.config, name)
        z = self._normals(name, 2)
        self._drift[name] += cfg.drift_std * sqrt_dt * z[1]
        return truth + (cfg.bias + self._drift[name] + cfg.noise_std * z[0])

    def _gps(self, t_s: float, now: _GpsState) -> GpsFix | None:
        cfg = self.config.gps
        self._history.append(now)
        target = t_s - cfg.latency_s
        while len(self._history) >= 2 and self._history[1].t_s <= target:
            self._history.popleft()  # keep the one sample at or before the target, and everything after
        if self._gps_t0 is None:
            self._gps_t0 = t_s
        if t_s + _TIME_EPS_S < self._gps_t0 + self._gps_k / cfg.rate_hz:
            return None
        # next fix on the fixed grid t0 + k / rate (one fix per sample at most, missed slots are skipped)
        self._gps_k = math.floor((t_s - self._gps_t0 + _TIME_EPS_S) * cfg.rate_hz) + 1
        s = self._state_at(target)
        z = self._normals("gps", 9)
        err_n, err_e, err_d = self._gauss_markov(s.t_s, z[6:9])
        r_m, r_n = (float(r) for r in radii_of_curvature(math.radians(s.lat_deg)))
        cos_lat = max(math.cos(math.radians(s.lat_deg)), 1e-9)
        north, east = err_n + cfg.pos_noise_std_h_m * z[0], err_e + cfg.pos_noise_std_h_m * z[1]
        lat = s.lat_deg + math.degrees(north / (r_m + s.height_m))
        lon = _wrap_deg(s.lon_deg + math.degrees(east / ((r_n + s.height_m) * cos_lat)))
        if east == 0.0:
            lon = s.lon_deg  # exact (wrapping may change the last bit)
        alt = s.height_m - err_d + cfg.pos_noise_std_v_m * float(z[2])
        vn, ve, vd = (v + cfg.vel_noise_std_m_s * float(n) for v, n in zip(s.vel_ned_m_s, z[3:6], strict=True))
        speed = math.hypot(vn, ve)
        course = math.degrees(math.atan2(ve, vn)) % 360.0 if speed > 0.0 else 0.0
        if course >= 360.0:  # -tiny % 360 rounds to 360.0
            course = 0.0
        return GpsFix(time_s=s.t_s, lat_deg=lat, lon_deg=lon, alt_msl_m=alt, vel_ned_m_s=(vn, ve, vd),
                      ground_speed_m_s=speed, course_deg=course, eph_m=cfg.eph_m, epv_m=cfg.epv_m,
                      fix_type=cfg.fix_type, satellites=cfg.satellites)

    def _gauss_markov(self, t_s: float, z: list[float]) -> list[float]:
        """The position error [m] (north, east, down) at fix time ``t_s``, advanced from the last fix."""
        cfg, e = self.config.gps, self._gps_err
        if self._gps_err_t is not None and t_s > self._gps_err_t:
            phi = math.exp(-(t_s - self._gps_err_t) / cfg.pos_gm_tau_s)
            drive = math.sqrt(max(1.0 - phi * phi, 0.0))
            e[0] = phi * e[0] + cfg.pos_gm_std_h_m * drive * z[0]
            e[1] = phi * e[1] + cfg.pos_gm_std_h_m * drive * z[1]
            e[2] = phi * e[2] + cfg.pos_gm_std_v_m * drive * z[2]
        self._gps_err_t = t_s
        return e

    def _state_at(self, target: float) -> _GpsState:
        """The state at ``target`` from the history, linearly interpolated; the oldest one before it."""
        first = self._history[0]
        if target <= first.t_s or len(self._history) == 1:
            return first
        second = self._history[1]
        if target >= second.t_s or second.t_s <= first.t_s:
            return second
        f = (target - first.t_s) / (second.t_s - first.t_s)

        def lerp(a: float, b: float) -> float:
            return a + f * (b - a)

        return _GpsState(target, lerp(first.lat_deg, second.lat_deg),
                         _wrap_deg(first.lon_deg + f * _wrap_deg(second.lon_deg - first.lon_deg)),
                         lerp(first.height_m, second.height_m),
                         tuple(lerp(a, b) for a, b in zip(first.vel_ned_m_s, second.vel_ned_m_s, strict=True)))

    # ------------------------------------------------------------------ the frame
    def sample(self, t_s: float, outputs: Mapping[str, float]) -> SensorFrame:
        """Sensor readings at simulation time ``t_s`` [s] from the FMU outputs by name."""
        t_s = float(t_s)
        if not math.isfinite(t_s):
            raise ValueError(f"sample time must be finite, got {t_s}")
        try:  # one pass, in the order of REQUIRED_OUTPUTS
            ax, ay, az, p, q, r, qw, qx, qy, qz, lat, lon, height, vn, ve, vd = map(
                float, map(outputs.__getitem__, REQUIRED_OUTPUTS))
        except KeyError:
            missing = [name for name in REQUIRED_OUTPUTS if name not in outputs]
            raise MissingOutputError(f"FMU output{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                                     "missing: the sensor models need them") from None
        if self._t_prev is not None and t_s < self._t_prev:
            self._restart_clock()
        dt = 0.0 if self._t_prev is None else t_s - self._t_prev
        self._t_prev = t_s

        mag_body = _ned_to_body((qw, qx, qy, qz), self._mag_ned_list)
        temp_k, p_pa, rho = isa(height)  # plain floats for a float altitude
        sqrt_dt = math.sqrt(dt)  # the random walks' step
        abs_pressure = self._scalar("baro", p_pa, sqrt_dt)
        airspeed = outputs.get(AIRSPEED_OUTPUT)
        if airspeed is None:
            self._normals("diff_pressure", 2)  # keep the stream in step either way
            diff_pressure = 0.0
        else:
            diff_pressure = self._scalar("diff_pressure", 0.5 * rho * float(airspeed) ** 2, sqrt_dt)

        gps = self._gps(t_s, _GpsState(t_s, lat, lon, height, (vn, ve, vd)))
        return SensorFrame(self._vector("accel", (ax, ay, az), sqrt_dt), self._vector("gyro", (p, q, r), sqrt_dt),
                           self._vector("mag", mag_body, sqrt_dt), abs_pressure, temp_k - KELVIN_OFFSET,
                           diff_pressure, pressure_altitude_m(abs_pressure), gps)


__all__ = [
    "REQUIRED_OUTPUTS", "AccelConfig", "BaroConfig", "DiffPressureConfig", "GpsConfig", "GpsFix", "GyroConfig",
    "MagConfig", "MissingOutputError", "SensorConfig", "SensorConfigError", "SensorFrame", "SensorSuite",
    "pressure_altitude_m",
]

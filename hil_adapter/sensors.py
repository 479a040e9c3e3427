"""Sensor models for the HIL adapter: IMU, magnetometer, barometer, pitot and GPS from FMU outputs.

Pure Python/numpy, no I/O. Every random number comes from ``numpy.random.Generator`` streams derived from
one seed (one independent stream per sensor, so changing e.g. the GPS settings does not change the IMU
noise); ``SensorSuite.reset()`` restarts them and a rerun repeats exactly.

Each sensor reads ``truth + bias + drift + noise``: ``bias`` is constant; ``drift`` a random walk whose
increment over ``dt`` seconds has the std ``drift_std * sqrt(dt)``, for the IMU and magnetometer a first-order
Gauss-Markov process (``drift_tau_s``) started at 0, with a constant turn-on bias drawn at (re)start added, as
in PX4's Gazebo IMU plugin; ``noise`` is
white, a per-sample std ``noise_std`` and, for the IMU and magnetometer, a density ``noise_density`` (per sample
``density / sqrt(dt)``). Profiles (``PROFILES``, ``[sensors] profile``): ``px4_gazebo`` (the default: PX4's
Gazebo plugins, each default citing its source in its field description), ``ublox_m8`` (data sheets: u-blox
NEO-M8, TDK ICM-20602, MS5611) and ``ideal`` (no errors; reproduces the FMU outputs exactly).

Frames and conventions follow the FMUs: body FRD, NED world, ``quat_w/x/y/z`` rotates body vectors into NED,
the accelerometer reads specific force (``-9.80665`` on z at rest, level). Configurations are pydantic schemas
(``fmu_models.config``); ``SensorConfig.from_dict(data, source)`` checks a dict (a TOML table) and lists every
problem with field, value and allowed range.
"""

from __future__ import annotations

import math
import operator
from collections import deque
from collections.abc import Mapping
from typing import Annotated, Any, NamedTuple

import numpy as np
from pydantic import BeforeValidator, Field

# Both helpers are written once for CasADi but take and return plain floats for float arguments, which is
# all we use here (checked: ``isa(1000.0)`` and ``radii_of_curvature(0.8)`` return Python floats).
from fmu_models.common.atmosphere import EXPONENT, LAPSE_K_M, P0_PA, T0_K, isa
from fmu_models.common.units import G0_M_S2
from fmu_models.common.wgs84 import normal_gravity, radii_of_curvature
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
_REQUIRED = operator.itemgetter(*REQUIRED_OUTPUTS)
_tuple_new = tuple.__new__
_TIME_EPS_S = 1e-9  #: float slack when comparing sample times with the GPS schedule
_HISTORY_MAX = 4096  #: GPS history length at which it is trimmed even when no fix is due


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


# Where the defaults come from (the source of each is also in the field's description):
#: PX4's Gazebo models (PX4-SITL_gazebo-classic, models/iris/iris.sdf, gazebo_imu_plugin; the rotors IMU model:
#: white noise of a density, bias a first-order Gauss-Markov process of a random walk and correlation time,
#: started at a turn-on bias)
GAZEBO_IMU = "PX4-SITL_gazebo-classic iris.sdf <gazebo_imu_plugin>"
#: gazebo_magnetometer_plugin.h kDefaultNoiseDensity / kDefaultRandomWalk / kDefaultBiasCorrelationTime
GAZEBO_MAG = "PX4-SITL_gazebo-classic gazebo_magnetometer_plugin.h"
#: gazebo_barometer_plugin.cpp: 1 Pa RMS white noise, baroDriftPaPerSec 0 by default
GAZEBO_BARO = "PX4-SITL_gazebo-classic gazebo_barometer_plugin.cpp"
#: gazebo_airspeed_plugin.cpp: diff_pressure_stddev_ 0.01 hPa
GAZEBO_AIRSPEED = "PX4-SITL_gazebo-classic gazebo_airspeed_plugin.cpp"
GAZEBO_GPS = "PX4-SITL_gazebo-classic gazebo_gps_plugin.{h,cpp}"
#: the Gazebo physics step the GPS plugin's per-step update runs at (PX4's worlds: max_step_size 0.004 s)
GAZEBO_STEP_S = 0.004


def gazebo_gps_error(random_walk: float, step_s: float = GAZEBO_STEP_S, correlation: float = 60.0) -> tuple[float,
                                                                                                           float]:
    """(stationary std [m], time constant [s]) of the GPS position error PX4's Gazebo plugin really simulates.

    Its update per physics step is ``b += random_walk * sqrt(dt) * n * dt - b / correlation`` (the constant named
    a correlation time, 60, divides per *step*, not per second): a discrete Gauss-Markov process with the pole
    ``1 - 1/60`` per step, i.e. a time constant of 60 steps (0.24 s at 4 ms), and a drive of
    ``random_walk * dt**1.5`` per step: millimetres, not metres."""
    phi = 1.0 - 1.0 / correlation
    drive = random_walk * step_s ** 1.5
    return drive / math.sqrt(1.0 - phi * phi), step_s / (1.0 - phi)


_GPS_H_STD_M, GAZEBO_GPS_TAU_S = gazebo_gps_error(2.0)  #: kDefaultGpsXYRandomWalk 2 (m/s)/sqrt(Hz)
_GPS_V_STD_M, _ = gazebo_gps_error(4.0)  #: kDefaultGpsZRandomWalk 4 (m/s)/sqrt(Hz)


def _src(lo: float, hi: float, default: float, source: str) -> Any:
    """A bounded number whose default cites ``source`` (kept in the schema: ``Model.model_fields[f].description``)."""
    return Field(default, ge=lo, le=hi, allow_inf_nan=False, description=f"default from {source}")


class _Inertial(_Section):
    """Shared model of the IMU axes and the magnetometer: ``truth + bias + b(t) + white``, the white noise from
    a per-sample std ``noise_std`` and a density ``noise_density`` [unit/sqrt(Hz)] (per sample
    ``density / sqrt(dt)``, as an integrating sampler), ``b(t)`` a first-order Gauss-Markov process with the
    random walk ``drift_std`` [unit/sqrt(s)] and correlation time ``drift_tau_s`` [s] (0: a pure random walk)
    started at 0, plus a constant turn-on bias of std ``turn_on_bias_std`` per axis drawn at (re)start, as PX4's
    Gazebo IMU plugin adds it to every sample."""

    def drift_step(self, dt: float) -> tuple[float, float]:
        """(pole, drive std) of the drift over ``dt`` seconds (exact discretisation, Maybeck 4-114; a negative
        interval counts as none)."""
        dt = max(dt, 0.0)
        if self.drift_tau_s <= 0.0:
            return 1.0, self.drift_std * math.sqrt(dt)
        phi = math.exp(-dt / self.drift_tau_s)
        return phi, self.drift_std * math.sqrt(self.drift_tau_s / 2.0 * (1.0 - phi * phi))

    def white_std(self, dt: float) -> float:
        """Per-sample white noise std at the sample interval ``dt`` [s] (the density term needs dt > 0)."""
        density = self.noise_density * self.noise_density / dt if dt > 0.0 else 0.0
        return math.sqrt(self.noise_std * self.noise_std + density)


class AccelConfig(_Inertial):
    """Accelerometer [m/s^2]."""

    noise_std: float = _src(0.0, 10.0, 0.0, "none: white noise set by its density")
    noise_density: float = _src(0.0, 1.0, 0.00186, f"{GAZEBO_IMU} accelerometerNoiseDensity [m/s^2/sqrt(Hz)]")
    bias: _vec3(-10.0, 10.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _src(0.0, 1.0, 0.006, f"{GAZEBO_IMU} accelerometerRandomWalk [m/s^3/sqrt(Hz)]")
    drift_tau_s: float = _src(0.0, 1e5, 300.0, f"{GAZEBO_IMU} accelerometerBiasCorrelationTime [s]")
    turn_on_bias_std: float = _src(0.0, 5.0, 0.196, f"{GAZEBO_IMU} accelerometerTurnOnBiasSigma [m/s^2]")


class GyroConfig(_Inertial):
    """Gyroscope [rad/s]."""

    noise_std: float = _src(0.0, 1.0, 0.0, "none: white noise set by its density")
    noise_density: float = _src(0.0, 0.1, 0.00018665, f"{GAZEBO_IMU} gyroscopeNoiseDensity [rad/s/sqrt(Hz)]")
    bias: _vec3(-1.0, 1.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _src(0.0, 0.1, 3.8785e-5, f"{GAZEBO_IMU} gyroscopeRandomWalk [rad/s^2/sqrt(Hz)]")
    drift_tau_s: float = _src(0.0, 1e5, 1000.0, f"{GAZEBO_IMU} gyroscopeBiasCorrelationTime [s]")
    turn_on_bias_std: float = _src(0.0, 0.5, 0.0087, f"{GAZEBO_IMU} gyroscopeTurnOnBiasSigma [rad/s]")


class MagConfig(_Inertial):
    """Magnetometer [gauss] and the Earth field it measures: total intensity [gauss] (the Earth's is 0.22..0.67),
    declination (east of true north, positive) and inclination (below the horizon, positive) [deg]; constant
    over the flight."""

    noise_std: float = _src(0.0, 1.0, 0.0, "none: white noise set by its density")
    noise_density: float = _src(0.0, 0.1, 0.4e-3, f"{GAZEBO_MAG} kDefaultNoiseDensity [gauss/sqrt(Hz)]")
    bias: _vec3(-2.0, 2.0) = (0.0, 0.0, 0.0)  # type: ignore[valid-type]
    drift_std: float = _src(0.0, 0.1, 6.4e-6, f"{GAZEBO_MAG} kDefaultRandomWalk [gauss*sqrt(Hz)]")
    drift_tau_s: float = _src(0.0, 1e5, 600.0, f"{GAZEBO_MAG} kDefaultBiasCorrelationTime [s]")
    turn_on_bias_std: float = _src(0.0, 1.0, 0.0, f"{GAZEBO_MAG} (none)")
    rate_hz: float = _src(1.0, 1000.0, 100.0, f"{GAZEBO_MAG} kDefaultPubRate (between samples: repeated, not "
                                              "flagged as updated)")
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
    """Barometer static pressure [Pa] at ``rate_hz`` (between its samples the last reading is repeated and not
    flagged as updated); drift_std in Pa per sqrt(s). The temperature is the noise-free ISA one."""

    rate_hz: float = _src(1.0, 1000.0, 50.0, f"{GAZEBO_BARO} kDefaultPubRate")
    noise_std: float = _src(0.0, 1000.0, 1.0, f"{GAZEBO_BARO}: 1 Pa RMS")
    bias: float = _num(-5000.0, 5000.0, 0.0)
    drift_std: float = _src(0.0, 100.0, 0.0, f"{GAZEBO_BARO}: baroDriftPaPerSec 0")


class DiffPressureConfig(_Section):
    """Pitot differential pressure [Pa]; drift_std in Pa per sqrt(s). Used only when the FMU has airspeed."""

    noise_std: float = _src(0.0, 100.0, 1.0, f"{GAZEBO_AIRSPEED}: DiffPressureStdev 0.01 hPa")
    bias: float = _num(-100.0, 100.0, 0.0)
    drift_std: float = _src(0.0, 10.0, 0.0, f"{GAZEBO_AIRSPEED}: white noise only, no drift")


class GpsConfig(_Section):
    """GPS receiver: fix rate [Hz], latency [s] (a fix delivered at t describes the state at t - latency),
    the reported accuracies eph/epv [m], fix type (MAVLink GPS_FIX_TYPE: 3 = 3D), satellites.

    Position error = a first-order Gauss-Markov process per axis plus white noise: ``e(t+dt) = exp(-dt/tau) e(t)
    + std * sqrt(1 - exp(-2 dt/tau)) n``, stationary std ``pos_gm_std_h_m`` (north and east) / ``pos_gm_std_v_m``
    (down) [m], time constant ``pos_gm_tau_s`` [s], started in its stationary distribution. The defaults are
    what PX4's Gazebo GPS plugin really simulates (``gazebo_gps_error``: millimetres, 0.24 s; its random walks of
    2 and 4 (m/s)/sqrt(Hz) are applied per 4 ms physics step with a pole of 1 - 1/60 per step, not the 1 m / 2 m,
    60 s its constants suggest). NED velocity: white noise std [m/s], horizontal and down."""

    rate_hz: float = _src(0.1, 100.0, 5.0, f"{GAZEBO_GPS} kDefaultUpdateRate")
    latency_s: float = _src(0.0, 1.0, 0.12, f"{GAZEBO_GPS} gps_delay_ 120 ms")
    eph_m: float = _src(0.0, 600.0, 1.0, f"{GAZEBO_GPS} std_xy 1.0")
    epv_m: float = _src(0.0, 600.0, 1.0, f"{GAZEBO_GPS} std_z 1.0")
    fix_type: int = Field(3, ge=0, le=8)
    satellites: int = Field(10, ge=0, le=255)
    pos_gm_std_h_m: float = _src(0.0, 100.0, _GPS_H_STD_M, f"{GAZEBO_GPS} (gazebo_gps_error, 2 (m/s)/sqrt(Hz))")
    pos_gm_std_v_m: float = _src(0.0, 100.0, _GPS_V_STD_M, f"{GAZEBO_GPS} (gazebo_gps_error, 4 (m/s)/sqrt(Hz))")
    pos_gm_tau_s: float = _src(0.01, 3600.0, GAZEBO_GPS_TAU_S, f"{GAZEBO_GPS} (60 steps of 4 ms)")
    pos_noise_std_h_m: float = _src(0.0, 100.0, 2.0e-4 * math.sqrt(GAZEBO_STEP_S),
                                    f"{GAZEBO_GPS} kDefaultGpsXYNoiseDensity * sqrt(dt)")
    pos_noise_std_v_m: float = _src(0.0, 100.0, 4.0e-4 * math.sqrt(GAZEBO_STEP_S),
                                    f"{GAZEBO_GPS} kDefaultGpsZNoiseDensity * sqrt(dt)")
    vel_noise_std_m_s: float = _src(0.0, 10.0, 0.2 * math.sqrt(GAZEBO_STEP_S),
                                    f"{GAZEBO_GPS} kDefaultGpsVXYNoiseDensity * sqrt(dt)")
    vel_noise_std_down_m_s: float = _src(0.0, 10.0, 0.4 * math.sqrt(GAZEBO_STEP_S),
                                         f"{GAZEBO_GPS} kDefaultGpsVZNoiseDensity * sqrt(dt)")


#: u-blox NEO-M8 data sheet (UBX-15031086 R11): 2.5 m CEP horizontal (GPS+GLONASS), velocity 0.05 m/s, up to
#: 10 Hz concurrent GNSS; CEP = 1.1774 sigma for a circular normal error. The data sheet gives no vertical figure
#: and no correlation time: vertical = 1.5 x horizontal (a typical VDOP/HDOP) and 60 s are ASSUMPTIONS, said so.
#: IMU: TDK ICM-20602 data sheet, gyro 0.004 dps/sqrt(Hz), accel 100 ug/sqrt(Hz) (bias processes as Gazebo's).
#: Baro: TE MS5611-01BA03 data sheet, resolution 0.012 mbar RMS at OSR 4096 (1.2 Pa).
_M8_SIGMA_H_M = 2.5 / 1.1774
PROFILES: dict[str, dict[str, dict[str, float]]] = {
    "px4_gazebo": {},
    "ublox_m8": {
        "gps": {"rate_hz": 10.0, "latency_s": 0.1, "eph_m": 2.5, "epv_m": 3.75, "pos_gm_std_h_m": _M8_SIGMA_H_M,
                "pos_gm_std_v_m": 1.5 * _M8_SIGMA_H_M, "pos_gm_tau_s": 60.0, "pos_noise_std_h_m": 0.0,
                "pos_noise_std_v_m": 0.0, "vel_noise_std_m_s": 0.05, "vel_noise_std_down_m_s": 0.05},
        "gyro": {"noise_density": math.radians(0.004)},
        "accel": {"noise_density": 100e-6 * G0_M_S2},
        "baro": {"noise_std": 1.2},
    },
    "ideal": {name: {"noise_std": 0.0, "noise_density": 0.0, "drift_std": 0.0, "turn_on_bias_std": 0.0}
              for name in ("accel", "gyro", "mag")}
    | {"baro": {"noise_std": 0.0, "drift_std": 0.0}, "diff_pressure": {"noise_std": 0.0, "drift_std": 0.0},
       "gps": {"pos_gm_std_h_m": 0.0, "pos_gm_std_v_m": 0.0, "pos_noise_std_h_m": 0.0, "pos_noise_std_v_m": 0.0,
               "vel_noise_std_m_s": 0.0, "vel_noise_std_down_m_s": 0.0}},
}


class SensorConfig(Schema):
    """All sensors; defaults: PX4's Gazebo sensor plugins (each field's description names its source). TOML
    layout: one table per sensor, ``[accel] [gyro] [mag] [baro] [diff_pressure] [gps]``, each optional, missing
    keys keep the profile's value (``from_dict(data, profile=...)``, ``PROFILES``)."""

    accel: AccelConfig = AccelConfig()
    gyro: GyroConfig = GyroConfig()
    mag: MagConfig = MagConfig()
    baro: BaroConfig = BaroConfig()
    diff_pressure: DiffPressureConfig = DiffPressureConfig()
    gps: GpsConfig = GpsConfig()

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "sensor config",
                  profile: str = "px4_gazebo") -> SensorConfig:
        """Check every field of every table over the ``profile``'s values; ``SensorConfigError`` lists all
        problems, prefixed by ``source``."""
        if profile not in PROFILES:
            raise SensorConfigError(source, [f"profile = {profile!r}: allowed {', '.join(sorted(PROFILES))}"])
        merged: dict[str, Any] = {k: dict(v) for k, v in PROFILES[profile].items()}
        for key, table in data.items():
            merged[key] = {**merged.get(key, {}), **table} if isinstance(table, Mapping) else table
        return _validated(cls, merged, source)

    @classmethod
    def profile(cls, name: str) -> SensorConfig:
        """The named profile (``PROFILES``: ``px4_gazebo`` the default, ``ublox_m8``, ``ideal``)."""
        return cls.from_dict({}, f"profile {name}", profile=name)

    def replace(self, **sections: Any) -> SensorConfig:
        """A copy with whole sections replaced."""
        return type(self).model_validate({**{k: getattr(self, k) for k in type(self).model_fields}, **sections})

    @classmethod
    def noise_free(cls) -> SensorConfig:
        """Every noise, bias and drift 0 (GPS rate, latency and the Earth field keep their defaults)."""
        return cls.profile("ideal")


# ------------------------------------------------------------------------------------------ frames
class GpsFix(NamedTuple):
    """One GPS solution. ``time_s`` is the time the fix describes (delivery time minus the latency, no
    earlier than the first sample); ``alt_msl_m`` is the FMU's ellipsoidal height (see ``SensorSuite``).
    (A named tuple: immutable like a frozen dataclass, and cheaper to build.)"""

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


#: bits of ``SensorFrame.updated`` (MAVLink HIL_SENSOR.fields_updated: accel xyz 0-2, gyro xyz 3-5, mag xyz 6-8,
#: abs pressure 9, diff pressure 10, pressure altitude 11, temperature 12)
UPDATED_IMU = 0x3F
UPDATED_MAG = 0x1C0
UPDATED_BARO = (1 << 9) | (1 << 11) | (1 << 12)
UPDATED_DIFF_PRESSURE = 1 << 10


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
    #: which readings are new at this sample, in the bit layout of MAVLink HIL_SENSOR.fields_updated
    #: (``UPDATED_*``): the IMU always, the magnetometer and barometer at their own rates
    updated: int = 0


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
    norm2 = w * w + x * x + y * y + z * z
    if not -1e-12 < norm2 - 1.0 < 1e-12:  # the FMU's quaternion is unit to rounding: normalise only otherwise
        if not norm2 > 0.0:
            raise ValueError(f"attitude quaternion {q} has no direction")
        norm = math.sqrt(norm2)
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
    r00, r01, r02 = w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)
    r10, r11, r12 = 2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)
    r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z
    return (r00 * v[0] + r10 * v[1] + r20 * v[2], r01 * v[0] + r11 * v[1] + r21 * v[2],
            r02 * v[0] + r12 * v[1] + r22 * v[2])


#: FMU output of the gravity the model integrates with (WGS-84 normal gravity at the vehicle) [m/s^2]
GRAVITY_OUTPUT = "gravity_m_s2"
Vec3 = tuple[float, float, float]


#: the FMU outputs ``interval_imu`` reads at each end of the interval, in one C call
_IMU_ENDS = operator.itemgetter("quat_w", "quat_x", "quat_y", "quat_z", "vel_north_m_s", "vel_east_m_s",
                                "vel_down_m_s")


def interval_imu(before: Mapping[str, float], after: Mapping[str, float], dt_s: float) -> tuple[Vec3, Vec3]:
    """What a strapdown IMU reports for the sample interval of ``dt_s`` [s] between two FMU states: (mean specific
    force [m/s^2], mean body rate [rad/s]), body FRD. The specific force is the delta velocity over the interval,
    ``(v1 - v0) / dt - g`` in NED (exact for the model's flat NED velocity equation), rotated into the body at the
    interval's middle attitude; the rate is the delta angle, the rotation vector of ``q0* q1``, over ``dt``. An
    impulse shorter than the interval (a touchdown) so reaches the estimator with its whole velocity change, which
    the outputs at the end of the interval (the FMU's ``accel_body_*``, an instant) miss. Gravity: the FMU's
    ``gravity_m_s2`` (mean of both ends), else WGS-84 normal gravity at the end position. Plain floats: it runs
    once per lockstep step."""
    w0, x0, y0, z0, vn0, ve0, vd0 = _IMU_ENDS(before)
    w1, x1, y1, z1, vn1, ve1, vd1 = _IMU_ENDS(after)
    g0, g1 = before.get(GRAVITY_OUTPUT), after.get(GRAVITY_OUTPUT)
    if g0 is None or g1 is None:  # an FMU without the gravity output: the same formula at the end position
        g0 = g1 = normal_gravity(math.radians(after["lat_deg"]), float(after["height_m"]))
    # q0* q1: the rotation over the interval in the body frame (q and -q are one attitude: take the short way)
    dw = w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1
    dx = w0 * x1 - x0 * w1 - y0 * z1 + z0 * y1
    dy = w0 * y1 + x0 * z1 - y0 * w1 - z0 * x1
    dz = w0 * z1 - x0 * y1 + y0 * x1 - z0 * w1
    if dw < 0.0:
        dw, dx, dy, dz, w1, x1, y1, z1 = -dw, -dx, -dy, -dz, -w1, -x1, -y1, -z1
    sin_half = math.sqrt(dx * dx + dy * dy + dz * dz)
    inv_dt = 1.0 / dt_s
    # angle / sin(angle / 2), -> 2 as the angle -> 0
    k = (2.0 * math.atan2(sin_half, dw) / sin_half if sin_half > 1e-9 else 2.0) * inv_dt
    fn, fe, fd = (vn1 - vn0) * inv_dt, (ve1 - ve0) * inv_dt, (vd1 - vd0) * inv_dt - 0.5 * (g0 + g1)
    # the middle attitude, (q0 + q1) normalised, applied as R_b2n^T
    w, x, y, z = w0 + w1, x0 + x1, y0 + y1, z0 + z1
    s = 1.0 / (w * w + x * x + y * y + z * z)
    return ((s * ((w * w + x * x - y * y - z * z) * fn + 2 * (x * y + w * z) * fe + 2 * (x * z - w * y) * fd),
             s * (2 * (x * y - w * z) * fn + (w * w - x * x + y * y - z * z) * fe + 2 * (y * z + w * x) * fd),
             s * (2 * (x * z + w * y) * fn + 2 * (y * z - w * x) * fe + (w * w - x * x - y * y + z * z) * fd)),
            (k * dx, k * dy, k * dz))


def _walk_and_noise(truth: tuple[float, float, float], bias: list[float], drift: list[float],
                    coef: tuple[float, float, float], z: list[float], i: int = 0) -> tuple[float, float, float]:
    """One 3-axis reading from the six draws ``z[i:i + 6]``: ``drift`` (updated in place) ``= pole * drift +
    drive * z[i+3:i+6]``, reading ``= truth + bias + drift + white * z[i:i+3]``, ``coef = (pole, drive, white)``."""
    phi, walk, sigma = coef
    d0 = drift[0] = phi * drift[0] + walk * z[i + 3]
    d1 = drift[1] = phi * drift[1] + walk * z[i + 4]
    d2 = drift[2] = phi * drift[2] + walk * z[i + 5]
    return (truth[0] + bias[0] + d0 + sigma * z[i], truth[1] + bias[1] + d1 + sigma * z[i + 1],
            truth[2] + bias[2] + d2 + sigma * z[i + 2])


def pressure_altitude_m(pressure_pa: float) -> float:
    """ISA troposphere altitude [m] of a static pressure: the inverse of ``atmosphere.isa``'s pressure
    (written here because the atmosphere module only goes from altitude to pressure)."""
    return T0_K / LAPSE_K_M * (1.0 - (pressure_pa / P0_PA) ** (1.0 / EXPONENT))


def _wrap_deg(angle_deg: float) -> float:
    return (angle_deg + 180.0) % 360.0 - 180.0


# ------------------------------------------------------------------------------------------ the suite
_BLOCK = 6 * 256  #: normal draws fetched per numpy call for the GPS and turn-on streams
_ROWS = 256  #: readings per block drawn ahead, per stream
#: the streams read by rows and their draws per reading (white noise and drift per axis)
_ROW_SIZE = {"accel": 6, "gyro": 6, "mag": 6, "baro": 2, "diff_pressure": 2}


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

    _STREAMS = ("accel", "gyro", "mag", "baro", "diff_pressure", "gps", "turn_on")

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
        for name in ("accel", "gyro", "mag"):  # a constant turn-on bias per axis (the Gauss-Markov part starts at 0)
            on = getattr(self.config, name).turn_on_bias_std
            draws = self._normals("turn_on", 3)
            self._bias3[name] = [b + on * z for b, z in zip(self._bias3[name], draws, strict=True)]
        #: (biases, drifts) of accel, gyro, mag: the same lists as in _bias3 and _drift, looked up once
        self._imu_state = (tuple(self._bias3[n] for n in ("accel", "gyro", "mag")),
                           tuple(self._drift[n] for n in ("accel", "gyro", "mag")))
        #: the sample interval the coefficients were computed for; per inertial sensor (pole, drive, white std)
        #: and the baro / pitot random-walk steps
        self._coef_dt = -1.0
        self._mag_coef: tuple[float, tuple[float, float, float]] | None = None
        #: the last magnetometer and barometer readings, repeated between their samples
        self._mag_last: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._baro_last: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._coef: tuple[Any, ...] = ()
        self._row = _ROWS  # the IMU's draws (accel and gyro rows of one block index): refilled on first use
        self._blocks: tuple[list[float], ...] = ()  # flat: sample k's six draws at 6k
        #: the other row streams, drawn only when read (the magnetometer and barometer below the sample rate,
        #: the pitot only with an airspeed): per stream [rows, next row]
        self._rows: dict[str, list[Any]] = {name: [[], 0] for name in ("mag", "baro", "diff_pressure")}
        gps = self.config.gps
        z = self._normals("gps", 3)  # the Gauss-Markov errors start in their stationary distribution
        self._gps_err = [gps.pos_gm_std_h_m * z[0], gps.pos_gm_std_h_m * z[1], gps.pos_gm_std_v_m * z[2]]
        self._gps_err_t: float | None = None
        self._restart_clock()

    def _restart_clock(self) -> None:
        self._t_prev: float | None = None
        #: (t_s, lat, lon, height, velocity) per sample since the GPS latency ago: plain tuples (made every
        #: sample), read as ``_GpsState`` when a fix is due
        self._history: deque[tuple[Any, ...]] = deque()
        #: per sensor read below the sample rate: [grid start, next slot index, time of its last reading] and
        #: the time its next reading is due
        self._schedule: dict[str, list[Any]] = {name: [None, 0, 0.0] for name in ("mag", "baro", "gps")}
        self._next = dict.fromkeys(("mag", "baro", "gps"), -math.inf)

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

    def _coefficients(self, dt: float) -> tuple[Any, ...]:
        """Per-interval constants of the every-sample sensors, recomputed only when the sample interval changes
        (in lockstep it is constant up to float rounding; exp and sqrt per sample would cost microseconds):
        accel and gyro (drift pole, drift drive std, white std), the pitot random-walk step."""
        if abs(dt - self._coef_dt) <= 1e-9 * dt:
            return self._coef
        cfg = self.config
        white_dt = dt if dt > 0.0 else GAZEBO_STEP_S  # the first sample: white noise at Gazebo's 4 ms step
        inertial = tuple((*c.drift_step(dt), c.white_std(white_dt)) for c in (cfg.accel, cfg.gyro))
        self._coef = (*inertial, cfg.diff_pressure.drift_std * math.sqrt(dt))
        self._coef_dt = dt
        return self._coef

    def _read(self, name: str, t_s: float, rate_hz: float) -> float:
        """A reading of ``name`` is taken at ``t_s`` (the caller checked it is due: ``_next[name]``): the
        interval [s] since its last one (0 for the first); the next is due at the following slot of its fixed
        grid ``t0 + k / rate`` (missed slots are skipped, one reading per sample at most)."""
        sched = self._schedule[name]
        if sched[0] is None:
            sched[:] = [t_s, 0, t_s]
        sched[1] = math.floor((t_s - sched[0] + _TIME_EPS_S) * rate_hz) + 1
        self._next[name] = sched[0] + sched[1] / rate_hz
        interval, sched[2] = t_s - sched[2], t_s
        return interval

    def _mag(self, t_s: float, q: tuple[float, float, float, float]) -> tuple[float, float, float]:
        """The magnetometer reading due at ``t_s`` (constants cached per interval between readings)."""
        cfg = self.config.mag
        dt = self._read("mag", t_s, cfg.rate_hz)
        cached = self._mag_coef
        if cached is None or abs(dt - cached[0]) > 1e-9 * dt:
            cached = self._mag_coef = (dt, (*cfg.drift_step(dt), cfg.white_std(dt if dt > 0.0 else 1.0 / cfg.rate_hz)))
        return _walk_and_noise(_ned_to_body(q, self._mag_ned_list), self._imu_state[0][2], self._imu_state[1][2],
                               cached[1], self._take("mag"))

    def _draws(self) -> None:
        """Draw the IMU's next ``_ROWS`` samples of standard normals ahead (accel and gyro: 6 per sample, white
        noise and drift per axis), one numpy call per stream and block, kept flat (a list per row costs more)."""
        self._blocks = tuple(self._rng[name].standard_normal(_ROWS * 6).tolist() for name in ("accel", "gyro"))

    def _block(self, name: str) -> list[list[float]]:
        n = _ROW_SIZE[name]
        return self._rng[name].standard_normal(_ROWS * n).reshape(_ROWS, n).tolist()

    def _take(self, name: str) -> list[float]:
        """The next row of draws of a stream read below the sample rate."""
        state = self._rows[name]
        rows, k = state
        if k >= len(rows):
            rows, k = self._block(name), 0
            state[0] = rows
        state[1] = k + 1
        return rows[k]

    def _baro(self, dt: float, height_m: float, z: list[float]) -> tuple[float, float, float]:
        """(pressure [Pa], temperature [degC], pressure altitude [m]) after ``dt`` seconds since the last."""
        cfg = self.config.baro
        temp_k, p_pa, _ = isa(height_m)  # plain floats for a float altitude
        pressure = self._scalar("baro", cfg, p_pa, cfg.drift_std * math.sqrt(dt), z)
        return pressure, temp_k - KELVIN_OFFSET, pressure_altitude_m(pressure)

    def _scalar(self, name: str, cfg: Any, truth: float, walk: float, z: list[float]) -> float:
        drift = self._drift[name] + walk * z[1]
        self._drift[name] = drift
        return truth + (cfg.bias + drift + cfg.noise_std * z[0])

    def _gps(self, t_s: float, now: tuple[Any, ...]) -> GpsFix | None:
        hist = self._history
        hist.append(now)
        if t_s + _TIME_EPS_S < self._next["gps"] and len(hist) < _HISTORY_MAX:
            return None
        cfg = self.config.gps
        target = t_s - cfg.latency_s
        while len(hist) >= 2 and hist[1][0] <= target:
            hist.popleft()  # keep the one sample at or before the target, and everything after
        if t_s + _TIME_EPS_S < self._next["gps"]:
            return None  # only trimmed: a slow GPS at a fast sample rate
        self._read("gps", t_s, cfg.rate_hz)  # the next fix on its grid
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
        vn = s.vel_ned_m_s[0] + cfg.vel_noise_std_m_s * z[3]
        ve = s.vel_ned_m_s[1] + cfg.vel_noise_std_m_s * z[4]
        vd = s.vel_ned_m_s[2] + cfg.vel_noise_std_down_m_s * z[5]
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
        first = _GpsState(*self._history[0])
        if target <= first.t_s or len(self._history) == 1:
            return first
        second = _GpsState(*self._history[1])
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
    def sample(self, t_s: float, outputs: Mapping[str, float], imu: tuple[Vec3, Vec3] | None = None) -> SensorFrame:
        """Sensor readings at simulation time ``t_s`` [s] from the FMU outputs by name; ``imu`` (mean specific force,
        mean body rate over the sample interval: :func:`interval_imu`) replaces the outputs' instantaneous
        accelerometer and gyro truth when given."""
        t_s = float(t_s)
        if not math.isfinite(t_s):
            raise ValueError(f"sample time must be finite, got {t_s}")
        try:  # one C call, in the order of REQUIRED_OUTPUTS (numbers as the FMU host gives them: floats)
            ax, ay, az, p, q, r, qw, qx, qy, qz, lat, lon, height, vn, ve, vd = _REQUIRED(outputs)
        except KeyError:
            missing = [name for name in REQUIRED_OUTPUTS if name not in outputs]
            raise MissingOutputError(f"FMU output{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                                     "missing: the sensor models need them") from None
        if imu is not None:
            (ax, ay, az), (p, q, r) = imu
        if self._t_prev is not None and t_s < self._t_prev:
            self._restart_clock()
        dt = 0.0 if self._t_prev is None else t_s - self._t_prev
        self._t_prev = t_s

        coef = self._coefficients(dt)
        row = self._row
        if row >= _ROWS:
            self._draws()  # refill
            row = 0
        self._row = row + 1
        blocks = self._blocks
        (ba, bg, _), (da, dg, _) = self._imu_state
        accel = _walk_and_noise((ax, ay, az), ba, da, coef[0], blocks[0], 6 * row)
        gyro = _walk_and_noise((p, q, r), bg, dg, coef[1], blocks[1], 6 * row)
        updated = UPDATED_IMU
        due = self._next
        if t_s + _TIME_EPS_S >= due["mag"]:
            self._mag_last = self._mag(t_s, (qw, qx, qy, qz))
            updated |= UPDATED_MAG
        if t_s + _TIME_EPS_S >= due["baro"]:
            self._baro_last = self._baro(self._read("baro", t_s, self.config.baro.rate_hz), height,
                                         self._take("baro"))
            updated |= UPDATED_BARO
        pressure, temp_c, pressure_alt = self._baro_last
        airspeed = outputs.get(AIRSPEED_OUTPUT)
        if airspeed is None:
            diff_pressure = 0.0
        else:
            rho = isa(height)[2]
            diff_pressure = self._scalar("diff_pressure", self.config.diff_pressure,
                                         0.5 * rho * float(airspeed) ** 2, coef[2], self._take("diff_pressure"))
            updated |= UPDATED_DIFF_PRESSURE
        gps = self._gps(t_s, (t_s, lat, lon, height, (vn, ve, vd)))
        # tuple.__new__ as namedtuple's own _make does: the generated __new__ is a Python call per frame
        return _tuple_new(SensorFrame, (accel, gyro, self._mag_last, pressure, temp_c, diff_pressure, pressure_alt,
                                        gps, updated))


__all__ = [
    "PROFILES", "REQUIRED_OUTPUTS", "UPDATED_BARO", "UPDATED_DIFF_PRESSURE", "UPDATED_IMU", "UPDATED_MAG",
    "AccelConfig", "BaroConfig", "DiffPressureConfig", "GpsConfig", "GpsFix",
    "GyroConfig", "MagConfig", "MissingOutputError", "SensorConfig", "SensorConfigError", "SensorFrame", "SensorSuite",
    "gazebo_gps_error", "interval_imu", "pressure_altitude_m",
]

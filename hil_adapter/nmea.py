"""NMEA 0183 GPS output for the HIL bench: GGA, RMC and VTG sentences over a serial port, like an RS-232 GPS.

``nmea_sentences`` builds one epoch (``$GPGGA``, ``$GPRMC``, ``$GPVTG``, each with checksum and CRLF) with
pynmea2; ``NmeaGpsWriter`` keeps the latest simulated state and writes an epoch whenever one is due at its
rate in *simulation* time; ``open_serial`` opens a device path or a pyserial URL (``loop://``, a pty path).

Formats: time ``hhmmss.ss`` (UTC rounded to 10 ms, the date follows the rounded time), date ``ddmmyy``,
latitude ``ddmm.mmmmm`` and longitude ``dddmm.mmmmm`` (1e-5 minute ~ 2 cm) with N/S and E/W, altitude MSL
and geoid separation in metres, speed in knots (RMC, VTG) and km/h (VTG), course true in degrees. RMC status
is ``A`` when ``fix_quality > 0`` and ``V`` otherwise; RMC and VTG carry the NMEA 2.3 mode indicator
(``N`` no fix, ``A`` autonomous, ``D`` differential, ...).

Bandwidth: one epoch is about 190 bytes, so 5 Hz needs about 9.5 kbit/s on the wire. That saturates a real
9600 baud line (writes then block or time out); use 38400 baud or more on real RS-232. Ptys ignore the baud rate.
"""

from __future__ import annotations

import math
import numbers
from datetime import UTC, datetime, timedelta
from typing import Any, Protocol

import pynmea2
import serial

KNOTS_PER_M_S = 3600.0 / 1852.0  #: 1 m/s in knots (1 nautical mile = 1852 m)
KMH_PER_M_S = 3.6  #: 1 m/s in km/h

#: allowed ranges ``(low, high, unit)``, inclusive; every value must also be finite
LIMITS: dict[str, tuple[float, float, str]] = {
    "lat_deg": (-90.0, 90.0, "deg"),
    "lon_deg": (-180.0, 180.0, "deg"),
    "alt_msl_m": (-1_000.0, 50_000.0, "m"),
    "ground_speed_m_s": (0.0, 10_000.0, "m/s"),
    "course_deg": (0.0, 360.0, "deg"),
    "hdop": (0.0, 99.99, ""),
    "geoid_sep_m": (-200.0, 200.0, "m"),
    "vel_north_m_s": (-10_000.0, 10_000.0, "m/s"),
    "vel_east_m_s": (-10_000.0, 10_000.0, "m/s"),
    "vel_down_m_s": (-10_000.0, 10_000.0, "m/s"),
}
INT_LIMITS: dict[str, tuple[int, int]] = {"fix_quality": (0, 8), "satellites": (0, 99)}

#: GGA fix quality -> NMEA 2.3 mode indicator of RMC/VTG
_MODE = {0: "N", 1: "A", 2: "D", 3: "P", 4: "R", 5: "F", 6: "E", 7: "M", 8: "S"}
_STILL_M_S = 0.01  #: below this ground speed the writer keeps the previous course


class NmeaError(ValueError):
    """An invalid input; the message names the field, the value and the allowed range."""


class WritablePort(Protocol):
    def write(self, data: bytes, /) -> int | None: ...


def _real(name: str, value: Any) -> float:
    lo, hi, unit = LIMITS[name]
    allowed = f"allowed range [{lo:g}, {hi:g}]{' ' + unit if unit else ''}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise NmeaError(f"{name}={value!r} is not a real number; {allowed}")
    x = float(value)
    if not math.isfinite(x):
        raise NmeaError(f"{name}={value!r} is not finite; {allowed}")
    if not lo <= x <= hi:
        raise NmeaError(f"{name}={value!r} outside the {allowed}")
    return x


def _integer(name: str, value: Any) -> int:
    lo, hi = INT_LIMITS[name]
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise NmeaError(f"{name}={value!r} must be an integer in the allowed range [{lo}, {hi}]")
    return int(value)


def _utc(name: str, value: Any) -> datetime:
    """Aware datetimes are converted to UTC; naive ones are taken as UTC already."""
    if not isinstance(value, datetime):
        raise NmeaError(f"{name}={value!r} is not a datetime; allowed: any datetime (naive = UTC)")
    return value.astimezone(UTC) if value.tzinfo is not None else value.replace(tzinfo=UTC)


def _angle(value_deg: float, deg_digits: int, hemispheres: str) -> tuple[str, str]:
    """``(d)ddmm.mmmmm`` and the hemisphere letter; rounds in whole 1e-5 minutes so 60.00000 never appears."""
    total = round(abs(value_deg) * 60.0 * 100_000)  # 1e-5 minutes
    deg, rest = divmod(total, 60 * 100_000)
    minutes, frac = divmod(rest, 100_000)
    hemi = hemispheres[1] if value_deg < 0 and total else hemispheres[0]
    return f"{deg:0{deg_digits}d}{minutes:02d}.{frac:05d}", hemi


def _time_date(utc: datetime) -> tuple[str, str]:
    """``hhmmss.ss`` and ``ddmmyy`` of ``utc`` rounded to 10 ms (so 23:59:59.996 gives the next day)."""
    t = utc.replace(microsecond=0) + timedelta(microseconds=round(utc.microsecond / 10_000) * 10_000)
    return f"{t:%H%M%S}.{t.microsecond // 10_000:02d}", f"{t:%d%m%y}"


def nmea_sentences(
    utc: datetime,
    lat_deg: float,
    lon_deg: float,
    alt_msl_m: float,
    ground_speed_m_s: float,
    course_deg: float,
    fix_quality: int,
    satellites: int,
    hdop: float,
    geoid_sep_m: float = 0.0,
) -> list[str]:
    """``[GGA, RMC, VTG]`` (GP talker), each a full line ``$...*hh\\r\\n``.

    ``course_deg`` is true course over ground in [0, 360] (360 is sent as 0); ``alt_msl_m`` is above mean
    sea level, ``geoid_sep_m`` the geoid height above the WGS-84 ellipsoid. Invalid inputs raise
    ``NmeaError`` naming the field, value and allowed range.
    """
    when = _utc("utc", utc)
    lat = _real("lat_deg", lat_deg)
    lon = _real("lon_deg", lon_deg)
    alt = _real("alt_msl_m", alt_msl_m)
    speed = _real("ground_speed_m_s", ground_speed_m_s)
    course = _real("course_deg", course_deg)
    fix = _integer("fix_quality", fix_quality)
    sats = _integer("satellites", satellites)
    dop = _real("hdop", hdop)
    sep = _real("geoid_sep_m", geoid_sep_m)

    hhmmss, ddmmyy = _time_date(when)
    lat_s, ns = _angle(lat, 2, "NS")
    lon_s, ew = _angle(lon, 3, "EW")
    knots = f"{speed * KNOTS_PER_M_S:.3f}"
    kmh = f"{speed * KMH_PER_M_S:.3f}"
    course_s = f"{round(course, 2) % 360.0:.2f}"  # 359.999 -> "0.00", never "360.00"
    mode = _MODE[fix]

    gga = pynmea2.GGA("GP", "GGA", (hhmmss, lat_s, ns, lon_s, ew, str(fix), f"{sats:02d}", f"{dop:.2f}",
                                    f"{alt:.2f}", "M", f"{sep:.2f}", "M", "", ""))
    rmc = pynmea2.RMC("GP", "RMC", (hhmmss, "A" if fix > 0 else "V", lat_s, ns, lon_s, ew, knots, course_s,
                                    ddmmyy, "", "", mode))
    vtg = pynmea2.VTG("GP", "VTG", (course_s, "T", "", "M", knots, "N", kmh, "K", mode))
    return [f"{msg}\r\n" for msg in (gga, rmc, vtg)]


class NmeaGpsWriter:
    """Writes GGA/RMC/VTG to ``port`` at ``rate_hz`` in simulation time, like a GPS receiver on RS-232.

    ``port`` is anything with ``write(bytes)``: a ``serial.Serial`` (see ``open_serial``) or an unbuffered
    file on a pty. Call ``update`` with the simulated state and ``poll`` every simulation step; epoch ``k``
    is due at ``t = k / rate_hz`` (first at t = 0) and is written by the first poll at or after that time.
    Missed epochs are not caught up (no bursts); polls before the first ``update`` write nothing and the
    first poll after it writes at once. If time goes backwards (a simulation reset) the schedule restarts
    from that time. UTC is ``start_utc + t_s`` of the poll (``start_utc`` defaults to the wall clock at
    construction, whole seconds; naive datetimes are taken as UTC).

    Write failures (``OSError``, which includes pyserial's ``SerialException`` and write timeouts, and short
    writes) never raise: they are counted in ``errors`` and kept in ``last_error``, since the autopilot side
    may go away and come back. ``sent`` counts sentences written in full. Not thread-safe.
    """

    def __init__(self, port: WritablePort, rate_hz: float = 5.0, start_utc: datetime | None = None) -> None:
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, numbers.Real) or not 0.0 < rate_hz <= 100.0:
            raise NmeaError(f"rate_hz={rate_hz!r} outside the allowed range (0, 100] Hz")
        self.port = port
        self.rate_hz = float(rate_hz)
        self.start_utc = _utc("start_utc", start_utc) if start_utc is not None else \
            datetime.now(UTC).replace(microsecond=0)
        self.sent = 0
        self.errors = 0
        self.bytes_written = 0
        self.last_error: OSError | None = None
        self._state: dict[str, Any] | None = None
        self._state_t_s: float | None = None
        self._course_deg = 0.0
        self._next_k = 0
        self._last_poll_t: float | None = None

    @property
    def state_time_s(self) -> float | None:
        """Simulation time of the latest ``update``, None before the first."""
        return self._state_t_s

    def update(
        self,
        t_s: float,
        lat_deg: float,
        lon_deg: float,
        alt_msl_m: float,
        vel_north_m_s: float,
        vel_east_m_s: float,
        vel_down_m_s: float,
        fix_quality: int = 1,
        satellites: int = 10,
        hdop: float = 0.8,
    ) -> None:
        """Store the latest state (validated now, so errors surface here rather than in ``poll``).

        Ground speed and course come from the NED velocity; below 1 cm/s the previous course is kept.
        ``vel_down_m_s`` is validated but GGA/RMC/VTG carry no vertical speed.
        """
        if isinstance(t_s, bool) or not isinstance(t_s, numbers.Real) or not math.isfinite(t_s):
            raise NmeaError(f"t_s={t_s!r} is not finite; allowed range: any finite simulation time in s")
        vn = _real("vel_north_m_s", vel_north_m_s)
        ve = _real("vel_east_m_s", vel_east_m_s)
        _real("vel_down_m_s", vel_down_m_s)
        state = {
            "lat_deg": _real("lat_deg", lat_deg),
            "lon_deg": _real("lon_deg", lon_deg),
            "alt_msl_m": _real("alt_msl_m", alt_msl_m),
            "ground_speed_m_s": _real("ground_speed_m_s", math.hypot(vn, ve)),
            "course_deg": self._course_deg,
            "fix_quality": _integer("fix_quality", fix_quality),
            "satellites": _integer("satellites", satellites),
            "hdop": _real("hdop", hdop),
        }
        if state["ground_speed_m_s"] >= _STILL_M_S:
            self._course_deg = state["course_deg"] = math.degrees(math.atan2(ve, vn)) % 360.0
        self._state, self._state_t_s = state, float(t_s)

    def due(self, t_s: float) -> bool:
        """Whether an epoch is due at simulation time ``t_s`` (1 ns tolerance against float steps)."""
        return t_s >= self._next_k / self.rate_hz - 1e-9

    def poll(self, t_s: float) -> int:
        """Write one epoch if due at ``t_s``; returns the number of bytes written (0 if none or on error)."""
        if isinstance(t_s, bool) or not isinstance(t_s, numbers.Real) or not math.isfinite(t_s):
            raise NmeaError(f"t_s={t_s!r} is not finite; allowed range: any finite simulation time in s")
        t = float(t_s)
        if self._last_poll_t is not None and t < self._last_poll_t:  # simulation reset
            self._next_k = max(0, math.ceil(t * self.rate_hz - 1e-6))
        self._last_poll_t = t
        if self._state is None or not self.due(t):
            return 0
        self._next_k = math.floor(t * self.rate_hz + 1e-6) + 1
        lines = nmea_sentences(self.start_utc + timedelta(seconds=t), **self._state)
        data = "".join(lines).encode("ascii")
        try:
            n = self.port.write(data)
        except OSError as exc:
            self.errors += 1
            self.last_error = exc
            return 0
        written = len(data) if n is None else int(n)
        self.bytes_written += written
        if written < len(data):
            self.errors += 1
            self.last_error = OSError(f"short write: {written} of {len(data)} bytes")
            return written
        self.sent += len(lines)
        return written


def open_serial(
    url_or_device: str,
    baudrate: int = 9600,
    *,
    timeout: float | None = 1.0,
    write_timeout: float | None = 1.0,
) -> serial.SerialBase:
    """Open a serial device path (``/dev/ttyUSB0``, a pty slave ``/dev/pts/N``) or a pyserial URL (``loop://``).

    ``timeout`` bounds reads and ``write_timeout`` bounds writes (a stalled reader then gives
    ``serial.SerialTimeoutException``, an ``OSError`` that ``NmeaGpsWriter`` counts), both in seconds.
    """
    return serial.serial_for_url(url_or_device, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout)

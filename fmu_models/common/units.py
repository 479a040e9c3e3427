"""Physical constants and unit conversions, each written once (readers, output maps, HIL packets, models).

``LOG_UNITS`` maps a unit a flight log may record in to ``(SI unit, factor)``: ``SI value = log value * factor``.
(``fmu_models.fmi.units`` parses the project's unit strings into FMI base units; it takes its factors from here.)
"""

from __future__ import annotations

import math

G0_M_S2 = 9.80665  #: standard gravity (CGPM 1901; ISA, "g" and milli-g units) [m/s^2]
DEG_TO_RAD = math.pi / 180.0
RAD_TO_DEG = 180.0 / math.pi
RPM_TO_RAD_S = 2.0 * math.pi / 60.0
CDEG_TO_RAD = DEG_TO_RAD / 100.0  #: centidegrees (ArduPilot attitude fields)
DEGE7_TO_DEG = 1e-7  #: latitude/longitude as int32 degrees * 1e7 (MAVLink, DataFlash, ULog)
FT_TO_M = 0.3048
NMI_M = 1852.0  #: international nautical mile [m]
KN_TO_M_S = NMI_M / 3600.0
KMH_TO_M_S = 1.0 / 3.6

LOG_UNITS: dict[str, tuple[str, float]] = {
    "deg": ("rad", DEG_TO_RAD), "cdeg": ("rad", CDEG_TO_RAD), "deg/s": ("rad/s", DEG_TO_RAD),
    "cm": ("m", 0.01), "mm": ("m", 0.001), "ft": ("m", FT_TO_M), "km": ("m", 1000.0),
    "cm/s": ("m/s", 0.01), "kn": ("m/s", KN_TO_M_S), "km/h": ("m/s", KMH_TO_M_S), "ft/s": ("m/s", FT_TO_M),
    "cm/s2": ("m/s2", 0.01),
    "g": ("m/s2", G0_M_S2), "mG": ("m/s2", G0_M_S2 / 1000.0), "kN": ("N", 1000.0),
}

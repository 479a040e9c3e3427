"""PX4 ULog through pyulog: canonical signals from sensor_combined, vehicle_attitude, actuator_outputs,
vehicle_gps_position, vehicle_local_position and vehicle_status; parameters kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pyulog import ULog

from fmu_models.common.units import DEGE7_TO_DEG
from fmu_models.quadrotor.constants import N_MOTORS
from identification.logs.flightlog import DataQuality, FlightLog, LogError, Signal, add_battery, sanitize_log
from identification.logs.readers.px4_signals import add_imu_and_attitude, add_local_position, add_outputs, alias

ARMING_STATE_ARMED = 2  #: vehicle_status.arming_state value for armed


def _battery(signals: dict[str, Signal]) -> None:
    """battery_status (instance 0): ``voltage_v`` (else ``voltage_filtered_v``) [V], ``current_a`` [A]
    (PX4 logs -1 for an unknown current), also ``voltage_filtered_v`` as ``battery_voltage_filtered_v``."""
    volt = signals.get("battery_status.voltage_v") or signals.get("battery_status.voltage_filtered_v")
    if volt is None:
        return
    curr = signals.get("battery_status.current_a")
    c = None if curr is None else np.where(curr.values == -1.0, np.nan, curr.values)
    add_battery(signals, volt.t_s, volt.values, c, "battery_status")
    filt = signals.get("battery_status.voltage_filtered_v")
    if filt is not None:
        good = np.isfinite(filt.values) & (filt.values > 0)
        if good.any():
            signals["battery_voltage_filtered_v"] = Signal("battery_voltage_filtered_v", filt.t_s[good],
                                                           filt.values[good], "V", "from battery_status")


def _raw_signals(ulog: ULog) -> tuple[dict[str, Signal], list[str]]:
    """``topic[_instance].field`` signals [s from the ULog start]; topics whose format lost its timestamp
    (a damaged definition) and non-numeric fields are skipped."""
    t0 = float(ulog.start_timestamp)
    signals: dict[str, Signal] = {}
    skipped: list[str] = []
    for d in ulog.data_list:
        prefix = d.name if d.multi_id == 0 else f"{d.name}_{d.multi_id}"
        stamps = np.asarray(d.data.get("timestamp", []))
        if stamps.ndim != 1 or stamps.dtype.kind not in "iuf" or not stamps.size:
            skipped.append(prefix)
            continue
        t = (stamps.astype(float) - t0) * 1e-6
        for fld, vals in d.data.items():
            arr = np.asarray(vals)
            if fld != "timestamp" and arr.shape == t.shape and arr.dtype.kind in "iufb":
                key = f"{prefix}.{fld}"
                with np.errstate(invalid="ignore"):  # a damaged float's signalling NaN reads as NaN, no warning
                    signals[key] = Signal(key, t, arr.astype(float), "", f"raw {key}")
    return signals, skipped


def read_ulog(path: Path) -> FlightLog:
    try:
        ulog = ULog(str(path))
    except Exception as err:  # pyulog raises bare Exceptions and struct errors on bad files
        raise LogError(f"{path}: not a readable ULog file ({type(err).__name__}: {err})") from err
    if not ulog.data_list:
        raise LogError(f"{path}: the ULog holds no data messages")
    signals, skipped = _raw_signals(ulog)

    add_imu_and_attitude(signals)
    alias(signals, "lat_deg", "vehicle_gps_position.latitude_deg", "deg")
    alias(signals, "lon_deg", "vehicle_gps_position.longitude_deg", "deg")
    alias(signals, "height_m", "vehicle_gps_position.altitude_msl_m", "m")
    alias(signals, "lat_deg", "vehicle_gps_position.lat", "deg", DEGE7_TO_DEG)
    alias(signals, "lon_deg", "vehicle_gps_position.lon", "deg", DEGE7_TO_DEG)
    alias(signals, "height_m", "vehicle_gps_position.alt", "m", 1e-3)
    for a, full, local in (("n", "north", "vx"), ("e", "east", "vy"), ("d", "down", "vz")):
        # the estimator's fused NED velocity (the altitude's source) before the receiver's raw one
        alias(signals, f"vel_{full}_m_s", f"vehicle_local_position.{local}", "m/s")
        alias(signals, f"vel_{full}_m_s", f"vehicle_gps_position.vel_{a}_m_s", "m/s")
    add_local_position(signals)
    _battery(signals)
    add_outputs(signals, N_MOTORS)  # PX4 quadrotor: motors on the first four actuator outputs
    if "vehicle_status.arming_state" in signals:
        s = signals["vehicle_status.arming_state"]
        signals["armed"] = Signal("armed", s.t_s, (s.values == ARMING_STATE_ARMED).astype(float), "1",
                                  "from vehicle_status.arming_state")
    warnings = [f"{path}: topic(s) {', '.join(skipped)} without a usable timestamp skipped"] if skipped else []
    quality = DataQuality(str(path))
    quality.bytes_total = path.stat().st_size
    quality.messages_total = sum(len(next(iter(d.data.values()), ())) for d in ulog.data_list)
    if getattr(ulog, "file_corruption", False):
        warnings.append(f"{path}: pyulog reports a corrupt section; the readable messages were kept")
        quality.messages_skipped += 1  # pyulog skips to the next sync marker without saying how much
    params = {k: float(v) for k, v in ulog.initial_parameters.items() if isinstance(v, int | float)}
    log = FlightLog(str(path), "ulog", signals, params, "quadrotor" if "motor_1_pwm_us" in signals else None,
                    warnings, boot_s=float(ulog.start_timestamp) * 1e-6)
    return sanitize_log(log, quality)

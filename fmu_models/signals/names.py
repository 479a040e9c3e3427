"""Names shared by every room: which canonical log signal records each FMU output."""

from __future__ import annotations

#: model/FMU outputs a flight log records, and the canonical signal they are logged under (the body rates
#: are the gyro readings; every other name is the same). One table for identification, synthetic logs and the
#: HIL recorder.
OUTPUT_TO_LOG: dict[str, str] = {
    "roll_rad": "roll_rad", "pitch_rad": "pitch_rad", "yaw_rad": "yaw_rad",
    "rate_body_x_rad_s": "gyro_body_x_rad_s", "rate_body_y_rad_s": "gyro_body_y_rad_s",
    "rate_body_z_rad_s": "gyro_body_z_rad_s", "accel_body_x_m_s2": "accel_body_x_m_s2",
    "accel_body_y_m_s2": "accel_body_y_m_s2", "accel_body_z_m_s2": "accel_body_z_m_s2",
    "airspeed_m_s": "airspeed_m_s", "altitude_m": "altitude_m", "vel_north_m_s": "vel_north_m_s",
    "vel_east_m_s": "vel_east_m_s", "vel_down_m_s": "vel_down_m_s", "lat_deg": "lat_deg", "lon_deg": "lon_deg",
}


#: the fixed wing's outputs an output-error fit uses by default: attitude, body rates, specific force and airspeed
#: (what its sensors measure directly; shared by the derivative identification and the excitation check)
FIXED_WING_FIT_OUTPUTS = ("roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
                          "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s")

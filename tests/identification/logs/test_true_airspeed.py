"""The logged airspeed is the equivalent airspeed; the FMUs output the true one: readers convert (ISA)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fmu_models.common.atmosphere import eas_to_tas, isa
from identification.logs.readers import read_log
from tests.conftest import shared_data


def test_eas_to_tas_is_the_isa_density_ratio() -> None:
    assert eas_to_tas(0.0) == pytest.approx(1.0, abs=1e-12)
    # ISA table (ISO 2533): density 1.2250 kg/m3 at sea level, 1.1117 at 1000 m, 0.7364 at 5000 m
    assert eas_to_tas(1000.0) == pytest.approx((1.2250 / 1.1117) ** 0.5, rel=2e-4)
    assert eas_to_tas(5000.0) == pytest.approx((1.2250 / 0.7364) ** 0.5, rel=2e-4)
    h = np.array([-200.0, 0.0, 651.0, 3000.0])
    np.testing.assert_allclose(eas_to_tas(h), [(isa(0.0)[2] / isa(x)[2]) ** 0.5 for x in h], rtol=1e-12)
    assert isinstance(eas_to_tas(651.0), float)  # the HIL loop's scalar path
    assert eas_to_tas(651.0) == pytest.approx(float(eas_to_tas(np.array([651.0]))[0]), rel=1e-14)


def _wing_log(tmp_path: Path, altitude_m: float, gps: bool = True) -> Path:
    from identification.logs.dataflash_writer import write_log

    t = np.arange(50) * 0.1
    streams = {"ARSP": (t, {"I": 0, "Airspeed": 24.0 + 0.1 * t, "U": 1, "H": 1})}
    if gps:
        streams["GPS"] = (t[::5], {"I": 0, "Status": 3, "Lat": -35.0, "Lng": 149.0, "Alt": altitude_m + 0.0 * t[::5],
                                   "Spd": 25.0, "GCrs": 0.0, "VZ": 0.0})
    return write_log(tmp_path / "wing.bin", streams)


def test_dataflash_airspeed_becomes_true_at_the_gps_altitude(tmp_path: Path) -> None:
    log = read_log(_wing_log(tmp_path, 1500.0))
    eas = 24.0 + 0.1 * np.arange(50) * 0.1
    np.testing.assert_allclose(log.signal("airspeed_eas_m_s").values, eas, rtol=1e-6)
    np.testing.assert_allclose(log.signal("airspeed_m_s").values, eas * eas_to_tas(1500.0), rtol=1e-6)
    assert eas_to_tas(1500.0) > 1.07  # the error the conversion removes: 7 % at 1500 m
    assert "height_m" in log.signal("airspeed_m_s").description


@pytest.mark.parametrize("gps", [False, True])
def test_without_an_amsl_altitude_the_airspeed_stays_as_logged_and_says_so(tmp_path: Path, gps: bool) -> None:
    """No altitude above mean sea level logged, or one that is all zeros (a field not filled): kept, named."""
    log = read_log(_wing_log(tmp_path, 0.0, gps=gps))
    np.testing.assert_allclose(log.signal("airspeed_m_s").values, 24.0 + 0.01 * np.arange(50), rtol=1e-6)
    assert not log.has("airspeed_eas_m_s")
    assert any("equivalent airspeed" in w and "ARSP.Airspeed" in w and "kept as logged" in w for w in log.warnings)


def test_synthetic_wing_log_round_trips_the_fmu_true_airspeed(tmp_path: Path) -> None:
    from identification.flights.scenarios import Recording
    from identification.flights.synthetic import write_log

    n = 200
    t = np.arange(n) * 0.01
    const = {"roll_rad": 0.0, "pitch_rad": 0.05, "yaw_rad": 0.3, "rate_body_x_rad_s": 0.0, "rate_body_y_rad_s": 0.0,
             "rate_body_z_rad_s": 0.0, "accel_body_x_m_s2": 0.5, "accel_body_y_m_s2": 0.0,
             "accel_body_z_m_s2": -9.8, "vel_north_m_s": 25.0, "vel_east_m_s": 0.0, "vel_down_m_s": 0.0,
             "lat_deg": -35.0, "lon_deg": 149.0}
    outputs = {k: np.full(n, v) for k, v in const.items()}
    outputs["altitude_m"] = 2000.0 + 2.0 * t  # climbing: the factor follows the altitude sample by sample
    outputs["airspeed_m_s"] = 25.0 + t
    inputs = {"aileron_rad": np.zeros(n), "elevator_rad": np.zeros(n), "rudder_rad": np.zeros(n),
              "throttle": np.full(n, 0.5)}
    log = read_log(write_log(tmp_path / "w.bin", Recording(t, inputs, outputs)))
    a = log.signal("airspeed_m_s")
    # within the altitude held past the last 5 Hz GPS sample (2 m/s x 0.2 s: 2e-5 of the factor)
    np.testing.assert_allclose(a.values, np.interp(a.t_s, t, outputs["airspeed_m_s"]), rtol=3e-5)
    assert log.signal("airspeed_eas_m_s").values[0] < 0.95 * a.values[0]  # what ArduPilot logs at 2000 m


def test_arduplane_sitl_airspeed_matches_the_gps_speed_once_true() -> None:
    """SITL, no wind: its airspeed sensor logs the FMU's true airspeed divided by EAS2TAS at the AMSL altitude
    (about 650 m here, 3 % low); converted, the log's airspeed matches the GPS ground speed to the sensor's ratio
    setting (SIM_ARSPD_RATIO 1.99 against ARSPD_RATIO 2.0: +0.25 %) within the GPS lag's scatter."""
    log = read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN"))
    assert log.params.get("SIM_WIND_SPD") == 0.0
    a = log.signal("airspeed_m_s")
    g = np.sqrt(sum(log.signal(f"vel_{c}_m_s").resample(a.t_s) ** 2 for c in ("north", "east", "down")))
    ok = g > 15.0
    assert np.median(log.signal("airspeed_eas_m_s").values[ok] / g[ok]) < 0.975
    assert np.median(a.values[ok] / g[ok]) == pytest.approx(1.0025, abs=0.004)

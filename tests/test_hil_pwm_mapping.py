"""PWM mapping: trim/min/max, reversal, deadband, throttle, ArduPilot params, bad configs and pulses."""

from __future__ import annotations

import math

import pytest

from fmu_models.signals.pwm_mapping import Channel, MappingError, PwmMapping
from tests.conftest import shared_data


def test_surface_trim_min_max_reversed_and_deadband() -> None:
    ail = Channel("aileron_rad", 1, 1100, 1500, 1900, -0.35, 0.35, deadband_us=5)
    assert ail.to_input(1500) == 0.0 and ail.to_input(1504) == 0.0
    assert ail.to_input(1900) == pytest.approx(0.35) and ail.to_input(1100) == pytest.approx(-0.35)
    assert ail.to_input(1700) == pytest.approx(0.175) and ail.to_input(2100) == pytest.approx(0.35)
    rev = Channel("aileron_rad", 1, 1100, 1500, 1900, -0.35, 0.35, reversed=True)
    assert rev.to_input(1900) == pytest.approx(-0.35)


def test_throttle_is_one_sided() -> None:
    thr = Channel("throttle", 3, 1000, 1000, 2000, 0.0, 1.0)
    assert thr.to_input(1000) == 0.0 and thr.to_input(1500) == 0.5 and thr.to_input(2000) == 1.0


def test_nan_and_implausible_pulses_are_errors() -> None:
    ch = Channel("throttle", 3, 1000, 1000, 2000, 0.0, 1.0)
    for bad in (math.nan, 0.0, 3000.0):
        with pytest.raises(MappingError, match="channel 3 \\(throttle\\)"):
            ch.to_input(bad)


def test_config_errors_list_every_problem(tmp_path) -> None:
    f = tmp_path / "m.toml"
    f.write_text("[channels.aileron_rad]\nsource = 40\nmin_us = 1900\ntrim_us = 1500\nmax_us = 1100\n"
                 "[channels.throttle]\nsource = 3\nout_min = 1.0\nout_max = 0.0\n")
    with pytest.raises(MappingError) as err:
        PwmMapping.load(f)
    text = str(err.value)
    assert str(f) in text and "source = 40" in text and "min_us <= trim_us" in text and "out_min 1.0" in text


def test_from_ardupilot_params_of_the_sitl_plane_log() -> None:
    from identification.readers import read_log

    log = read_log(shared_data("fixed_wing", "arduplane_sitl_takeoff_00000012.BIN"))
    m = PwmMapping.from_ardupilot(log.params)
    assert {c.target for c in m.channels} == {"aileron_rad", "elevator_rad", "rudder_rad", "throttle"}
    trims = {c.source: c.trim_us for c in m.channels}
    out = m.apply({n: trims[n] for n in trims})
    assert out["aileron_rad"] == 0.0 and out["throttle"] == 0.0


def test_ardupilot_convention_pull_is_nose_up_right_rudder_nose_right() -> None:
    """ArduPilot (SIM_Plane: c_m_deltae, c_n_deltar > 0 on (pwm - trim)) and PX4 (FRD torque demands): PWM
    above trim is nose up / nose right; the FMU's uavbook elevator and rudder are positive nose down / left."""
    from fmu_models.signals.pwm_mapping import ardupilot_servo_reversed, default_mapping

    params = {"SERVO1_FUNCTION": 4, "SERVO2_FUNCTION": 19, "SERVO3_FUNCTION": 70, "SERVO4_FUNCTION": 21}
    for m in (PwmMapping.from_ardupilot(params), default_mapping("fixed_wing")):
        out = m.apply({1: 1700.0, 2: 1700.0, 3: 1500.0, 4: 1700.0})
        assert out["aileron_rad"] > 0 and out["elevator_rad"] < 0 and out["rudder_rad"] < 0
        assert all(not ardupilot_servo_reversed(c) for c in m.channels)
    flipped = PwmMapping.from_ardupilot(params | {"SERVO2_REVERSED": 1, "SERVO1_REVERSED": 1})
    out = flipped.apply({1: 1700.0, 2: 1700.0, 3: 1500.0, 4: 1500.0})
    assert out["aileron_rad"] < 0 and out["elevator_rad"] > 0


def test_mapping_schema_names_file_field_value_and_range(tmp_path) -> None:
    from fmu_models.config import ConfigError

    f = tmp_path / "m.toml"
    f.write_text('[channels.elevator_rad]\nsource = 2\nmin_us = "1100"\nreversed = 1\ndeadband_us = -3\n'
                 "trim_us = nan\n")
    with pytest.raises(ConfigError) as err:
        PwmMapping.load(f)
    text = str(err.value)
    assert str(f) in text and len(err.value.problems) == 4, text
    assert "channels.elevator_rad.min_us = '1100'" in text and "channels.elevator_rad.reversed = 1" in text
    assert "deadband_us = -3" in text and ">= 0" in text and "trim_us" in text
    with pytest.raises(MappingError):  # still caught as a MappingError by the adapter
        PwmMapping.from_dict({"channels": {"throttle": {"source": 3, "unknown": 1}}})


def test_px4_pitch_up_and_yaw_right_controls_reach_the_fmu_as_nose_up_and_nose_right() -> None:
    """PX4 control group 0 (FRD torque demands: + pitch = nose up, + yaw = nose right) through the adapter's
    controls -> PWM assignment and the default mapping: uavbook elevator and rudder come out negative."""
    from fmu_models.signals.pwm_mapping import default_mapping
    from hil_adapter.px4 import controls_to_pwm

    pwm = controls_to_pwm([0.5, 0.5, 0.5, 0.7] + [0.0] * 12, "fixed_wing", True)
    out = default_mapping("fixed_wing").apply(pwm)
    assert out["aileron_rad"] > 0 and out["elevator_rad"] < 0 and out["rudder_rad"] < 0
    assert out["throttle"] == pytest.approx(0.7)

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
    from identification.logs.readers import read_log

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


# ------------------------------------------------------------------ inverse mapping, file checks, ArduPilot
CHANNELS = [
    Channel("aileron_rad", 1, 1100.0, 1500.0, 1900.0, -0.35, 0.35),
    Channel("elevator_rad", 2, 1000.0, 1400.0, 2000.0, -0.2, 0.5, reversed=True),  # asymmetric both ways
    Channel("throttle", 3, 1000.0, 1000.0, 2000.0, 0.0, 1.0),
    Channel("throttle", 4, 1100.0, 1100.0, 1900.0, 0.1, 0.9, reversed=True),
]


@pytest.mark.parametrize("ch", CHANNELS, ids=lambda c: f"{c.target}-{c.source}")
def test_to_pwm_inverts_to_input_and_clips(ch: Channel) -> None:
    for v in (ch.out_min, 0.5 * ch.out_min + 0.5 * ch.out_max, 0.3 * ch.out_max, 0.6 * ch.out_min, ch.out_max):
        v = min(max(v, ch.out_min), ch.out_max)
        pwm = ch.to_pwm(v)
        assert ch.min_us <= pwm <= ch.max_us
        assert ch.to_input(pwm) == pytest.approx(v, abs=1e-12), (v, pwm)
    ends = (ch.max_us, ch.min_us) if ch.reversed else (ch.min_us, ch.max_us)
    assert ch.to_pwm(ch.out_min - 5.0) == pytest.approx(ends[0])  # clipped to the channel's range
    assert ch.to_pwm(ch.out_max + 5.0) == pytest.approx(ends[1])


def test_to_pwm_by_hand() -> None:
    ail, elev, thr, rev = CHANNELS
    assert ail.to_pwm(0.0) == 1500.0 and ail.to_pwm(0.175) == pytest.approx(1700.0)
    assert ail.to_pwm(-0.175) == pytest.approx(1300.0)
    assert elev.to_pwm(0.25) == pytest.approx(1400.0 - 0.5 * 400.0)  # reversed: positive input below trim
    assert elev.to_pwm(-0.1) == pytest.approx(1400.0 + 0.5 * 600.0)
    assert thr.to_pwm(0.25) == pytest.approx(1250.0)
    assert rev.to_pwm(0.1) == pytest.approx(1900.0) and rev.to_pwm(0.7) == pytest.approx(1300.0)


@pytest.mark.parametrize(("fields", "words"), [
    ({"min_us": 1600.0}, "need min_us <= trim_us <= max_us and min_us < max_us (got 1600.0, 1500.0, 2000.0)"),
    ({"max_us": 1400.0}, "need min_us <= trim_us <= max_us and min_us < max_us (got 1000.0, 1500.0, 1400.0)"),
    ({"min_us": 1500.0, "trim_us": 1500.0, "max_us": 1500.0},
     "need min_us <= trim_us <= max_us and min_us < max_us (got 1500.0, 1500.0, 1500.0)"),
    ({"out_min": 0.5, "out_max": 0.5}, "out_min 0.5 must be below out_max 0.5"),
    ({"out_min": 1.0}, "out_min 1.0 must be below out_max 1.0"),
])
def test_order_problems_name_channel_and_values(fields: dict, words: str) -> None:
    from fmu_models.signals.pwm_mapping import MappingConfigError

    with pytest.raises(MappingConfigError) as err:
        PwmMapping.from_dict({"channels": {"aileron_rad": {"source": 1, **fields}}}, source="m.toml")
    assert err.value.problems == [f"field channels.aileron_rad: {words}"]
    assert str(err.value).startswith("m.toml")


def test_order_checks_accept_edges_and_skip_what_the_schema_refuses() -> None:
    from fmu_models.signals.pwm_mapping import MappingConfigError

    ok = PwmMapping.from_dict({"throttle": {"source": 3, "min_us": 1000.0, "trim_us": 1000.0, "max_us": 1001.0,
                                            "out_min": 0.0, "out_max": 1e-9}})  # bare tables, tight bounds
    assert ok.channels[0].target == "throttle" and ok.channels[0].max_us == 1001.0
    with pytest.raises(MappingConfigError) as err:
        PwmMapping.from_dict({"channels": {"x": {"source": 1, "min_us": "low", "out_max": True}}})
    assert not any("need min_us" in p or "must be below" in p for p in err.value.problems), err.value.problems
    assert any("min_us" in p for p in err.value.problems) and any("out_max" in p for p in err.value.problems)


def test_from_dict_refuses_non_tables_and_unknown_keys() -> None:
    from fmu_models.signals.pwm_mapping import MappingConfigError

    with pytest.raises(MappingConfigError, match=r"(?s)^src: .*\(top level\) = \[1\]: must be a table"):
        PwmMapping.from_dict([1], source="src")  # type: ignore[arg-type]
    with pytest.raises(MappingConfigError, match=r"(?s)^src: .*field channels = 3: must be a table"):
        PwmMapping.from_dict({"channels": 3}, source="src")
    with pytest.raises(MappingConfigError) as err:
        PwmMapping.from_dict({"channels": {"a": {"source": 1, "min_us": 1600.0}}, "extra": 1}, source="src")
    assert len(err.value.problems) == 2 and any("extra" in p for p in err.value.problems)


def test_load_names_the_file(tmp_path) -> None:
    from fmu_models.signals.pwm_mapping import MappingConfigError

    good = tmp_path / "good.toml"
    good.write_text('[channels.throttle]\nsource = 3\nmin_us = 1000\ntrim_us = 1000\nout_min = 0.0\n')
    m = PwmMapping.load(good)
    assert [(c.target, c.source, c.min_us, c.max_us) for c in m.channels] == [("throttle", 3, 1000.0, 2000.0)]
    bad = tmp_path / "bad.toml"
    bad.write_text("[channels\n")
    with pytest.raises(MappingConfigError, match=r"(?s)bad.toml.*cannot read mapping"):
        PwmMapping.load(bad)
    with pytest.raises(MappingConfigError, match=r"(?s)missing.toml.*cannot read mapping"):
        PwmMapping.load(tmp_path / "missing.toml")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text("[channels.throttle]\nsource = 99\n")
    with pytest.raises(MappingConfigError, match=r"wrong.toml"):
        PwmMapping.load(wrong)


def test_from_ardupilot_fields_by_hand() -> None:
    from fmu_models.signals.pwm_mapping import ardupilot_servo_reversed

    m = PwmMapping.from_ardupilot({
        "SERVO1_FUNCTION": 4, "SERVO1_MIN": 1000, "SERVO1_MAX": 2000, "SERVO1_TRIM": 1450,
        "SERVO2_FUNCTION": 19, "SERVO2_REVERSED": 1,  # MIN/MAX/TRIM defaults: 1100, 1900, their middle
        "SERVO3_FUNCTION": 70, "SERVO3_MIN": 1050, "SERVO3_TRIM": 1500,  # throttle: trim is its minimum
        "SERVO5_FUNCTION": 33,  # a motor: not a surface, left out
        "SERVO32_FUNCTION": 21,  # the last output counts too
    }, surface_limit_rad=0.3)
    got = {c.target: c for c in m.channels}
    assert [c.source for c in m.channels] == [1, 2, 3, 32]
    assert got["aileron_rad"] == Channel("aileron_rad", 1, 1000, 1450, 2000, -0.3, 0.3, False)
    assert got["elevator_rad"] == Channel("elevator_rad", 2, 1100.0, 1500.0, 1900.0, -0.3, 0.3, False)
    assert got["throttle"] == Channel("throttle", 3, 1050, 1050, 1900.0, 0.0, 1.0, False)
    assert got["rudder_rad"] == Channel("rudder_rad", 32, 1100.0, 1500.0, 1900.0, -0.3, 0.3, True)
    # the log's SERVOn_REVERSED comes back from the mapping
    assert [ardupilot_servo_reversed(got[t]) for t in ("aileron_rad", "elevator_rad", "throttle", "rudder_rad")] \
        == [False, True, False, False]
    assert ardupilot_servo_reversed(Channel("pwm_1_us", 1, reversed=True)) is True
    with pytest.raises(MappingError, match=r"no SERVOn_FUNCTION for aileron \(4\), elevator \(19\), rudder \(21\)"):
        PwmMapping.from_ardupilot({"SERVO1_FUNCTION": 33, "SERVO33_FUNCTION": 4})


def test_to_input_edges_by_hand() -> None:
    ail = Channel("aileron_rad", 1, 1100.0, 1500.0, 1900.0, -0.35, 0.35, deadband_us=20.0)
    assert ail.to_input(500.0) == -0.35 and ail.to_input(2500.0) == 0.35  # plausible extremes, clipped
    for bad in (499.9, 2500.1, math.nan):
        with pytest.raises(MappingError, match=r"^channel 1 \(aileron_rad\): PWM .* us outside \[500.0, 2500.0\] us$"):
            ail.to_input(bad)
    assert ail.to_input(1480.0) == 0.0 and ail.to_input(1520.0) == 0.0  # exactly at the deadband's edge
    assert ail.to_input(1521.0) == pytest.approx(0.35 * 21 / 400)
    thr = Channel("throttle", 3, 1000.0, 1500.0, 2000.0, 0.0, 1.0)  # out_min 0: one-sided whatever the trim
    assert thr.to_input(1500.0) == 0.5 and thr.to_input(1000.0) == 0.0
    low_trim = Channel("pwm_1_us", 1, 1000.0, 1000.0, 2000.0, -1.0, 1.0)  # trim at min: one-sided too
    assert low_trim.to_input(1000.0) == -1.0 and low_trim.to_input(1500.0) == 0.0
    top_trim = Channel("elevator_rad", 2, 1000.0, 2000.0, 2000.0, -1.0, 1.0)  # no travel above trim
    assert top_trim.to_input(2000.0) == 0.0 and top_trim.to_input(1500.0) == -0.5


def test_apply_failsafe_and_missing_channels() -> None:
    m = PwmMapping((Channel("throttle", 3, 1000.0, 1000.0, 2000.0, 0.0, 1.0, failsafe=0.0),
                    Channel("aileron_rad", 1, failsafe=0.1)))
    assert m.apply({3: 1500, 1: 1500}) == {"throttle": 0.5, "aileron_rad": 0.0}
    assert m.apply({}, failsafe=True) == {"throttle": 0.0, "aileron_rad": 0.1}
    with pytest.raises(MappingError, match=r"^channel 1 \(aileron_rad\) is not in the received outputs$"):
        m.apply({3: 1500})


def test_mapping_defaults_by_hand() -> None:
    from fmu_models.signals.pwm_mapping import MappingConfigError, ardupilot_servo_reversed, default_mapping

    quad = default_mapping("quadrotor").channels
    assert quad == tuple(Channel(f"pwm_{k}_us", k, 1000.0, 1000.0, 2000.0, 1000.0, 2000.0, failsafe=1000.0)
                         for k in range(1, 5))
    wing = {c.target: c for c in default_mapping("fixed_wing").channels}
    assert wing["aileron_rad"] == Channel("aileron_rad", 1, 1100.0, 1500.0, 1900.0, -0.35, 0.35)
    assert wing["elevator_rad"] == Channel("elevator_rad", 2, 1100.0, 1500.0, 1900.0, -0.35, 0.35, reversed=True)
    assert wing["throttle"] == Channel("throttle", 3, 1000.0, 1000.0, 2000.0, 0.0, 1.0)
    assert wing["rudder_rad"] == Channel("rudder_rad", 4, 1100.0, 1500.0, 1900.0, -0.35, 0.35, reversed=True)
    assert ardupilot_servo_reversed(Channel("pwm_1_us", 1)) is False  # not a surface: no convention to undo
    assert PwmMapping.from_ardupilot({"SERVO0_FUNCTION": 21, "SERVO1_FUNCTION": 4}).channels == (
        Channel("aileron_rad", 1, 1100.0, 1500.0, 1900.0, -0.35, 0.35),)  # no SERVO0; default limit 0.35 rad
    with pytest.raises(MappingError, match=r"^no SERVOn_FUNCTION for aileron \(4\), elevator \(19\), rudder \(21\) "
                                           r"or throttle \(70\)$"):
        PwmMapping.from_ardupilot({})
    with pytest.raises(MappingConfigError, match=r"^mapping: "):  # the default source name
        PwmMapping.from_dict({"channels": {"a": {"source": 99}}})
    edge = PwmMapping.from_dict({"a": {"source": 1, "trim_us": 2000.0}})  # trim at max is allowed
    assert edge.channels[0].trim_us == 2000.0
    with pytest.raises(MappingConfigError) as err:  # out_min left at its default -1
        PwmMapping.from_dict({"a": {"source": 1, "out_max": -1.5}})
    assert err.value.problems == ["field channels.a: out_min -1.0 must be below out_max -1.5"]

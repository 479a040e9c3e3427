"""The autopilot parameter files shipped in autopilot/: well-formed, and consistent with the FMUs and the
adapter's default PWM mapping (X frame for the X quadrotor, SERVO outputs as the mapping reads them, an
ArduPlane minimum airspeed the Aerosonde FMU can trim with its surface range)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fmu_models.signals.pwm_mapping import PwmMapping, default_mapping

AUTOPILOT = Path(__file__).resolve().parents[1] / "autopilot"
NAME = re.compile(r"^[A-Z][A-Z0-9_]{0,15}$")  # ArduPilot and PX4 parameter names: at most 16 characters


def ardupilot_params(name: str) -> dict[str, float]:
    params: dict[str, float] = {}
    for line in (AUTOPILOT / "ardupilot" / name).read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, value = line.split()
        assert NAME.match(key), key
        assert key not in params, f"{key} twice"
        params[key] = float(value)
    return params


def test_copter_is_an_x_frame_spinning_above_the_fmu_idle() -> None:
    from fmu_models.quadrotor.params import QuadrotorParams

    p = ardupilot_params("copter-f450-x.parm")
    assert p["FRAME_CLASS"] == 1 and p["FRAME_TYPE"] == 1  # quad, X
    idle_us = QuadrotorParams().pwm_idle_us
    spin_arm_us = p["MOT_PWM_MIN"] + p["MOT_SPIN_ARM"] * (p["MOT_PWM_MAX"] - p["MOT_PWM_MIN"])
    assert spin_arm_us > idle_us and p["MOT_SPIN_MIN"] > p["MOT_SPIN_ARM"]
    assert (p["MOT_PWM_MIN"], p["MOT_PWM_MAX"]) == (1000, 2000)  # what the default mapping passes through


def test_plane_outputs_match_the_adapter_mapping_and_its_speeds_can_be_trimmed() -> None:
    from fmu_models.common.simulate import Simulator
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.trim import trim

    p = ardupilot_params("plane-aerosonde.parm")
    mapping = PwmMapping.from_ardupilot(p)
    default = default_mapping("fixed_wing")
    assert {(c.target, c.source, c.min_us, c.trim_us, c.max_us, c.reversed) for c in mapping.channels} == {
        (c.target, c.source, c.min_us, c.trim_us, c.max_us, c.reversed) for c in default.channels}
    sim = Simulator(FixedWingModel())
    limit = max(c.out_max for c in default.channels if c.target == "elevator_rad")
    slowest = trim(sim.model, sim.params(), p["AIRSPEED_MIN"])
    assert abs(slowest.elevator_rad) < limit  # the autopilot never asks for a speed the surfaces cannot hold
    cruise = trim(sim.model, sim.params(), p["AIRSPEED_CRUISE"])
    assert p["TRIM_THROTTLE"] / 100 == pytest.approx(cruise.throttle, abs=0.02)
    assert p["AIRSPEED_MIN"] < p["AIRSPEED_CRUISE"] < p["AIRSPEED_MAX"]


def test_px4_params_are_param_set_default_lines() -> None:
    lines = [ln for ln in (AUTOPILOT / "px4" / "px4-rc.params").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    assert lines
    for ln in lines:
        cmd, verb, key, value = ln.split()
        assert (cmd, verb) == ("param", "set-default") and NAME.match(key)
        float(value)


def test_landing_mission_takes_off_first_and_lands_last() -> None:
    rows = (AUTOPILOT / "ardupilot" / "aerosonde-circuit.waypoints").read_text().splitlines()
    assert rows[0] == "QGC WPL 110"
    items = [r.split("\t") for r in rows[1:]]
    assert [int(i[0]) for i in items] == list(range(len(items))) and all(len(i) == 12 for i in items)
    commands = [int(i[3]) for i in items]
    assert commands[1] == 22 and commands[-1] == 21  # MAV_CMD_NAV_TAKEOFF ... MAV_CMD_NAV_LAND

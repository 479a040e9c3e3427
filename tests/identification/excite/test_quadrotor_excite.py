"""Quadrotor excitation: plan timings follow the model's rate dynamics, the written steps and SystemId parameters
parse back within their ranges, and the closed-loop check tells a plan that moves every axis from one that does not."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fmu_models.quadrotor.params import QuadrotorParams
from identification.estimation.identifiability import CONDITION_LIMIT
from identification.estimation.oem import RELATIVE_STD_WARN
from identification.excite.design import ExciteError, spectrum_centre
from identification.excite.quadrotor import (
    AXES,
    PX4_LOOPS,
    QuadExcitationPlan,
    QuadExciteOptions,
    axis_loops,
    hover_point,
    plan_quadrotor_excitation,
)
from identification.excite.quadrotor_check import (
    DRAG_SET,
    QuadFlight,
    QuadSetCheck,
    check_quadrotor_plan,
    check_set,
    fly_closed_loop,
)
from identification.excite.quadrotor_workflow import excite_quadrotor, write_files
from identification.excite.quadrotor_writers import (
    MANUAL_CONTROL_LIMITS,
    SID_RANGES,
    QuadOutputOptions,
    manual_control,
    rc_override,
    sid_parameters,
)
from uavfmu.commands import excite as excite_command

#: fine timing so that pulse widths are not rounded to the same sample
FINE = QuadExciteOptions(rate_hz=400.0, min_pulse_s=0.02, max_frequency_hz=50.0)
SHORT = dict(inputs=("doublet", "drag"), settle_s=0.5, tail_s=2.0, recovery_s=2.0)


def _params(**values: float) -> QuadrotorParams:
    return dataclasses.replace(QuadrotorParams(), **values)


def _units(plan: QuadExcitationPlan) -> dict[tuple[str, str], float]:
    return {(b.input, b.axis): b.pulse_unit_s for b in plan.blocks}


def test_roll_and_yaw_effectiveness_follow_the_inertia_and_the_yaw_torque() -> None:
    """Angular acceleration per unit command is moment / inertia: halving Jx doubles the roll effectiveness and
    leaves pitch alone; doubling the fan torque constant b doubles the yaw effectiveness."""
    base = hover_point(QuadrotorParams(), PX4_LOOPS)
    light = hover_point(_params(Jx_kg_m2=0.0035), PX4_LOOPS)
    torque = hover_point(_params(b_drag_N_m_s2=2 * QuadrotorParams().b_drag_N_m_s2), PX4_LOOPS)
    assert light.effectiveness["roll"] == pytest.approx(2 * base.effectiveness["roll"], rel=1e-6)
    assert light.effectiveness["pitch"] == pytest.approx(base.effectiveness["pitch"], rel=1e-9)
    assert torque.effectiveness["yaw"] == pytest.approx(2 * base.effectiveness["yaw"], rel=1e-3)
    # hover: the four motors carry the weight
    assert 1100.0 < base.pwm_us < 2000.0 and base.collective_m_s2 > 0


def test_loop_natural_frequencies_match_the_closed_forms() -> None:
    """A P rate loop on an integrator closes as K P / (s + K P): 45 deg lag at K P; an angle P loop Ka around it
    gives Ka K P / (s^2 + K P s + Ka K P): 90 deg lag at its natural frequency sqrt(Ka K P)."""
    loops = dataclasses.replace(PX4_LOOPS, rate_i=(0.0, 0.0, 0.0), rate_d=(0.0, 0.0, 0.0))
    hover = hover_point(QuadrotorParams(), loops)
    lp = axis_loops(hover, loops, 0.0)["roll"]
    kp = hover.effectiveness["roll"] * loops.rate_p[0]
    assert lp.rate_bandwidth_rad_s == pytest.approx(kp, rel=0.01)
    assert lp.bandwidth_rad_s == pytest.approx(math.sqrt(loops.angle_p[0] * kp), rel=0.01)


def test_faster_roll_dynamics_give_shorter_roll_pulses_and_slower_yaw_longer_yaw_pulses() -> None:
    base = plan_quadrotor_excitation(QuadrotorParams(), FINE)
    light = plan_quadrotor_excitation(_params(Jx_kg_m2=0.0035), FINE)
    heavy_yaw = plan_quadrotor_excitation(_params(Jz_kg_m2=0.05), FINE)
    laggy = plan_quadrotor_excitation(_params(tau_motor_s=0.06), FINE)
    b, lt, hy, lg = _units(base), _units(light), _units(heavy_yaw), _units(laggy)
    for kind in ("3211", "doublet"):
        assert lt[(kind, "roll")] < b[(kind, "roll")]
        assert lt[(kind, "pitch")] == b[(kind, "pitch")]
        assert hy[(kind, "yaw")] > b[(kind, "yaw")]
        assert lg[(kind, "yaw")] > b[(kind, "yaw")]  # motor lag slows the yaw-rate loop
    # the pulse puts the input spectrum's centre on the axis's natural frequency (the fixed-wing rule)
    for blk in base.blocks:
        if blk.input == "drag":
            continue
        w = base.targets_rad_s[blk.axis]
        assert blk.pulse_unit_s == pytest.approx(spectrum_centre((1, -1) if blk.input == "doublet" else
                                                                 (1, 1, 1, -1, -1, 1, -1)) / w, abs=0.5 / FINE.rate_hz)


def test_drag_doublets_are_timed_by_the_translational_mode() -> None:
    """A drag doublet's unit puts the doublet's spectrum centre on kd / m (held at most max_hold_s): the F450's
    0.25 N s/m over 1.14 kg (0.22 rad/s) needs more than 3 s, so it is held 3 s; 2 N s/m gives 1.75 rad/s."""
    base = _units(plan_quadrotor_excitation(None, FINE))
    draggy = _units(plan_quadrotor_excitation(_params(kd_x_N_s_m=2.0), FINE))
    assert base[("drag", "pitch")] == FINE.max_hold_s and ("drag", "yaw") not in base
    centre = spectrum_centre((1, -1))
    assert draggy[("drag", "pitch")] == pytest.approx(centre * QuadrotorParams().mass_kg / 2.0, abs=0.5 / FINE.rate_hz)
    assert draggy[("drag", "roll")] == base[("drag", "roll")]  # roll tilts along y: kd_y unchanged


def test_stick_amplitudes_keep_the_linear_response_within_the_limits() -> None:
    opt = QuadExciteOptions(roll_limit_deg=20.0, attitude_fraction=0.5)
    plan = plan_quadrotor_excitation(None, opt)
    for b in plan.blocks:
        stick = b.signals[b.axis].peak_rad()
        assert 0.0 < stick <= opt.max_stick + 1e-12
        if b.axis in ("roll", "pitch"):
            assert b.predicted_peak_deg["tilt_deg"] <= 10.0 + 1e-9
        if b.axis == "throttle":
            assert stick > plan.loops.throttle_deadzone  # outside altitude hold's deadzone
        if b.input == "drag" and b.axis != "throttle":
            assert b.predicted_peak_deg["speed_m_s"] <= opt.speed_limit_m_s + 1e-9


def test_bad_options_are_refused_with_the_allowed_values() -> None:
    with pytest.raises(ExciteError, match="autopilot: 'inav' unknown; allowed px4, ardupilot"):
        plan_quadrotor_excitation(None, QuadExciteOptions(autopilot="inav"))
    with pytest.raises(ExciteError, match="multisine"):
        plan_quadrotor_excitation(None, QuadExciteOptions(inputs=("multisine",)))
    with pytest.raises(ExciteError, match=r"rate_hz = 25.0; allowed range \[50.0, 400.0\] Hz"):
        plan_quadrotor_excitation(None, QuadExciteOptions(rate_hz=25.0))
    with pytest.raises(ExciteError, match="cannot hover"):
        plan_quadrotor_excitation(_params(mass_kg=20.0), QuadExciteOptions())


def test_manual_control_rows_parse_back_within_mavlink_ranges_with_the_planned_sticks() -> None:
    plan = plan_quadrotor_excitation(None, QuadExciteOptions())
    out = QuadOutputOptions(rc_rate_hz=50.0)
    data = json.loads(json.dumps(manual_control(plan, out)))
    rows = data["rows"]
    t = np.array([r["t_s"] for r in rows])
    sticks = plan.sticks(t)
    for field, (lo, hi) in MANUAL_CONTROL_LIMITS.items():
        values = np.array([r[field] for r in rows])
        assert values.min() >= lo and values.max() <= hi, field
    assert [r["y"] for r in rows] == [round(1000 * v) for v in sticks[:, 0]]  # roll right = +y
    assert [r["x"] for r in rows] == [round(-1000 * v) for v in sticks[:, 1]]  # nose up = stick back = -x
    assert [r["r"] for r in rows] == [round(1000 * v) for v in sticks[:, 2]]
    assert [r["z"] for r in rows] == [round(500 + 500 * v) for v in sticks[:, 3]]  # centred throttle = 500
    for b in plan.blocks:  # each block moves its own stick only, from its excitation start
        inside = (t >= b.start_s) & (t < b.end_s)
        block_rows = [r for r, k in zip(rows, inside, strict=True) if k]
        moved = {f for f in "xyrz" if any(r[f] != (500 if f == "z" else 0) for r in block_rows)}
        assert moved == {{"roll": "y", "pitch": "x", "yaw": "r", "throttle": "z"}[b.axis]}
        first = t[np.flatnonzero(inside & (np.abs(sticks[:, AXES.index(b.axis)]) > 0))[0]]
        assert first == pytest.approx(b.excitation_start_s, abs=1.0 / out.rc_rate_hz)
    assert data["modes"] == {"excite": "ALTCTL", "recover": "POSCTL"}


def test_rc_override_rows_stay_within_the_channel_range_with_arducopter_signs() -> None:
    plan = plan_quadrotor_excitation(None, QuadExciteOptions(autopilot="ardupilot"))
    data = rc_override(plan, QuadOutputOptions())
    lo, hi = data["range_us"]
    t = np.array([r["t_s"] for r in data["rows"]])
    sticks = plan.sticks(t)
    pwm = np.array([[r["pwm_us"][str(c)] for c in (1, 2, 3, 4)] for r in data["rows"]])
    assert lo == 1000 and hi == 2000 and pwm.min() >= lo and pwm.max() <= hi
    assert np.array_equal(pwm[:, 1], np.round(1500 + 500 * sticks[:, 1]))  # ch2: pitch back (nose up) = high PWM
    assert np.array_equal(pwm[:, 2], np.round(1500 + 500 * sticks[:, 3]))  # ch3: throttle, mid holds altitude
    assert pwm[:, 0].max() > 1500 and pwm[:, 0].min() < 1500  # roll both ways


def _parse_parm(text: str) -> dict[str, float]:
    out = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, value = line.split()
            out[name] = float(value)
    return out


@pytest.mark.parametrize("injection", ["mixer", "rate"])
def test_systemid_parameters_parse_back_within_arducopter_ranges(injection: str) -> None:
    plan = plan_quadrotor_excitation(_params(tau_motor_s=0.03), QuadExciteOptions(autopilot="ardupilot"))
    files = sid_parameters(plan, QuadOutputOptions(sid_injection=injection))
    assert set(files) == set(AXES)
    axes = {}
    for axis, text in files.items():
        v = _parse_parm(text)
        assert set(v) == {"SID_MAGNITUDE", *SID_RANGES}
        for name, (lo, hi) in SID_RANGES.items():
            assert lo <= v[name] <= hi, (axis, name, v[name])
        assert v["SID_F_START_HZ"] < v["SID_F_STOP_HZ"]
        assert v["SID_T_REC"] > 2.0 / v["SID_F_START_HZ"]  # the mode's own check (time_record > 2 / f_start)
        assert v["SID_T_FADE_IN"] + v["SID_T_FADE_OUT"] < v["SID_T_REC"]
        assert v["SID_MAGNITUDE"] > 0
        if v["SID_AXIS"] >= 10:
            assert v["SID_MAGNITUDE"] <= 1.0  # mixer units
        axes[axis] = int(v["SID_AXIS"])
    expected = {"mixer": {"roll": 10, "pitch": 11, "yaw": 12, "throttle": 13},
                "rate": {"roll": 7, "pitch": 8, "yaw": 9, "throttle": 13}}[injection]
    assert axes == expected
    # the band comes from the model: a slower airframe starts its chirp lower
    slow = plan_quadrotor_excitation(_params(Jx_kg_m2=0.03, tau_motor_s=0.03), QuadExciteOptions(autopilot="ardupilot"))
    slow_roll = _parse_parm(sid_parameters(slow, QuadOutputOptions(sid_injection=injection))["roll"])
    assert slow_roll["SID_F_START_HZ"] < _parse_parm(files["roll"])["SID_F_START_HZ"]


@pytest.fixture(scope="module")
def good_check() -> tuple[QuadExcitationPlan, QuadFlight, dict[str, QuadSetCheck]]:
    plan = plan_quadrotor_excitation(None, QuadExciteOptions(**SHORT))
    return plan, *check_quadrotor_plan(plan, compile=False)


def test_check_of_a_plan_moving_every_axis_is_well_conditioned_and_flies_within_limits(good_check) -> None:
    plan, flight, checks = good_check
    assert set(checks) == {"rotation", "drag"}
    for key, c in checks.items():
        print(f"test plan {key}: {c.line()}")  # the figures docs/excitation.md quotes (pytest -s)
        assert math.isfinite(c.condition_number) and c.condition_number < CONDITION_LIMIT
        assert c.ok, c.line()
    assert max(checks["rotation"].relative_std.values()) < 0.01  # inertia, lag and yaw torque: well below 1 %
    assert max(checks["drag"].relative_std.values()) < 0.1  # the drag doublets
    assert flight.max_tilt_deg <= plan.options.roll_limit_deg
    assert flight.height_range_m < 3.0  # altitude hold between the blocks
    assert any("tau_motor_s" in n for n in flight.notes)  # the default F450 has no lag: said so


def test_check_flags_a_plan_that_leaves_pitch_and_yaw_unexcited() -> None:
    plan = plan_quadrotor_excitation(None, QuadExciteOptions(axes=("roll", "throttle"), **SHORT))
    _, checks = check_quadrotor_plan(plan, compile=False)
    rot = checks["rotation"]
    for key, c in checks.items():
        print(f"negative control {key}: {c.line()}")
    assert not rot.ok and "NOT well conditioned" in rot.line()
    assert rot.relative_std["Jy_kg_m2"] > RELATIVE_STD_WARN and rot.relative_std["b_drag_N_m_s2"] > RELATIVE_STD_WARN
    assert rot.relative_std["Jx_kg_m2"] < 0.01  # the roll blocks still determine Jx
    assert not checks["drag"].ok and checks["drag"].relative_std["kd_x_N_s_m"] > RELATIVE_STD_WARN


def test_drag_doublets_determine_the_drag_that_short_pulses_leave_open(good_check) -> None:
    """Drag acts on body velocity, which short pulses hardly build: without the drag doublets the same plan leaves
    drag flagged (Cramér-Rao std above half its value); with them it is within 10 %."""
    plan = plan_quadrotor_excitation(None, QuadExciteOptions(**{**SHORT, "inputs": ("doublet",)}))
    flight = fly_closed_loop(plan, compile=False)
    short = check_set(plan, flight, DRAG_SET, ("roll", "pitch", "throttle"))
    print(f"without drag doublets, drag: {short.line()}")
    with_drag = good_check[2]["drag"]
    assert not short.ok
    for name in DRAG_SET:
        assert with_drag.relative_std[name] < 0.1 < short.relative_std[name]


def test_workflow_writes_the_files_of_each_autopilot(tmp_path: Path) -> None:
    px4 = excite_quadrotor(None, QuadExciteOptions(**SHORT))
    ap = excite_quadrotor(None, QuadExciteOptions(autopilot="ardupilot", **SHORT))
    assert set(px4.files) == {".manual_control.json", ".manual_control.csv", ".plan.json"}
    assert set(ap.files) == {".rc_override.json", ".rc_override.csv", ".plan.json",
                             *(f".sid_{a}.parm" for a in AXES)}
    paths = write_files(ap, tmp_path / "quad")
    plan = json.loads((tmp_path / "quad.plan.json").read_text())
    assert plan["vehicle"] == "quadrotor" and set(plan["systemid"]) == set(AXES) and len(plan["blocks"]) == 7
    assert (tmp_path / "quad.rc_override.csv").read_text().splitlines()[0] == \
        "t_s,phase,block,ch1_us,ch2_us,ch3_us,ch4_us"
    assert all(p.exists() for p in paths) and px4.well_conditioned is None


def test_quadrotor_bad_input_is_refused_with_excite_exit_status(tmp_path: Path, capsys) -> None:
    parser = argparse.ArgumentParser()
    excite_command.add_arguments(parser)
    args = parser.parse_args(["--vehicle", "quadrotor", "--out", str(tmp_path / "q"), "--axes", "roll,flip"])
    assert excite_command.run(args) == excite_command.EXIT_BAD_INPUT
    assert "axes: 'flip' unknown" in capsys.readouterr().err
    wing = tmp_path / "wing.json"
    wing.write_text(json.dumps({"C_ell_p": -0.4}))
    args = parser.parse_args(["--vehicle", "quadrotor", "--out", str(tmp_path / "q"), "--params", str(wing)])
    assert excite_command.run(args) == excite_command.EXIT_BAD_INPUT  # a fixed-wing file is not read as defaults
    assert "fixed_wing only (fixed_wing: C_ell_p)" in capsys.readouterr().err

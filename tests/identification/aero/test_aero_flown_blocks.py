"""``identify aero`` finds the flown blocks in the log itself: a plan from ``uavfmu excite``, its Lua script run
on the stand-in ArduPilot bindings while the model flies the plan in closed loop, the script's EXCT marks and the
flight written as one DataFlash log (starting 31.365 s after boot, as the shared SITL log does), then
``identify_aero`` with no timeline: the blocks come from the marks, on the log's time axis, and the derivatives
come back. Also the other source: the MANUAL mode spans of the shared SITL excitation log, against its
hand-made timeline."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero.identify import AeroOptions, identify_aero
from identification.excite.check import fly_closed_loop
from identification.excite.design import ExciteOptions, plan_excitation
from identification.excite.writers import OutputOptions, lua_script
from identification.flights.scenarios import Recording
from identification.flights.synthetic import write_log
from identification.logs.dataflash_writer import MessageLayout
from identification.logs.flown_blocks import mode_blocks
from identification.logs.readers import read_log
from identification.logs.timeline import load_timeline
from tests.conftest import shared_data

pytest.importorskip("lupa.lua53", reason="lupa (Lua 5.3 for Python) not installed: pip install lupa")

from identification.excite.dry_run import HIGH_US, LOW_US, SWITCH_CHANNEL, FakeArduPlane

BOOT_S = 31.365  #: boot time of the log's first sample [s]
LEAD_S = 4.0  #: trim flight before the trigger [s]
EXCT = MessageLayout("EXCT", "QBBBII", ("TimeUS", "Blk", "Ph", "Ax", "Tms", "Pms"))
#: the truth flown: lateral derivatives 15-25 % away from the Aerosonde start values
TRUTH = {"C_ell_p": 1.2, "C_ell_delta_a": 0.85, "C_n_r": 1.25, "C_n_delta_r": 0.8}
FREE = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]
#: every servo command logged (RCOU at the 50 Hz loop rate; at half of it the closed-loop part of the commands
#: is half unseen, which biases C_ell_p by +38 % here: bench/aero_chain_replica.py)
LOGGED_EVERY = {"RCOU": 1, "ATT": 1}


@pytest.fixture(scope="module")
def flown(tmp_path_factory):  # type: ignore[no-untyped-def]
    plan = plan_excitation(None, ExciteOptions(settle_s=1.0, tail_s=2.0, recovery_s=2.0, inputs=("3211", "doublet"),
                                               surfaces=("aileron", "rudder")))
    truth = FixedWingParams.from_dict({**FixedWingParams().to_dict(),
                                       **{k: getattr(FixedWingParams(), k) * f for k, f in TRUTH.items()}})
    p = np.array(FixedWingModel(truth).params.starts())
    late = dataclasses.replace(plan, blocks=[dataclasses.replace(
        b, start_s=b.start_s + LEAD_S, excitation_start_s=b.excitation_start_s + LEAD_S, end_s=b.end_s + LEAD_S)
        for b in plan.blocks])
    flight = fly_closed_loop(late, p=p)  # trim until LEAD_S, then the plan
    names = flight.output_names
    # the script flies along: switch high at LEAD_S, ticks every 20 ms, attitude from the flight
    ap = FakeArduPlane(lua_script(plan, OutputOptions()), {f"RC{SWITCH_CHANNEL}_OPTION": 300})
    ap.set(armed=True, airspeed=25.0, height=100.0, switch_us=LOW_US)
    for k, t in enumerate(flight.t_s):
        ap.set(roll=float(flight.y[k, names.index("roll_rad")]), pitch=float(flight.y[k, names.index("pitch_rad")]))
        if t >= LEAD_S - 1e-9:
            ap.set(switch_us=HIGH_US)
        ap.tick(1000 * (BOOT_S + t))
    marks = ap.marks
    # at t_k the servos hold u[k]; y[k] is the output after that step, at t_{k+1}
    rec = Recording(flight.t_s[1:], {n: flight.u[1:, i] for i, n in enumerate(("aileron_rad", "elevator_rad",
                                                                                 "rudder_rad", "throttle"))},
                    {n: flight.y[:-1, i] for i, n in enumerate(names)})
    exct = (np.array([m.t_ms / 1000 for m in marks]),
            {"Blk": [m.block for m in marks], "Ph": [m.phase for m in marks], "Ax": [m.axis for m in marks],
             "Tms": [m.since_trigger_ms for m in marks], "Pms": [m.planned_ms for m in marks]})
    path = write_log(tmp_path_factory.mktemp("flown") / "flight.bin", rec, noise=True, seed=4, boot_s=BOOT_S,
                     extra={"EXCT": exct}, layouts=[EXCT], decimation=LOGGED_EVERY)
    return plan, truth, marks, path, LEAD_S - rec.t_s[0]  # the trigger's time on the log's axis


def test_marks_are_read_on_the_log_time_axis(flown) -> None:  # type: ignore[no-untyped-def]
    from identification.logs.flown_blocks import marked_blocks

    plan, _, _, path, t_trigger = flown
    log = read_log(path)
    blocks = marked_blocks(log)
    assert [b.index for b in blocks] == [b.index for b in plan.blocks]
    assert [b.axis for b in blocks] == [b.axis for b in plan.blocks]
    for got, b in zip(blocks, plan.blocks, strict=True):  # each at most one tick after its planned time
        for have, want in ((got.start_s, b.start_s), (got.excitation_start_s, b.excitation_start_s),
                           (got.end_s, b.end_s)):
            assert -1e-6 <= have - (t_trigger + want) <= 0.02 + 1e-6, (b.index, have, want)


def test_identify_aero_without_a_timeline_uses_the_marks(flown) -> None:  # type: ignore[no-untyped-def]
    plan, truth, _, path, _ = flown
    log = read_log(path)
    res = identify_aero(log, PwmMapping.from_ardupilot(log.params), FixedWingParams(),
                        AeroOptions(free=FREE, max_delay_s=0.0, equation_error=False, priors="none"))
    assert not any("timeline" in n and "flight.bin" not in n for n in res.notes)
    found = [n for n in res.notes if "blocks found in the log (EXCT marks)" in n]
    assert found and f"{len(plan.blocks)} blocks" in found[0]
    listed = [n for n in res.notes if n.strip().startswith("block ")]
    axes = [b.axis for b in plan.blocks]
    assert len(listed) == len(plan.blocks)
    assert sum("held out" in n for n in listed) == len({a for a in axes if axes.count(a) >= 2})  # one per axis
    assert len(res.fit_segments) + len(res.validation_segments) == len(plan.blocks)
    est = res.estimate
    for name in FREE:
        i = est.names.index(name)
        want = getattr(truth, name)
        assert est.values[i] == pytest.approx(want, rel=0.05), (name, est.values[i], want)
    for out in ("rate_body_x_rad_s", "accel_body_y_m_s2"):  # held-out roll rate and side force
        assert res.baselines[out]["skill"]["persistence"]["outcome"] == "win", (out, res.baselines[out])


def test_mode_spans_of_the_shared_sitl_log_match_its_timeline() -> None:
    log = read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN"))
    tl = load_timeline(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.timeline.json"))
    blocks = mode_blocks(log)
    assert [b.axis for b in blocks] == [b.axis for b in tl.blocks]
    t0 = tl.log_first_sample_s
    for got, want in zip(blocks, tl.blocks, strict=True):
        assert got.start_s == pytest.approx(want.start_s - t0, abs=0.05)
        assert got.end_s == pytest.approx(want.end_s - t0, abs=0.05)
        assert got.excitation_start_s == pytest.approx(want.excitation_start_s - t0, abs=0.05)
    assert json.loads(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.timeline.json").read_text())

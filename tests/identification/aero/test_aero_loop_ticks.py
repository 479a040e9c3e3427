"""The fit on the autopilot's loop ticks (``identify aero --loop-ticks``) on the shared ArduPlane SITL excitation
log: the grid steps on the gyro's time stamps, a logged loop's input is its RCOU sample, an unlogged loop's the
mean of its neighbours, and the brackets of the unlogged commands line up with the manoeuvre's inputs."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero import model as aero
from identification.logs.readers import read_log
from identification.logs.sensor_chain import loop_clock
from tests.conftest import shared_data


def test_manoeuvre_on_the_loop_ticks_with_the_loops_commands() -> None:
    log = read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN"))
    model = FixedWingModel()
    mapping = PwmMapping.from_ardupilot(log.params)
    clock = loop_clock(log)
    assert clock is not None
    p = np.array(model.params.starts())
    seg = aero.Segment(62.507, 74.0)  # an aileron 3-2-1-1 of the first block, started between two ticks
    held = aero.manoeuvres(model, p, log, mapping, [seg], ["roll_rad"], 50.0)[0]
    ticked = aero.manoeuvres(model, p, log, mapping, [seg], ["roll_rad"], 50.0, clock=clock)[0]
    assert held.dt_s == 0.02 and ticked.dt_s == pytest.approx(0.020, abs=2e-6)
    t = clock.grid(seg.t0_s, seg.t1_s)[:-1]
    assert np.min(np.abs(clock.tick_s - t[0])) < 1e-9 and 0 <= t[0] - seg.t0_s < 0.02
    i = list(model.inputs.index).index("aileron_rad")
    sig = log.signal("aileron_pwm_us")
    loops = clock.loop_index(t)
    assert np.all(np.diff(loops) == 1)  # the uniform grid reads every loop once (no drift against the ticks)
    assert np.max(np.abs(t - clock.tick_s[loops])) < 1e-3
    tick = clock.tick_s[loops]
    on_sample = np.array([np.min(np.abs(sig.t_s - x)) < 1e-4 for x in tick])
    assert 0.4 < on_sample.mean() < 0.6  # every second loop logged
    ch = {c.target: c for c in mapping.channels}["aileron_rad"]
    k = np.flatnonzero(on_sample)[3]
    assert ticked.u[k, i] == pytest.approx(ch.to_input(float(np.interp(tick[k], sig.t_s, sig.values))))
    k = np.flatnonzero(~on_sample)[3]
    j = np.searchsorted(sig.t_s, tick[k])
    assert ticked.u[k, i] == pytest.approx(0.5 * (ch.to_input(float(sig.values[j - 1]))
                                                  + ch.to_input(float(sig.values[j]))), abs=1e-9)
    moved = np.abs(ticked.u[:, i] - held.u[:, i]).max()
    assert moved > 0.01  # the steps of the 3-2-1-1 land in other loops than the held grid puts them
    br = aero.unlogged_brackets(model, log, mapping, [seg], clock)[0]
    assert br.before.shape == ticked.u.shape and np.array_equal(br.logged[:, i], on_sample)
    assert all(not br.logged[k, c] for k, c in br.free()) and len(br.free()) >= 4

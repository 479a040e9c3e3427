"""The shared excitation log (our FMU with unknown derivatives, Aerosonde mass, inertia and
geometry, open-loop 3-2-1-1 and doublets in MANUAL, a timeline beside the log): segments from the timeline,
every primary derivative free and data-determined, the model beats persistence on held-out roll, pitch,
body rates and lateral acceleration (skill interval wholly above zero), and the parameter file carries the
covariance the Monte Carlo replays read. The true values are not handed over (not checked here)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero.identify import PRIMARY, AeroOptions, AeroResult, identify_aero, write_results
from identification.aero.segments import load_timeline_blocks, timeline_segments
from tests.conftest import shared_data


@pytest.fixture(scope="module")
def result() -> AeroResult:
    from identification.logs.readers import read_log

    log = read_log(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.BIN"))
    # no delay scan and one continuation schedule (the restarts have their own tests; on this log every restart
    # reaches the first schedule's criterion, identification/aero/readme.md): the suite's time, not the result
    return identify_aero(log, PwmMapping.from_ardupilot(log.params), FixedWingParams(),
                         AeroOptions(max_delay_s=0.0, restart_horizons_s=()))


def test_timeline_blocks_become_fit_and_held_out_segments() -> None:
    path = shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.timeline.json")
    tl = load_timeline_blocks(path)
    assert len(tl.blocks) == 10 and tl.log_start_s == pytest.approx(31.364949)
    fit, val, _ = timeline_segments(tl, 473.8)
    assert len(val) == 3 and len(fit) == 7  # the middle of each axis's three blocks held out
    raw = json.loads(path.read_text())["blocks"]
    first = fit[0]
    assert first.t0_s == pytest.approx(raw[0]["start_s"] - tl.log_start_s, abs=1e-3)
    assert first.t1_s == pytest.approx(raw[0]["end_s"] + 2.0 - tl.log_start_s, abs=1e-3)


def test_every_primary_derivative_is_free_and_bounded_and_the_model_beats_persistence(result, tmp_path) -> None:  # type: ignore[no-untyped-def]
    est = result.estimate
    assert set(PRIMARY) <= set(result.free)
    dom = dict(zip(est.names, est.dominance(), strict=False))
    for name in PRIMARY:
        # not prior-dominated; "fixed": the consider share of the coefficients still held fixed exceeds the
        # data std (identification/aero/readme.md names which ones on this log)
        assert dom[name] in ("data", "data (no prior)", "fixed"), (name, dom[name])
        i = est.names.index(name)
        assert est.std[i] < 0.2 * abs(est.values[i]), (name, est.values[i], est.std[i])  # 95 %: within 40 %
    assert any("timeline" in n for n in result.notes)
    for out in ("roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
                "accel_body_y_m_s2"):
        assert result.baselines[out]["skill"]["persistence"]["outcome"] == "win", (out, result.baselines[out])
    out = tmp_path / "p.json"
    write_results(result, out, tmp_path / "m.json", "excitation", 50.0)
    unc = json.loads(out.read_text())["uncertainty"]
    cov = np.array(unc["covariance"])
    assert unc["names"] == est.names[:est.n_global] and cov.shape == (len(unc["names"]),) * 2
    assert np.allclose(np.sqrt(np.diag(cov)), est.std[:est.n_global], rtol=1e-9)
    assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > -1e-12
    # the noise of each segment's logged start is read from the log and enters the bounds, named
    assert est.start_var is not None and np.all(est.start_var >= 0.0) and np.any(est.start_var > 0.0)
    # ... and the segments' scatter is taken expecting each segment's own start error
    assert est.scatter_start and est.scatter is not None and np.all(np.isfinite(est.scatter[0]))
    assert any("noise of the logged start" in n for n in result.notes)
    metrics = json.loads((tmp_path / "m.json").read_text())
    assert "logged start states" in json.loads(out.read_text())["_identification"]["bound_method"]
    assert all(metrics["estimate"]["parameters"][n]["start_state_std"] >= 0.0 for n in PRIMARY)
    assert set(metrics["start_state_sd"]) >= {"vel_body_x_m_s", "vel_body_z_m_s", "quat_y", "pos_down_m"}


def test_freed_zero_order_force_coefficients_take_over_their_accelerometer_biases(result) -> None:  # type: ignore[no-untyped-def]
    """A common offset of a specific force fits as a per-segment accelerometer bias or as a zero-order force
    coefficient; once ``free="auto"`` frees the coefficient, the bias of its axis leaves the nuisance set, so a
    replay without biases sees the offset. With the logged (equivalent) airspeed read as true airspeed, the
    held-out airspeed beats persistence and the segment mean (it tied the segment mean before)."""
    from identification.aero.identify import ZERO_FORCE_AXES

    freed = [c for c in ZERO_FORCE_AXES if c in result.free]
    assert "C_Y_0" in freed
    for c in freed:
        assert ZERO_FORCE_AXES[c] not in result.fit.oe.biases, c
    assert "rate_body_x_rad_s" in result.fit.oe.biases  # the gyro biases stay
    assert "dropped when freed" in result.nuisance_choice
    assert any("dropped the per-segment biases" in n for n in result.notes)
    skill = result.baselines["airspeed_m_s"]["skill"]
    assert skill["persistence"]["outcome"] == "win" and skill["segment_mean"]["outcome"] == "win", skill

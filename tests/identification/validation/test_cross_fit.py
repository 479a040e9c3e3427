"""The fixed wing's discrepancy learned on out-of-sample replays: every segment of ``identify aero`` left out in turn,
replayed with the estimate fitted without it, and the discrepancy learned on those replays stored beside the
covariance (``identification.validation.cross_fit``, ``identify aero --discrepancy``)."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fmu_models.fixed_wing.params import FixedWingParams
from identification.aero import model as aero
from identification.aero.identify import AeroOptions, AeroSource, identify_aero
from identification.common.parallel import Executor
from identification.flights import synthetic
from identification.logs.readers import read_log
from identification.validation.cross_fit import MIN_SEGMENTS, learn_folds, segment_folds
from identification.validation.discrepancy import horizons_s, read_discrepancy
from identification.validation.replay import ValidationInputError, options
from uavfmu.commands import identify_aero as command

FREE = ["C_ell_p", "C_ell_delta_a"]
OUTPUTS = ("roll_rad", "rate_body_x_rad_s")
#: the flight's aileron 3-2-1-1 starts 1 s into each 20 s block: three segments, each with a roll manoeuvre
SEGMENTS = "0.5:6,20.5:26,30.5:36"
#: the flown aircraft: the free derivatives away from the defaults the fit starts from, and a fixed coefficient off
#: its default that the fit is told (``init``) and every replay must carry
TRUTH = {"C_ell_p": -0.40, "C_ell_delta_a": 0.15, "C_n_r": -0.12}


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("cross_fit")
    t, sig = synthetic.fixed_wing_flight(FixedWingParams(**TRUTH), seconds=40.0, rate_hz=50.0, noise=True, seed=3)
    return {"dir": d, "log": synthetic.write_csv_log(d / "wing.csv", t, sig),
            "mapping": synthetic.write_mapping_toml(d / "mapping.toml")}


def _opt() -> AeroOptions:
    return AeroOptions(free=FREE, outputs=OUTPUTS, nuisance="none", max_delay_s=0.0, consider=False,
                       start_noise=False, priors="none", equation_error=False, restart_horizons_s=(), progress=False)


def test_each_segment_is_replayed_with_the_estimate_fitted_without_it(flight, fixed_wing_fmu) -> None:
    segs = aero.parse_segments(SEGMENTS)
    init = FixedWingParams(C_n_r=TRUTH["C_n_r"])
    with Executor(workers=2) as ex:
        folds, skipped = segment_folds(flight["log"], segs, fixed_wing_fmu, _opt(), init, options(window_s=2.0),
                                       draws=19, executor=ex, mapping_file=flight["mapping"])
    assert skipped == [] and [f.segment for f in folds] == segs
    # fold 0 is the identification on the other two segments, exactly
    log = read_log(flight["log"])
    alone = identify_aero([AeroSource(log, synthetic.MAPPING, None, segs[1:], segs[:1])], None, init, _opt())
    n = alone.estimate.n_global
    assert folds[0].uncertainty.names == list(alone.estimate.names[:n]) == FREE
    np.testing.assert_allclose(folds[0].uncertainty.mean, alone.estimate.values[:n], rtol=1e-9)
    means = np.array([f.uncertainty.mean for f in folds])  # columns in FREE's order (checked above)
    assert np.ptp(means[:, 0]) > 0.0  # each fold fitted other data (noisy): no fold's estimate is another's
    for k, name in enumerate(FREE):  # and each is near the flown truth, not at the default it started from
        assert np.all(np.abs(means[:, k] - TRUTH[name]) < 0.15 * abs(TRUTH[name])), (name, means[:, k])
    for f in folds:
        assert f.job.t_range_s == (f.segment.t0_s, f.segment.t1_s)
        t = np.asarray(f.replay.t_s)
        assert t.min() >= f.segment.t0_s - 1e-9 and t.max() <= f.segment.t1_s + 1e-9
        assert not set(FREE) & set(f.job.start_values)  # the free ones come from the uncertainty (drawn in --mc)
        assert f.job.start_values["C_n_r"] == TRUTH["C_n_r"]
        assert len(f.job.start_values) == len(init.to_dict()) - len(FREE)
        assert f.replay.fmu["parameters"]["C_n_r"] == pytest.approx(TRUTH["C_n_r"])  # the fold's values, not the FMU's
        assert f.replay.fmu["parameters"]["C_ell_p"] == pytest.approx(f.uncertainty.mean[0])
        assert horizons_s(f.replay).max() <= 2.0 + 1e-9
        dev = f.keep["roll_rad"]  # the fold's parameter draws (its own covariance) about its own replay
        assert dev.shape == (19, len(f.replay.t_s)) and np.nanstd(dev) > 0.0
    every, without = learn_folds(folds), learn_folds(folds, exclude=1)
    assert len(every.logs) == 3 and every.logs[1] not in without.logs and len(without.logs) == 2
    assert every.window_s == 2.0 and "out-of-sample" in every.note
    for name in OUTPUTS:  # calibrated on the draws: a band factor and a parameter weight per signal
        s = every.signals[name]
        assert s.band_factor is not None and s.band_factor > 0.0 and s.parameter_weight in (0.0, 1.0)
    bare = learn_folds([replace(f, keep={}) for f in folds])  # without draws nothing is calibrated
    assert all(s.band_factor is None for s in bare.signals.values())
    with pytest.raises(ValidationInputError, match=f"needs {MIN_SEGMENTS}"):
        segment_folds(flight["log"], segs[:2], fixed_wing_fmu, _opt(), init, mapping_file=flight["mapping"])


def _cli(*args: object) -> int:
    parser = argparse.ArgumentParser()
    command.add_arguments(parser)
    return command.run(parser.parse_args([*map(str, args), "--quiet"]))


def test_identify_aero_stores_the_cross_fitted_discrepancy(flight, capsys) -> None:
    out = flight["dir"] / "identified.json"
    base = [flight["log"], "--mapping", flight["mapping"], "--free", ",".join(FREE), "--outputs", ",".join(OUTPUTS),
            "--nuisance", "none", "--max-delay", "0", "--no-consider", "--no-start-noise", "--priors", "none",
            "--no-equation-error", "--restarts", "none", "--out", out]
    rc = _cli(*base, "--segments", "0.5:6,30.5:36", "--validate-segments", "20.5:26", "--discrepancy",
              "--discrepancy-mc", "0")
    printed = capsys.readouterr()
    assert rc == command.EXIT_OK, printed.err
    assert "discrepancy from 3 out-of-sample segment replays" in printed.out
    assert all(f"  {name:<18} 5-95 % of" in printed.out for name in OUTPUTS)  # each signal, as uavfmu discrepancy
    doc = json.loads(out.read_text())
    assert doc["uncertainty"]["names"] == FREE  # the estimate written first is kept
    disc = read_discrepancy(out)
    assert disc is not None and set(disc.signals) >= set(OUTPUTS)
    assert [x.rsplit(" ", 2)[1] for x in disc.logs] == ["0.5-6", "20.5-26", "30.5-36"]  # fit and held-out alike
    # the file builds, and the FMU carries the discrepancy to validate --mc
    from fmu_models.fmi.fmus import BuildOptions, build_fmus
    from fmu_models.fmi.zigcc import host_platform

    (fmu,) = build_fmus(out, flight["dir"] / "fmu", ["fixed_wing"], "native",
                        BuildOptions(kinds=("cs",), platforms=(host_platform().fmi_name,))).fmus
    assert read_discrepancy(None, fmu) == disc
    # one log only, and a draw count the Monte Carlo takes
    assert _cli(flight["log"], *base, "--discrepancy") == command.EXIT_BAD_INPUT
    assert "--discrepancy" in capsys.readouterr().err
    assert _cli(*base, "--segments", "0.5:6", "--discrepancy", "--discrepancy-mc", "5") == command.EXIT_BAD_INPUT
    assert "--discrepancy-mc 5" in capsys.readouterr().err


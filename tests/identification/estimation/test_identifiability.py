"""Identifiability before/after the solve, --free auto, nuisance parameters that work
and estimates that survive a late failure."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.estimation.identifiability import CORRELATION_LIMIT, analyse, condition_number, select_free
from identification.estimation.oem import OutputErrorEstimator
from identification.flights.synthetic import identification_manoeuvres
from tests.conftest import shared_data


def test_analyse_names_correlated_pairs_and_the_weak_combination() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=500)
    J = np.column_stack([a, a + 0.01 * rng.normal(size=500), rng.normal(size=500)])
    M = J.T @ J
    ident = analyse(M, ["C_ell_p", "C_ell_delta_a", "C_n_r"], 3, {"aileron_rad": 0.02, "rudder_rad": 0.0001})
    assert [(a, b) for a, b, _ in ident.pairs] == [("C_ell_p", "C_ell_delta_a")]
    assert ident.condition_number > 100 and not ident.ok
    assert {n for n, _ in ident.weakest} == {"C_ell_p", "C_ell_delta_a"}
    text = "\n".join(ident.advice)
    assert "fix C_ell_delta_a" in text and "rudder_rad hardly moves" in text
    assert condition_number(np.eye(3)) == pytest.approx(1.0)
    assert select_free(M, ["C_ell_p", "C_ell_delta_a", "C_n_r"], theta=np.ones(3)) == ["C_ell_p", "C_n_r"]


def test_information_before_the_solve_sees_the_pitch_pair_of_a_short_design() -> None:
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    free = ["C_m_alpha", "C_m_q", "C_m_delta_e", "C_ell_p"]
    oe = OutputErrorEstimator(sim.model, p, free, ["pitch_rad", "rate_body_y_rad_s", "roll_rad"])
    data = identification_manoeuvres(oe, p, 4.0, 50.0, 2, np.random.default_rng(1), np.array([1e-3, 1e-3, 1e-3]))
    ident = oe.identifiability(data)
    r = ident.correlation[0, 2]
    assert (abs(r) > CORRELATION_LIMIT) == any({"C_m_alpha", "C_m_delta_e"} == {a, b} for a, b, _ in ident.pairs)
    assert ident.excitation["elevator_rad"] > 0 and np.isfinite(ident.condition_number)


def run_cli(*args: object) -> int:
    from uavfmu.commands import identify_aero

    parser = argparse.ArgumentParser()
    identify_aero.add_arguments(parser)
    return identify_aero.run(parser.parse_args([*map(str, args), "--quiet"]))


def test_issue_nuisance_run_writes_estimates_and_reports_nuisance_apart(tmp_path, capsys) -> None:
    """The issue's run ended in a zip() traceback and wrote nothing; now it writes both files, derivatives in
    'parameters', initial states and biases in 'nuisance', and a late failure (plots) keeps them."""
    log = shared_data("fixed_wing", "arduplane_sitl_takeoff_00000012.BIN")
    out = tmp_path / "plane.json"
    blocker = tmp_path / "plots"
    blocker.write_text("a file where the plot folder should go")  # plots fail late
    rc = run_cli(log, "--free", "C_ell_p,C_ell_delta_a", "--estimate-initial", "rate_body_x_rad_s",
                 "--biases", "rate_body_x_rad_s,roll_rad", "--outputs", "roll_rad,rate_body_x_rad_s",
                 "--max-delay", "0", "--out", out, "--plots", blocker)
    printed = capsys.readouterr().out
    assert rc == 5 and "FAILED after the solve: plots" in printed
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert set(metrics["estimate"]["parameters"]) == {"C_ell_p", "C_ell_delta_a"}
    nuis = metrics["estimate"]["nuisance"]
    n_seg = len(metrics["fit_segments"])
    assert len(nuis) == 3 * n_seg and all(k.startswith("m") for k in nuis)
    assert metrics["failures"] and metrics["identifiability_before"]["condition_number"] > 0
    assert json.loads(out.read_text())["fixed_wing"]["C_ell_p"] == metrics["estimate"]["parameters"]["C_ell_p"]["value"]


def test_auto_nuisance_finds_gyro_biases_and_the_command_to_surface_delay(tmp_path) -> None:
    """A synthetic flight whose yaw gyro carries a different bias every 10 s and whose logged servo commands
    lead the surfaces by 40 ms: nuisance=auto keeps per-segment biases, the delay scan finds 40 ms, and the
    derivatives come back within 2 % (without either they are 10 % off)."""
    from fmu_models.fixed_wing.params import FixedWingParams
    from fmu_models.signals.names import OUTPUT_TO_LOG
    from identification.aero.identify import AeroOptions, identify_aero
    from identification.aero.model import parse_segments
    from identification.flights import synthetic
    from identification.logs.readers import read_log

    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0, noise=True, seed=3)
    col = OUTPUT_TO_LOG["rate_body_z_rad_s"]
    sig[col] = sig[col] + np.array([0.02, -0.015, 0.01, -0.02])[np.minimum((t // 10).astype(int), 3)]
    for k in (1, 2, 4):
        c = f"servo_{k}_pwm_us"
        sig[c] = np.concatenate([sig[c][2:], np.full(2, sig[c][-1])])  # the log leads the surfaces by 40 ms
    log = read_log(synthetic.write_csv_log(tmp_path / "biased.csv", t, sig))
    free = ("C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r")
    res = identify_aero(log, synthetic.MAPPING, FixedWingParams(), AeroOptions(
        free=free, outputs=("roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2"),
        segments=parse_segments("0.5:9.5,10.5:19.5,20.5:29.5,30.5:39.5")))
    assert res.nuisance_choice.startswith("per-segment") and res.fit.delay_s == pytest.approx(0.04)
    nuis = res.estimate.nuisance()
    biases = [nuis[f"m{j}.bias.rate_body_z_rad_s"]["value"] for j in range(4)]
    np.testing.assert_allclose(biases, [0.02, -0.015, 0.01, -0.02], atol=3e-3)
    truth = FixedWingParams()
    for n, v in res.estimate.derivatives().items():
        assert v == pytest.approx(getattr(truth, n), rel=0.02), res.summary()

"""``uavfmu identify aero``: from a log to an identified parameter file, on synthetic and ArduPlane SITL logs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from build_fmus import split_params
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import MappingError
from identification.aero import model as aero
from identification.flights import synthetic
from tests.conftest import shared_data
from uavfmu.commands import identify_aero
from uavfmu.commands.identify_aero import EXIT_BAD_INPUT, EXIT_OK

FREE = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]


@pytest.fixture(scope="module")
def synthetic_log(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A noise-free 40 s Aerosonde flight as a CSV log, its PWM mapping, and start values perturbed 30 %."""
    d = tmp_path_factory.mktemp("aero")
    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0)
    log = synthetic.write_csv_log(d / "flight.csv", t, sig)
    mapping = synthetic.write_mapping_toml(d / "mapping.toml")
    truth = FixedWingParams().to_dict()
    start = {n: truth[n] * (1.3 if k % 2 else 0.7) for k, n in enumerate(FREE)}
    init = d / "init.json"
    init.write_text(json.dumps(start))
    return {"dir": d, "log": log, "mapping": mapping, "init": init}


def run_cli(*args: object) -> int:
    parser = argparse.ArgumentParser()
    identify_aero.add_arguments(parser)
    return identify_aero.run(parser.parse_args([*map(str, args), "--quiet"]))


def test_noise_free_log_gives_back_the_truth(synthetic_log, capsys) -> None:
    d = synthetic_log["dir"]
    out = d / "identified.json"
    rc = run_cli(synthetic_log["log"], "--init", synthetic_log["init"], "--mapping", synthetic_log["mapping"],
                 "--free", ",".join(FREE), "--outputs", "roll_rad,rate_body_x_rad_s,rate_body_z_rad_s",
                 "--segments", "0:9,20:29", "--validate-segments", "10:19,30:39", "--out", out, "--plots", d / "plots",
                 "--sigma", "roll_rad=0.01,rate_body_x_rad_s=0.01,rate_body_z_rad_s=0.01", "--nuisance", "none",
                 "--max-delay", "0")
    assert rc == EXIT_OK, capsys.readouterr().err
    identified = FixedWingParams.load(out)  # the file loads as the FMU build loads it
    assert set(split_params(json.loads(out.read_text()))) == {"fixed_wing"}
    unc = json.loads(out.read_text())["uncertainty"]  # what the Monte Carlo replays read
    assert unc["names"] == FREE and len(unc["covariance"]) == len(FREE) == len(unc["mean"])
    truth = FixedWingParams()
    for n in FREE:
        assert getattr(identified, n) == pytest.approx(getattr(truth, n), rel=1e-4), n
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    for output, m in metrics["metrics"]["validation"].items():
        assert m["theil_u"] < 1e-3, output
    assert metrics["fit_segments"] == ["0:9", "20:29"]
    assert metrics["estimate"]["converged"]
    for png in ("fit.png", "validation.png", "residuals.png", "parameters.png", "correlation.png"):
        assert (d / "plots" / png).stat().st_size > 10_000
    assert "roll_rad" in capsys.readouterr().out


def test_bad_input_is_named(synthetic_log, capsys) -> None:
    d, log, mapping = synthetic_log["dir"], synthetic_log["log"], synthetic_log["mapping"]
    base = [log, "--mapping", mapping, "--out", d / "x.json"]
    assert run_cli(*base, "--free", "C_ell_pp", "--segments", "0:5") == EXIT_BAD_INPUT
    assert "C_ell_pp" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "5:2") == EXIT_BAD_INPUT
    assert "--segments" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "0:500") == EXIT_BAD_INPUT
    assert "ends after the log" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "0:5", "--outputs", "roll_deg") == EXIT_BAD_INPUT
    assert "roll_deg" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "0:5", "--outputs", "roll_rad",
                   "--sigma", "pitch_rad=0.1") == EXIT_BAD_INPUT
    assert "--sigma needs" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "0:5", "--prior", "C_ell_pp=-0.5:0.1") == EXIT_BAD_INPUT
    assert "C_ell_pp" in capsys.readouterr().err
    assert run_cli(*base, "--free", "C_ell_p", "--segments", "0:5", "--prior", "C_ell_p=-0.5:-1") == EXIT_BAD_INPUT
    assert "sd > 0" in capsys.readouterr().err
    assert run_cli(synthetic_log["log"], *base, "--free", "C_ell_p", "--segments", "0:5") == EXIT_BAD_INPUT
    assert "one log" in capsys.readouterr().err
    assert run_cli(d / "missing.bin", "--free", "C_ell_p", "--out", d / "x.json") == EXIT_BAD_INPUT
    assert not (d / "x.json").exists()


def test_pwm_out_of_range_in_the_log_names_the_channel(synthetic_log) -> None:
    from fmu_models.fixed_wing.model import FixedWingModel
    from identification.logs.readers import read_log

    log = read_log(synthetic_log["log"])
    sig = log.signal("servo_1_pwm_us")
    sig.values[40] = np.nan
    model = FixedWingModel()
    with pytest.raises(MappingError, match=r"servo_1_pwm_us.*aileron_rad.*nan"):
        aero.log_inputs(model, log, synthetic.MAPPING, np.arange(0, 2, 0.02))


def test_pwm_mapping_inverse_round_trips() -> None:
    for ch in synthetic.MAPPING.channels:
        for v in np.linspace(ch.out_min, ch.out_max, 7):
            assert ch.to_input(ch.to_pwm(v)) == pytest.approx(v, abs=1e-12)


def test_arduplane_sitl_roll_axis_held_out_fit(tmp_path, capsys) -> None:
    """On real-ish data: roll-axis derivatives from the SITL takeoff log, roll angle scored on held-out
    windows (Theil U below 0.3, the usual acceptance bar)."""
    log = shared_data("fixed_wing", "arduplane_sitl_takeoff_00000012.BIN")
    out = tmp_path / "plane.json"
    rc = run_cli(log, "--free", "C_ell_p,C_ell_delta_a,C_ell_beta,C_ell_r", "--outputs", "roll_rad,rate_body_x_rad_s",
                 "--out", out, "--plots", tmp_path / "plots")
    assert rc == EXIT_OK, capsys.readouterr().err
    metrics = json.loads(out.with_suffix(".metrics.json").read_text())
    assert len(metrics["validation_segments"]) >= 3
    theil = metrics["metrics"]["validation"]["roll_rad"]["theil_u"]
    assert theil < 0.3
    params = metrics["estimate"]["parameters"]
    assert params["C_ell_p"]["value"] < 0  # roll damping, kept by the stability constraint
    assert params["C_ell_delta_a"]["value"] > 0  # positive aileron rolls right (ArduPilot SERVO1 convention)
    assert (tmp_path / "plots" / "validation.png").exists()


def test_damaged_log_is_refused_unless_forced_and_its_damage_is_reported(synthetic_log, capsys) -> None:
    """A log that lost more than --max-damage is refused (exit 2, file and damage named); with
    --force it is used and its damage is printed and written to the metrics."""
    d = synthetic_log["dir"]
    lines = synthetic_log["log"].read_text().splitlines()
    cut = 1 + 3 * (len(lines) - 1) // 4  # the last quarter of the samples jump 1e6 s ahead: dropped
    jumped = [f"{float(r.split(',', 1)[0]) + 1e6!r},{r.split(',', 1)[1]}" for r in lines[cut:]]
    damaged = d / "damaged.csv"
    damaged.write_text("\n".join([*lines[:cut], *jumped]) + "\n")
    args = (damaged, "--mapping", synthetic_log["mapping"], "--free", "C_ell_p,C_ell_delta_a", "--outputs",
            "roll_rad,rate_body_x_rad_s", "--segments", "0:9", "--nuisance", "none", "--max-delay", "0")
    out = d / "damaged.json"
    assert run_cli(*args, "--out", out) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "damaged.csv" in err and "damaged or lost" in err and "--force" in err and not out.exists()
    assert run_cli(*args, "--out", out, "--force") == EXIT_OK
    printed = capsys.readouterr().out
    assert "time jump" in printed and "damaged.csv" in printed
    quality = json.loads(out.with_suffix(".metrics.json").read_text())["quality"]
    assert quality["damage_fraction"] == pytest.approx(0.25, abs=0.02) and quality["samples_beyond_jumps"] > 0

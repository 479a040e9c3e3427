"""``uavfmu validate``: single runs (quadrotor and fixed wing), reports, exit status, batch with failures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from identification.flights import synthetic
from tests.conftest import shared_data
from uavfmu.cli import main


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("vcli")
    t, sig = synthetic.fixed_wing_flight(seconds=20.0, rate_hz=50.0)
    wing = synthetic.write_csv_log(d / "wing.csv", t, sig)
    bad = dict(sig)
    bad["servo_1_pwm_us"] = sig["servo_1_pwm_us"].copy()
    bad["servo_1_pwm_us"][200:] = np.nan
    return {"dir": d, "wing": wing, "wing_nan": synthetic.write_csv_log(d / "wing_nan.csv", t, bad),
            "mapping": synthetic.write_mapping_toml(d / "mapping.toml")}


def test_fixed_wing_log_validates_with_report(fixed_wing_fmu: Path, logs, tmp_path: Path, capsys) -> None:
    rc = main(["validate", str(fixed_wing_fmu), str(logs["wing"]), "--mapping", str(logs["mapping"]),
               "--window-s", "5", "--report", str(tmp_path)])
    assert rc == 0, capsys.readouterr().err
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    for name in ("roll_rad", "pitch_rad", "rate_body_x_rad_s", "airspeed_m_s", "accel_body_z_m_s2"):
        assert metrics["signals"][name]["theil_u"] < 0.01, name  # same model, same inputs: only step-size error
    assert len(metrics["windows"]) == 4
    page = (tmp_path / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 1 and all(s in page for s in metrics["signals"])
    assert metrics["fmu"]["guid"] in page and "sha256" in page


def test_threshold_config_fails_a_signal_with_exit_1(fixed_wing_fmu: Path, logs, tmp_path: Path, capsys) -> None:
    cfg = tmp_path / "map.toml"
    cfg.write_text('[signals.roll_rad]\nlog = "roll_rad"\nmax_theil = 0.3\n'
                   '[signals.airspeed_m_s]\nlog = "airspeed_m_s"\nscale = 0.5\nmax_theil = 0.1\n')
    rc = main(["validate", str(fixed_wing_fmu), str(logs["wing"]), "--mapping", str(logs["mapping"]),
               "--map", str(cfg)])
    out = capsys.readouterr().out
    assert rc == 1
    assert "airspeed_m_s" in out and "FAIL" in out and "roll_rad" in out


def test_real_quadrotor_log_report_and_exit_status(quadrotor_fmu: Path, tmp_path: Path) -> None:
    log = shared_data("quadrotor", "arducopter_x_quad_real_218.BIN")
    rc = main(["validate", str(quadrotor_fmu), str(log), "--window-s", "2", "--rate-hz", "25",
               "--report", str(tmp_path)])
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    # the published F450 map holds altitude over 2 s windows; open-loop attitude of an unstable vehicle drifts
    assert metrics["signals"]["altitude_m"]["theil_u"] < 0.3
    assert rc == (1 if metrics["failed"] else 0)
    page = (tmp_path / "report.html").read_text()
    assert "altitude_m" in page and "paper 000 Fig. 5" in page


def test_bad_inputs_exit_2_with_a_message(quadrotor_fmu: Path, tmp_path: Path, capsys) -> None:
    csv = tmp_path / "f.csv"
    csv.write_text("time_s,motor_1_pwm_us\n0,1500\n1,1500\n")
    assert main(["validate", str(quadrotor_fmu), str(csv)]) == 2
    assert "motor_2_pwm_us" in capsys.readouterr().err
    assert main(["validate", str(tmp_path / "none.fmu"), str(csv)]) == 2
    assert "FMU not found" in capsys.readouterr().err
    assert main(["validate", str(quadrotor_fmu), str(csv), "--set", "mass_kg=heavy"]) == 2
    assert "NAME=NUMBER" in capsys.readouterr().err
    assert main(["validate", str(quadrotor_fmu)]) == 2
    assert "--batch" in capsys.readouterr().err
    manifest = tmp_path / "b.toml"
    manifest.write_text(f"[[job]]\nfmu = '{quadrotor_fmu}'\nlog = '{csv}'\n")
    assert main(["validate", "--batch", str(manifest), "--mc", "20"]) == 2
    err = capsys.readouterr().err
    assert "--batch with --mc needs --uncertainty" in err and "carries none" not in err


def test_batch_runs_every_pair_and_lists_failures(quadrotor_fmu: Path, fixed_wing_fmu: Path, logs, tmp_path: Path,
                                                  capsys) -> None:
    d = logs["dir"]
    manifest = tmp_path / "batch.toml"
    manifest.write_text(
        "[defaults]\nwindow_s = 5.0\n"
        f"[[job]]\nfmu = ['{fixed_wing_fmu}', '{quadrotor_fmu}']\nlog = ['{d / 'wing.csv'}', "
        f"'{d / 'wing_nan.csv'}']\nmapping = '{logs['mapping']}'\n"
        f"[[job]]\nfmu = '{tmp_path / 'missing.fmu'}'\nlog = '{d / 'wing.csv'}'\n")
    rc = main(["validate", "--batch", str(manifest), "--report", str(tmp_path / "rep"), "--jobs", "2", "--quiet"])
    assert rc == 1
    results = json.loads((tmp_path / "rep" / "results.json").read_text())
    assert len(results) == 5
    status = {(Path(r["fmu"]).name, Path(r["log"]).name): r for r in results}
    assert status[(fixed_wing_fmu.name, "wing.csv")]["status"] == "pass"
    assert "servo_1_pwm_us" in status[(fixed_wing_fmu.name, "wing_nan.csv")]["error"]
    assert "motor_1_pwm_us" in status[(quadrotor_fmu.name, "wing.csv")]["error"]
    assert "not found" in status[("missing.fmu", "wing.csv")]["error"]
    index = (tmp_path / "rep" / "index.html").read_text()
    assert "missing.fmu" in index and "4 not passing" in index
    assert "1 pass" in capsys.readouterr().out

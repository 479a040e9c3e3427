"""``uavfmu validate`` on the real quadrotor log: report written, failing signals give exit 1; bad input 2."""

from __future__ import annotations

import json
from pathlib import Path

from tests.conftest import shared_data
from uavfmu.cli import main


def test_real_log_report_and_exit_status(quadrotor_fmu: Path, tmp_path: Path) -> None:
    log = shared_data("quadrotor", "arducopter_x_quad_real_218.BIN")
    rc = main(["validate", str(quadrotor_fmu), str(log), "--window-s", "2", "--rate-hz", "25",
               "--report", str(tmp_path)])
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    # the published F450 map holds altitude over 2 s windows; open-loop attitude of an unstable vehicle drifts
    assert metrics["signals"]["altitude_m"]["theil_u"] < 0.3
    assert rc == (1 if metrics["failed"] else 0)
    page = (tmp_path / "report.html").read_text()
    assert "data:image/png;base64," in page and "altitude_m" in page


def test_bad_inputs_exit_2_with_a_message(quadrotor_fmu: Path, tmp_path: Path, capsys) -> None:
    csv = tmp_path / "f.csv"
    csv.write_text("time_s,motor_1_pwm_us\n0,1500\n1,1500\n")
    assert main(["validate", str(quadrotor_fmu), str(csv)]) == 2
    assert "motor_2_pwm_us" in capsys.readouterr().err
    assert main(["validate", str(tmp_path / "none.fmu"), str(csv)]) == 2
    assert "FMU not found" in capsys.readouterr().err
    assert main(["validate", str(quadrotor_fmu), str(csv), "--set", "mass_kg=heavy"]) == 2
    assert "NAME=NUMBER" in capsys.readouterr().err

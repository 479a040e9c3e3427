"""build_fmus.py: parameter files are embedded as the FMUs' start values; bad files give clear errors."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest
from fmpy import read_model_description

from build_fmus import main


def start_values(fmu: Path) -> dict[str, float]:
    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.causality == "parameter"}


def test_params_file_is_embedded_in_both_fmus(tmp_path: Path) -> None:
    params = {"quadrotor": {"mass_kg": 1.5, "thrust_map": {"type": "anfis", "inputs": ["pwm_sum_us"],
                                                           "mf_mean": [[5000.0, 7000.0]], "mf_sigma": [[800.0, 800.0]],
                                                           "order": 0, "consequents": [[6.0], [16.0]],
                                                           "input_range": [[4800.0, 7200.0]]}},
              "fixed_wing": {"C_ell_p": -0.42, "propulsion": {"D_prop_m": 0.45}}}
    f = tmp_path / "p.json"
    f.write_text(json.dumps(params))
    assert main(["--params", str(f), "--out", str(tmp_path / "out")]) == 0
    quad = start_values(tmp_path / "out" / "quadrotor.fmu")
    assert quad["mass_kg"] == 1.5 and quad["anfis_cons_2_N"] == 16.0 and quad["anfis_band_hi_us"] == 7200.0
    assert "anfis_mean_3_us" not in quad  # the map's structure (2 MFs) is built in
    fw = start_values(tmp_path / "out" / "fixed_wing.fmu")
    assert fw["C_ell_p"] == -0.42 and fw["D_prop_m"] == 0.45 and fw["C_ell_delta_a"] == 0.17


def test_bad_params_file_gives_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "bad.json"
    f.write_text('{"fixed_wing": {"C_ell_p": "abc", "mass_kgg": 3}}')
    assert main(["--params", str(f), "--out", str(tmp_path), "--only", "fixed_wing"]) == 2
    err = capsys.readouterr().err
    assert str(f) in err and "C_ell_p = 'abc' is not a number" in err and "mass_kgg is not a parameter" in err
    f.write_text('{"fixed_wing": {"C_D_0": 0.05}}')
    assert main(["--params", str(f), "--out", str(tmp_path), "--only", "fixed_wing"]) == 2
    assert "C_D_0 is no longer a parameter: the drag polar uses C_D_p" in capsys.readouterr().err
    f.write_text("{not json")
    assert main(["--params", str(f), "--out", str(tmp_path)]) == 2
    assert "not valid JSON" in capsys.readouterr().err


def test_cli_builds_fmi3_model_exchange_for_one_platform_with_a_progress_line_per_compile(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import zipfile

    from fmu_models.fmi import zigcc

    host = zigcc.host_platform()
    assert main(["--out", str(tmp_path), "--only", "quadrotor", "--fmi", "3", "--kind", "me",
                 "--platforms", host.fmi_name]) == 0
    out = capsys.readouterr().out
    assert f"[1/1] compiled quadrotor for {host.fmi_name}" in out
    md = read_model_description(str(tmp_path / "quadrotor.fmu"))
    assert md.fmiVersion == "3.0" and md.modelExchange is not None and md.coSimulation is None
    with zipfile.ZipFile(tmp_path / "quadrotor.fmu") as z:
        binaries = [n for n in z.namelist() if n.startswith("binaries/")]
    assert binaries == [f"binaries/{host.fmi3_name}/quadrotor{host.suffix}"]


@pytest.mark.parametrize("args, why", [
    (["--fmi", "4"], "invalid choice: 4"),
    (["--kind", "xx"], "invalid choice: 'xx'"),
    (["--platforms", "amiga"], "platforms = ['amiga']: each must be one of linux64, win64, darwin64"),
    (["--jobs", "0"], "jobs = 0: parallel compiles must be an integer in 1..8"),
    (["--jobs", "9"], "jobs = 9: parallel compiles must be an integer in 1..8"),
    (["--backend", "python", "--fmi", "3"], "the python backend builds FMI 2.0 Co-Simulation only"),
])
def test_bad_build_options_are_refused_with_a_clear_error(args: list[str], why: str, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) if "invalid choice" in why else contextlib.nullcontext():  # argparse exits
        assert main(["--out", str(tmp_path), "--only", "quadrotor", *args]) == 2
    assert why in capsys.readouterr().err
    assert not list(tmp_path.glob("*.fmu"))



@pytest.mark.parametrize("jobs", (0, 9, 100, -3, True, 2.5))
def test_the_library_refuses_a_parallel_compile_count_out_of_range(jobs: object) -> None:
    from fmu_models.fmi.fmus import MAX_JOBS, BuildOptions

    with pytest.raises(ValueError, match=f"jobs = .*: parallel compiles must be an integer in 1..{MAX_JOBS}"):
        BuildOptions(jobs=jobs)  # type: ignore[arg-type]
    assert BuildOptions(jobs=MAX_JOBS).jobs == MAX_JOBS and BuildOptions().jobs is None

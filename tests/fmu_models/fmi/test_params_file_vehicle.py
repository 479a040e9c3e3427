"""A parameter file is never silently ignored: its keys tell its vehicle, or the build refuses it naming the keys."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from fmpy import read_model_description

from fmu_models.common.errors import ParameterError
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fmi.fmus import BuildOptions, build_fmus, load_vehicle_params, sections_to_build, split_params
from fmu_models.quadrotor.params import QuadrotorParams
from uavfmu.commands import build as build_command

LINUX_ONLY = BuildOptions(kinds=("cs",), platforms=("linux64",))
FLAT_QUAD = {"Jx_kg_m2": 0.0123, "Jy_kg_m2": 0.0134, "Jz_kg_m2": 0.0251, "tau_motor_s": 0.035}


def _file(tmp_path: Path, data: object, name: str = "p.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def _problems(err: pytest.ExceptionInfo[ParameterError]) -> str:
    return "\n".join(err.value.problems)


def test_flat_quadrotor_file_with_only_quadrotor_builds_its_values(tmp_path: Path, capsys) -> None:
    """The reported loss: `uavfmu build --params quad.json --only quadrotor` with a flat quadrotor file built an FMU
    with every default. The command now builds the file's inertia and motor lag into the FMU."""
    params = _file(tmp_path, FLAT_QUAD, "quad.json")
    parser = argparse.ArgumentParser()
    build_command.add_arguments(parser)
    args = parser.parse_args(["--params", str(params), "--only", "quadrotor", "--out", str(tmp_path / "dist"),
                              "--kind", "cs", "--platforms", "linux64"])
    assert build_command.run(args) == 0, capsys.readouterr().err
    starts = {v.name: float(v.start) for v in read_model_description(str(tmp_path / "dist" / "quadrotor.fmu"))
              .modelVariables if v.causality == "parameter"}
    for name, value in FLAT_QUAD.items():
        assert starts[name] == value, name
    assert starts["Jx_kg_m2"] != QuadrotorParams().Jx_kg_m2


def test_flat_files_of_either_vehicle_go_to_the_vehicle_their_keys_tell() -> None:
    assert split_params(FLAT_QUAD) == {"quadrotor": FLAT_QUAD}
    wing = {"C_ell_p": -0.4, "mass_kg": 12.0, "propulsion": {"D_prop_m": 0.5}}
    assert split_params(wing) == {"fixed_wing": wing}
    # comments and the identified covariance belong to the file, not to a vehicle
    assert split_params({"_note": "x", "uncertainty": {}, **FLAT_QUAD}) == {"quadrotor": FLAT_QUAD}
    # and so does the model's discrepancy (uavfmu discrepancy, identify aero --discrepancy), flat or sectioned
    assert split_params({"discrepancy": {}, "uncertainty": {}, **FLAT_QUAD}) == {"quadrotor": FLAT_QUAD}
    assert split_params({"fixed_wing": wing, "uncertainty": {}, "discrepancy": {}}) == {"fixed_wing": wing}
    bare_map = {"type": "anfis", "inputs": ["pwm_sum_us"]}
    assert split_params(bare_map) == {"quadrotor": {"thrust_map": bare_map}}


def test_a_flat_file_with_a_misspelt_key_still_goes_to_its_vehicle_whose_check_names_the_key(tmp_path: Path) -> None:
    params = _file(tmp_path, {"tau_motor_s": 0.02, "Jx_kg_m": 0.01})
    with pytest.raises(ParameterError) as err:
        build_fmus(params, tmp_path / "out", ["quadrotor"], options=LINUX_ONLY)
    assert "Jx_kg_m is not a parameter (did you mean Jx_kg_m2?)" in _problems(err)
    assert str(params) in str(err.value)


def test_keys_of_both_vehicles_alike_are_refused_asking_for_the_vehicle_key(tmp_path: Path) -> None:
    params = _file(tmp_path, {"Jx_kg_m2": 0.01, "mass_kg": 1.5})
    with pytest.raises(ParameterError) as err:
        build_fmus(params, tmp_path / "out", ["quadrotor"], options=LINUX_ONLY)
    text = _problems(err)
    assert "Jx_kg_m2, mass_kg" in text and "does not tell which vehicle" in text
    assert '"quadrotor" or "fixed_wing"' in text
    assert str(params) in str(err.value)
    assert not (tmp_path / "out").exists()  # refused before any work


def test_keys_of_two_vehicles_in_one_flat_file_are_refused_naming_each_side() -> None:
    with pytest.raises(ParameterError) as err:
        split_params({"tau_motor_s": 0.02, "C_ell_p": -0.4, "mass_kg": 2.0}, "mixed.json")
    text = _problems(err)
    assert "tau_motor_s only of quadrotor" in text and "C_ell_p only of fixed_wing" in text


def test_keys_of_no_vehicle_are_named_with_the_closest_parameter() -> None:
    with pytest.raises(ParameterError) as err:
        split_params({"Jx_kgm2": 0.01, "mass_kg": 1.0}, "typo.json")
    text = _problems(err)
    assert "Jx_kgm2 is a parameter of no vehicle" in text and "did you mean Jx_kg_m2" in text
    assert "mass_kg" in text and "does not tell which vehicle" in text


def test_keys_beside_the_vehicle_sections_are_refused_not_dropped() -> None:
    with pytest.raises(ParameterError) as err:
        split_params({"quadrotor": {"mass_kg": 1.2}, "tau_motor_s": 0.03}, "stray.json")
    assert "tau_motor_s sit beside the vehicle sections quadrotor" in _problems(err)


@pytest.mark.parametrize("data", [{}, {"_comment": "nothing"}, {"uncertainty": {"names": ["a"]}}])
def test_a_file_without_parameters_is_refused(data: dict) -> None:
    with pytest.raises(ParameterError, match="no parameters"):
        split_params(data, "empty.json")


def test_a_file_whose_keys_fit_no_model_being_built_is_refused_naming_them(tmp_path: Path) -> None:
    wing = _file(tmp_path, {"C_ell_p": -0.4, "C_n_r": -0.1})
    with pytest.raises(ParameterError) as err:
        build_fmus(wing, tmp_path / "out", ["quadrotor"], options=LINUX_ONLY)
    text = _problems(err)
    assert "fixed_wing only (fixed_wing: C_ell_p, C_n_r)" in text and "makes quadrotor" in text
    section = {"fixed_wing": {"C_ell_p": -0.4}}
    with pytest.raises(ParameterError, match="fixed_wing only"):
        sections_to_build(section, ["quadrotor"], "sectioned.json")
    # a file for both vehicles, building one: the built one's section is used
    both = {"quadrotor": {"tau_motor_s": 0.02}, "fixed_wing": {"C_ell_p": -0.4}}
    assert sections_to_build(both, ["quadrotor"], "both.json") == {"quadrotor": {"tau_motor_s": 0.02}}


def test_commands_that_read_one_vehicle_load_its_parameters_as_the_build_does(tmp_path: Path) -> None:
    """`excite --params` and `identify aero --init` read one vehicle's parameters: a flat file of it, or its section;
    a file that does not tell its vehicle, or holds another vehicle's parameters, is refused naming the keys."""
    quad = load_vehicle_params(_file(tmp_path, FLAT_QUAD, "quad.json"), "quadrotor")
    assert isinstance(quad, QuadrotorParams) and quad.tau_motor_s == 0.035 and quad.Jx_kg_m2 == 0.0123
    wing = load_vehicle_params(_file(tmp_path, {"fixed_wing": {"C_ell_p": -0.4}, "uncertainty": {},
                                                "discrepancy": {}}, "w.json"), "fixed_wing")
    assert isinstance(wing, FixedWingParams) and wing.C_ell_p == -0.4
    with pytest.raises(ParameterError, match="quadrotor only"):
        load_vehicle_params(_file(tmp_path, FLAT_QUAD, "quad.json"), "fixed_wing")
    with pytest.raises(ParameterError, match="does not tell which vehicle"):
        load_vehicle_params(_file(tmp_path, {"Jx_kg_m2": 0.01}, "amb.json"), "fixed_wing")

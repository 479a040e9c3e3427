"""Parameter files as strict schemas generated from the dataclass metadata (fmu_models.common.params)."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fmu_models.common.errors import ParameterError
from fmu_models.common.params import numeric_fields, read_json, validate_params
from fmu_models.config import ConfigError
from fmu_models.fixed_wing.params import DEFAULTS_FILE, REFERENCE_ONLY, RETIRED, FixedWingParams
from fmu_models.quadrotor.params import QuadrotorParams


def _problems(values: dict, cls: type = QuadrotorParams) -> list[str]:
    with pytest.raises(ParameterError) as info:
        cls.from_dict(values, source="p.json")
    assert isinstance(info.value, ConfigError) and isinstance(info.value, ValueError)
    assert "p.json" in str(info.value)
    return info.value.problems


@pytest.mark.parametrize("bad", [True, False, "1.14", None, [1.0], {"kg": 1.0}, math.nan, math.inf, -math.inf])
def test_mass_of_the_wrong_kind_is_refused_naming_field_value_and_range(bad: object) -> None:
    (line,) = _problems({"mass_kg": bad})
    assert line.startswith("mass_kg = ") and "\n" not in line
    assert "[0.05, 50.0] kg" in line


@pytest.mark.parametrize("bad", [-1.14, 0.0, 1e-3, 51])
def test_mass_out_of_range_is_refused(bad: float) -> None:
    (line,) = _problems({"mass_kg": bad})
    assert line == f"mass_kg = {float(bad)!r} is outside the allowed range [0.05, 50.0] kg"


def test_every_problem_is_listed_at_once_with_a_did_you_mean() -> None:
    lines = _problems({"mass_kg": True, "Jx_kg_m2": "0.007", "arm_lenght_m": 0.2, "frame": "hexa"})
    assert len(lines) == 4
    assert "arm_lenght_m is not a parameter (did you mean arm_length_m?)" in lines
    assert any(line.startswith("frame = 'hexa'") for line in lines)


def test_quadrotor_inertia_keys_of_0_1_are_named_with_their_new_name() -> None:
    """Jxx/Jyy/Jzz became Jx/Jy/Jz (as the fixed wing and the Aerosonde set name them)."""
    lines = _problems({"Jxx_kg_m2": 0.007, "Jzz_kg_m2": 0.013})
    assert lines == ["Jxx_kg_m2 is no longer a parameter: renamed Jx_kg_m2 (the same value); rename the key",
                     "Jzz_kg_m2 is no longer a parameter: renamed Jz_kg_m2 (the same value); rename the key"]
    assert QuadrotorParams.from_dict({"Jz_kg_m2": 0.02}).Jz_kg_m2 == 0.02


def test_integers_are_numbers_and_stored_as_floats() -> None:
    p = QuadrotorParams.from_dict({"mass_kg": 2})
    assert p.mass_kg == 2.0 and isinstance(p.mass_kg, float)


def test_fixed_wing_propulsion_table_is_checked_like_the_top_level() -> None:
    lines = _problems({"propulsion": {"D_prop_m": "big", "ncells": 1.5}, "C_ell_p": math.nan}, FixedWingParams)
    assert len(lines) == 3 and any(line.startswith("D_prop_m = 'big' is not a number") for line in lines)
    assert _problems({"propulsion": [1, 2]}, FixedWingParams) == ["propulsion = [1, 2] is not a table of parameters"]


def test_a_retired_key_says_what_to_do() -> None:
    @dataclasses.dataclass(frozen=True)
    class P:
        a: float = dataclasses.field(default=1.0, metadata={"unit": "m", "min": 0.0, "max": 2.0, "description": ""})

    with pytest.raises(ParameterError) as info:
        validate_params(P, {"old_a": 1.0}, "x.json", retired={"old_a": "renamed a"})
    assert info.value.problems == ["old_a is no longer a parameter: renamed a"]


def test_a_user_file_setting_a_reference_only_fixed_wing_key_is_told_what_to_do(tmp_path) -> None:
    f = tmp_path / "fw.json"
    f.write_text('{"fixed_wing": {"C_D_0": 0.043, "C_ell_p": -0.5, "epsilon": 0.16}}')
    with pytest.raises(ParameterError) as info:
        FixedWingParams.load(f)
    assert info.value.problems == [
        "C_D_0 is no longer a parameter: the drag polar uses C_D_p (parasitic drag) and e_oswald; set C_D_p instead "
        "and delete C_D_0",
        "epsilon is no longer a parameter: the model never used it; delete epsilon",
    ]
    assert set(RETIRED) == set(REFERENCE_ONLY)
    assert not {f.name for f in numeric_fields(FixedWingParams)} & set(REFERENCE_ONLY)


def test_the_published_aerosonde_file_still_loads_as_the_default_set(caplog: pytest.LogCaptureFixture) -> None:
    """The uavbook copy keeps its reference-only keys; the reference reader leaves them out with a note."""
    raw = read_json(DEFAULTS_FILE)
    assert set(REFERENCE_ONLY) <= set(raw)
    with caplog.at_level("INFO", logger="fmu_models.fixed_wing.params"):
        assert FixedWingParams.load_reference(DEFAULTS_FILE) == FixedWingParams() == FixedWingParams.load_reference()
    assert all(k in caplog.text for k in REFERENCE_ONLY) and "left out" in caplog.text
    assert FixedWingParams().C_L_alpha == raw["C_L_alpha"] and FixedWingParams().C_D_p == raw["C_D_p"]


def test_unreadable_files_name_the_file(tmp_path) -> None:
    with pytest.raises(ParameterError, match=r"missing\.json"):
        read_json(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"quadrotor": {"mass_kg": 1.2,}}')
    with pytest.raises(ParameterError, match=r"bad\.json.*\n.*not valid JSON"):
        QuadrotorParams.load(bad)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.data())
def test_any_value_inside_the_declared_range_is_taken_exactly(data: st.DataObject) -> None:
    cls = data.draw(st.sampled_from([QuadrotorParams, FixedWingParams]))
    f = data.draw(st.sampled_from(numeric_fields(cls)))
    lo, hi = f.metadata["min"], f.metadata["max"]
    if cls is QuadrotorParams and f.name == "pwm_idle_us":
        hi = 1400.0  # 4 x idle must stay below the thrust map's band (5800 us summed): a cross-field rule
    if cls is QuadrotorParams and f.name == "tau_motor_s":
        lo = QuadrotorParams.step_internal_s  # a motor lag no shorter than the internal step: a cross-field rule
    value = data.draw(st.floats(lo if lo is not None else -1e6, hi if hi is not None else 1e6))
    assert getattr(cls.from_dict({f.name: value}), f.name) == value


def test_a_motor_lag_shorter_than_the_internal_step_is_refused_naming_both() -> None:
    with pytest.raises(ParameterError, match=r"tau_motor_s = 0.0004 s is shorter than step_internal_s = 0.001 s"):
        QuadrotorParams.from_dict({"tau_motor_s": 4e-4})
    fine = QuadrotorParams.from_dict({"tau_motor_s": 4e-4, "step_internal_s": 2e-4})
    assert (fine.tau_motor_s, fine.step_internal_s) == (4e-4, 2e-4)
    assert QuadrotorParams.from_dict({"tau_motor_s": 0.0}).tau_motor_s == 0.0  # no motor lag at all


def test_physical_lower_bounds_of_masses_and_inertias_are_positive() -> None:
    for cls in (QuadrotorParams, FixedWingParams):
        for f in numeric_fields(cls):
            if f.name == "mass_kg" or (f.name.startswith("J") and f.name != "Jxz_kg_m2" and "rotor" not in f.name):
                assert f.metadata["min"] > 0, f"{cls.__name__}.{f.name} allows {f.metadata['min']}"


def test_a_vehicle_loader_reads_the_file_as_the_build_does(tmp_path) -> None:
    """``QuadrotorParams.load``/``FixedWingParams.load``: a flat file with an uncertainty block loads (the block is the
    file's, not the vehicle's); a file holding only the other vehicle's section, or keys beside the sections, is
    refused saying so, never read as that vehicle's defaults."""
    unc = {"names": ["Jx_kg_m2"], "mean": [0.011], "covariance": [[1e-8]]}
    flat = tmp_path / "flat.json"
    flat.write_text(json.dumps({"Jx_kg_m2": 0.011, "uncertainty": unc, "_note": "identified"}))
    assert QuadrotorParams.load(flat).Jx_kg_m2 == 0.011
    wing_only = tmp_path / "wing.json"
    wing_only.write_text(json.dumps({"fixed_wing": {"C_ell_p": -0.5}}))
    with pytest.raises(ParameterError) as info:
        QuadrotorParams.load(wing_only)
    assert str(wing_only) in str(info.value) and "fixed_wing section only and no quadrotor section" in str(info.value)
    quad_only = tmp_path / "quad.json"
    quad_only.write_text(json.dumps({"quadrotor": {"Jx_kg_m2": 0.011}}))
    with pytest.raises(ParameterError, match="quadrotor section only and no fixed_wing section"):
        FixedWingParams.load(quad_only)
    stray = tmp_path / "stray.json"
    stray.write_text(json.dumps({"fixed_wing": {"C_ell_p": -0.5}, "C_n_r": -0.1}))
    with pytest.raises(ParameterError, match="C_n_r sit beside the vehicle sections fixed_wing"):
        FixedWingParams.load(stray)
    assert FixedWingParams.load(wing_only).C_ell_p == -0.5
    not_table = tmp_path / "list.json"
    not_table.write_text(json.dumps({"quadrotor": [1, 2]}))
    with pytest.raises(ParameterError, match="quadrotor: expected a table of parameters, found list"):
        QuadrotorParams.load(not_table)

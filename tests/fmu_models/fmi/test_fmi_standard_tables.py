"""The FMUs' state table (fmu_models/fmi/statemachine.py, from which the C layers are generated) against the FMI 2.0.4
and 3.0.2 tables written out in fmi_standard.py from the standards, cell by cell: a wrong row fails with the
function, the state and what each side says. The deliberate differences are listed, with their reasons, in
``fmi_standard.DEVIATIONS``; a listed difference that is no longer one fails too."""

from __future__ import annotations

import pytest

from fmu_models.fmi.statemachine import INTERFACE, MASKS, masks
from tests.fmu_models.fmi import fmi_standard as fs


def _differences(version: int, table: dict[str, tuple[str, ...]]) -> list[str]:
    """Every cell where ``table`` differs from the standard's table with the listed deviations."""
    out = []
    for row in fs.ROWS:
        std = fs.standard_states(version, row)
        if std is None:
            continue
        functions = ", ".join(fs.ROWS[row].fmi2 if version == 2 else fs.ROWS[row].fmi3)
        for state in fs.STATES[version]:
            dev = fs.DEVIATIONS.get((version, row, state))
            want = dev.allowed if dev else state in std
            got = state in table[row]
            if got != want:
                source = f"the listed deviation ({dev.why})" if dev else f"FMI {version}.0"
                out.append(f"{row} ({functions}) in {state}: statemachine.py {'allows' if got else 'refuses'} it, "
                           f"{source} {'allows' if want else 'refuses'} it")
    return out


@pytest.mark.parametrize("version", [2, 3])
def test_the_generated_table_is_the_standards_cell_by_cell(version: int) -> None:
    diff = _differences(version, masks(version))
    assert not diff, f"FMI {version}.0 state table:\n" + "\n".join(diff)


def test_a_wrong_row_is_named_with_its_function_and_state() -> None:
    """The comparison itself: Terminate also allowed in Instantiated (against both standards) is reported."""
    wrong = {**masks(2), "Terminate": ("Instantiated", *MASKS["Terminate"])}
    assert _differences(2, wrong) == ["Terminate (fmi2Terminate) in Instantiated: statemachine.py allows it, "
                                      "FMI 2.0 refuses it"]


def test_every_listed_deviation_differs_from_the_standard_and_every_row_is_mapped() -> None:
    for (version, row, state), dev in fs.DEVIATIONS.items():
        std = fs.standard_states(version, row)
        assert std is not None and (state in std) != dev.allowed, f"FMI {version} {row} in {state}: not a deviation"
    assert set(MASKS) == set(fs.ROWS), "a row of statemachine.py without its standard functions in fmi_standard.ROWS"


def test_fmi3_interface_of_each_row_is_the_standards() -> None:
    got = {row: INTERFACE.get(row) for row in fs.ROWS if fs.ROWS[row].fmi3}
    assert got == {row: fs.interface(row) for row in got}


def test_the_written_tables_read_as_the_standard_says() -> None:
    """Spot checks of the transcription against sentences of the standards."""
    # FMI 2.0.4 4.2.4: fmi2DoStep only in stepComplete; fmi2Terminate in stepComplete and stepFailed
    assert fs.standard_states(2, "DoStep") == {"StepComplete"}
    assert fs.standard_states(2, "Terminate") == {"StepComplete", "StepFailed", "EventMode", "ContinuousTimeMode"}
    # both FMI 2.0 tables agree on the states they share, for the functions they share
    shared = set(fs.FMI2_CS_COLUMNS) & set(fs.FMI2_ME_COLUMNS)
    for fn in set(fs.FMI2_CS) & set(fs.FMI2_ME):
        assert {s: c for s, c in fs.FMI2_CS[fn].items() if s in shared} == {
            s: c for s, c in fs.FMI2_ME[fn].items() if s in shared}, fn
    # FMI 3.0.2 2.3.2 and 3.2.1: start values readable in Instantiated, outputs not; fmi3SetTime and
    # fmi3EnterEventMode only in Continuous-Time Mode (Co-Simulation without event mode)
    assert "Instantiated" in fs.standard_states(3, "GetStart") and "Instantiated" not in fs.standard_states(
        3, "GetValue")
    assert fs.standard_states(3, "SetTime") == fs.standard_states(3, "EnterEventMode") == {"ContinuousTimeMode"}
    # 2.3.1: fmi3Error leads to Terminated; Terminate itself only in the Initialized states
    assert fs.standard_states(3, "Terminate") == {"EventMode", "ContinuousTimeMode", "StepComplete"}
    assert "Error" in fs.standard_states(3, "GetValue")

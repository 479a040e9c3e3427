"""Which FMI function may be called in which state, written out from the standards, not from the FMUs' own table.

The call-sequence oracle (``fmi_oracle.py``) judges every answer by :func:`oracle_table`, and
``test_fmi_standard_tables.py`` compares ``fmu_models/fmi/statemachine.py`` (the table the FMUs are generated from)
with it cell by cell. Sources (modelica/fmi-standard, tags ``v2.0.4`` and ``v3.0.2``):

* FMI 2.0.4 gives the allowed calls as two tables: section 3.2.3 (Model Exchange, ``docs/3_2_model_exchange_api
  .adoc``) and section 4.2.4 (Co-Simulation, ``docs/4_2_co-simulation_api.adoc``), copied below cell by cell
  (``x`` allowed, ``.`` not, a digit: allowed under the standard's numbered condition, see ``FMI2_CONDITIONS``).
* FMI 3.0.2 gives them per state, as the "Allowed Function Calls" of each state of the state machines (figures
  "Common calling sequence", "Calling sequence of Model Exchange C functions", "... of Co-Simulation C
  functions"): sections 2.3.1-2.3.8 (common states), 3.2.1 (Continuous-Time Mode), 4.2.1 (Step Mode), copied
  below as lists of functions per state.

State names are those of statemachine.py's bits (FMI 3.0's Step Mode is FMI 2.0's stepComplete: ``StepComplete``).
Where the FMUs deliberately answer otherwise, the cell is listed in ``DEVIATIONS`` with the reason; the oracle uses
the standard's table with those cells changed, and the comparison fails on any other difference.
"""

from __future__ import annotations

from typing import NamedTuple

# ----------------------------------------------------------------------------------------- FMI 2.0.4
#: FMI 2.0.4 section 4.2.4, the table "allowed function calls in the respective states" for Co-Simulation
FMI2_CS_COLUMNS = ("StartAndEnd", "Instantiated", "InitializationMode", "StepComplete", "StepInProgress",
                   "StepFailed", "StepCanceled", "Terminated", "Error", "Fatal")
FMI2_CS_TABLE = """
fmi2GetTypesPlatform          x x x x x x x x x .
fmi2GetVersion                x x x x x x x x x .
fmi2SetDebugLogging           . x x x x x x x x .
fmi2Instantiate               x . . . . . . . . .
fmi2FreeInstance              . x x x . x x x x .
fmi2SetupExperiment           . x . . . . . . . .
fmi2EnterInitializationMode   . x . . . . . . . .
fmi2ExitInitializationMode    . . x . . . . . . .
fmi2Terminate                 . . . x . x . . . .
fmi2Reset                     . x x x . x x x x .
fmi2GetReal                   . . 2 x . 8 7 x 7 .
fmi2GetInteger                . . 2 x . 8 7 x 7 .
fmi2GetBoolean                . . 2 x . 8 7 x 7 .
fmi2GetString                 . . 2 x . 8 7 x 7 .
fmi2SetReal                   . 1 3 6 . . . . . .
fmi2SetInteger                . 1 3 6 . . . . . .
fmi2SetBoolean                . 1 3 6 . . . . . .
fmi2SetString                 . 1 3 6 . . . . . .
fmi2GetFMUstate               . x x x . 8 7 x 7 .
fmi2SetFMUstate               . x x x . x x x x .
fmi2FreeFMUstate              . x x x . x x x x .
fmi2SerializedFMUstateSize    . x x x . x x x x .
fmi2SerializeFMUstate         . x x x . x x x x .
fmi2DeSerializeFMUstate       . x x x . x x x x .
fmi2GetDirectionalDerivative  . . x x . 8 7 x 7 .
fmi2SetRealInputDerivatives   . x x x . . . . . .
fmi2GetRealOutputDerivatives  . . . x . 8 x x 7 .
fmi2DoStep                    . . . x . . . . . .
fmi2CancelStep                . . . . x . . . . .
fmi2GetStatus                 . . . x x x . x . .
fmi2GetRealStatus             . . . x x x . x . .
fmi2GetIntegerStatus          . . . x x x . x . .
fmi2GetBooleanStatus          . . . x x x . x . .
fmi2GetStringStatus           . . . x x x . x . .
"""

#: FMI 2.0.4 section 3.2.3, the same table for Model Exchange
FMI2_ME_COLUMNS = ("StartAndEnd", "Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode",
                   "Terminated", "Error", "Fatal")
FMI2_ME_TABLE = """
fmi2GetTypesPlatform               x x x x x x x .
fmi2GetVersion                     x x x x x x x .
fmi2SetDebugLogging                . x x x x x x .
fmi2Instantiate                    x . . . . . . .
fmi2FreeInstance                   . x x x x x x .
fmi2SetupExperiment                . x . . . . . .
fmi2EnterInitializationMode        . x . . . . . .
fmi2ExitInitializationMode         . . x . . . . .
fmi2Terminate                      . . . x x . . .
fmi2Reset                          . x x x x x x .
fmi2GetReal                        . . 2 x x x 7 .
fmi2GetInteger                     . . 2 x x x 7 .
fmi2GetBoolean                     . . 2 x x x 7 .
fmi2GetString                      . . 2 x x x 7 .
fmi2SetReal                        . 1 3 4 5 . . .
fmi2SetInteger                     . 1 3 4 . . . .
fmi2SetBoolean                     . 1 3 4 . . . .
fmi2SetString                      . 1 3 4 . . . .
fmi2GetFMUstate                    . x x x x x 7 .
fmi2SetFMUstate                    . x x x x x x .
fmi2FreeFMUstate                   . x x x x x x .
fmi2SerializedFMUstateSize         . x x x x x x .
fmi2SerializeFMUstate              . x x x x x x .
fmi2DeSerializeFMUstate            . x x x x x x .
fmi2GetDirectionalDerivative       . . x x x x 7 .
fmi2EnterEventMode                 . . . x x . . .
fmi2NewDiscreteStates              . . . x . . . .
fmi2EnterContinuousTimeMode        . . . x . . . .
fmi2CompletedIntegratorStep        . . . . x . . .
fmi2SetTime                        . . . 8 x . . .
fmi2SetContinuousStates            . . . . x . . .
fmi2GetEventIndicators             . . x x x x 7 .
fmi2GetContinuousStates            . . x x x x 7 .
fmi2GetDerivatives                 . . x x x x 7 .
fmi2GetNominalsOfContinuousStates  . x x x x x 7 .
"""

#: The kinds of variable the FMUs have (modelDescription: inputs are continuous Reals with a start value,
#: parameters have a start value (initial exact) and are tunable or fixed, every other variable is an output or a
#: state or derivative computed by the model: initial calculated, in ``<InitialUnknowns>``, no start value).
INPUT, TUNABLE, FIXED, COMPUTED = "input", "tunable parameter", "fixed parameter", "computed"

#: FMI 2.0.4 footnotes of both tables: which of the FMUs' kinds of variable each numbered condition admits
FMI2_CONDITIONS: dict[str, frozenset[str]] = {
    # 1: variability != constant with initial = exact or approx (inputs have no initial attribute in FMI 2.0:
    #    section 4.2.4 "this does not include inputs")
    "1": frozenset({TUNABLE, FIXED}),
    # 2: causality = output or listed under <ModelStructure><InitialUnknowns>
    "2": frozenset({COMPUTED}),
    # 3: variability != constant with initial = exact, or causality = input
    "3": frozenset({INPUT, TUNABLE, FIXED}),
    # 4: causality = input, or causality = parameter and variability = tunable
    "4": frozenset({INPUT, TUNABLE}),
    # 5: causality = input and variability = continuous, and continuous-time states
    "5": frozenset({INPUT}),
    # 6: causality = input, or causality = parameter and variability = tunable
    "6": frozenset({INPUT, TUNABLE}),
    # 7: always, values for debugging only; 8: always (Get, FMU state), values usable only after fmi2Terminated
    "7": frozenset({INPUT, TUNABLE, FIXED, COMPUTED}),
    "8": frozenset({INPUT, TUNABLE, FIXED, COMPUTED}),
}
#: FMI 2.0.4 section 3.2.3, footnote 8 of fmi2SetTime in Event Mode: "only for a Pure Discrete-Time FMU"; both
#: FMUs have continuous states, so the condition never holds for them
FMI2_SET_TIME_IN_EVENT_MODE = False


def _parse(columns: tuple[str, ...], text: str) -> dict[str, dict[str, str]]:
    table = {}
    for line in text.strip().splitlines():
        fn, *cells = line.split()
        assert len(cells) == len(columns), f"{fn}: {len(cells)} cells for {len(columns)} states"
        table[fn] = {state: cell for state, cell in zip(columns, cells, strict=True) if cell != "."}
    return table


FMI2_CS = _parse(FMI2_CS_COLUMNS, FMI2_CS_TABLE)
FMI2_ME = _parse(FMI2_ME_COLUMNS, FMI2_ME_TABLE)


# ----------------------------------------------------------------------------------------- FMI 3.0.2
GET, SET = "fmi3Get{VariableType}", "fmi3Set{VariableType}"
FMU_STATE = ("fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState", "fmi3SerializedFMUStateSize",
             "fmi3SerializeFMUState", "fmi3DeserializeFMUState")
DERIVATIVES = ("fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative")
_ALL = frozenset({INPUT, TUNABLE, FIXED, COMPUTED})

#: FMI 3.0.2 section 2.3.1, super state FMU State Settable (every state from instantiation until the instance is
#: freed or fatal): allowed in each of its states
FMI3_SETTABLE = ("fmi3SetDebugLogging", "fmi3Reset", "fmi3FreeInstance", *FMU_STATE)
FMI3_SETTABLE_STATES = ("Instantiated", "ConfigurationMode", "InitializationMode", "EventMode", "ContinuousTimeMode",
                        "StepComplete", "Terminated")
#: FMI 3.0.2 section 2.3.4, super state Initialized (entered by fmi3ExitInitializationMode: Event Mode,
#: Continuous-Time Mode, Step Mode): allowed in each of its states
FMI3_INITIALIZED = ("fmi3GetNominalsOfContinuousStates", "fmi3Terminate")
FMI3_INITIALIZED_STATES = ("EventMode", "ContinuousTimeMode", "StepComplete")

#: FMI 3.0.2, "Allowed Function Calls" of each state. Get and Set: ``(function, kinds of variable)``, the kinds the
#: section's sentence admits among the FMUs' (see ``INPUT`` ...).
FMI3_STATES: dict[str, tuple[str | tuple[str, frozenset[str]], ...]] = {
    # 2.3.2 Instantiated: Set of variables with initial = exact or approx ("inputs, parameters ... are included"),
    # Get of start values (the section's table: "Get variable start values as defined in modelDescription.xml";
    # computed variables have none)
    "Instantiated": ((SET, frozenset({INPUT, TUNABLE, FIXED})), (GET, frozenset({INPUT, TUNABLE, FIXED})),
                     "fmi3EnterConfigurationMode", "fmi3GetNumberOfContinuousStates",
                     "fmi3GetNumberOfEventIndicators", "fmi3EnterInitializationMode"),
    # 2.3.3 Initialization Mode: Set of variables with initial = exact (inputs and parameters included), Get
    "InitializationMode": ((SET, frozenset({INPUT, TUNABLE, FIXED})), (GET, _ALL),
                           "fmi3GetContinuousStateDerivatives", "fmi3GetContinuousStates",
                           "fmi3GetNominalsOfContinuousStates", *DERIVATIVES, "fmi3GetEventIndicators",
                           "fmi3GetShiftDecimal", "fmi3GetShiftFraction", "fmi3GetIntervalDecimal",
                           "fmi3GetIntervalFraction", "fmi3SetShiftDecimal", "fmi3SetShiftFraction",
                           "fmi3SetIntervalDecimal", "fmi3SetIntervalFraction", "fmi3ExitInitializationMode"),
    # 2.3.5 Event Mode: Set of inputs and tunable parameters (and states with reinit), Get
    "EventMode": ((SET, frozenset({INPUT, TUNABLE})), (GET, _ALL),
                  "fmi3SetClock", "fmi3GetClock", "fmi3GetIntervalDecimal", "fmi3GetIntervalFraction", *DERIVATIVES,
                  "fmi3GetContinuousStates", "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators",
                  "fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators", "fmi3EvaluateDiscreteStates",
                  "fmi3UpdateDiscreteStates", "fmi3EnterConfigurationMode", "fmi3EnterContinuousTimeMode",
                  "fmi3EnterStepMode"),
    # 3.2.1 Continuous-Time Mode: Set of continuous-time inputs and states, Get
    "ContinuousTimeMode": ("fmi3SetTime", (SET, frozenset({INPUT})), (GET, _ALL),
                           "fmi3SetContinuousStates", "fmi3GetContinuousStates", "fmi3GetContinuousStateDerivatives",
                           "fmi3GetEventIndicators", "fmi3CompletedIntegratorStep", "fmi3EnterEventMode",
                           *DERIVATIVES),
    # 4.2.1 Step Mode: Set of inputs and tunable parameters, Get; fmi3EnterEventMode "must not be called if
    # fmi3InstantiateCoSimulation signaled eventModeUsed = fmi3False" (the FMUs have hasEventMode = false)
    "StepComplete": ((SET, frozenset({INPUT, TUNABLE})), (GET, _ALL),
                     "fmi3GetOutputDerivatives", *DERIVATIVES, "fmi3DoStep", "fmi3EnterConfigurationMode"),
    # 2.3.6 Configuration Mode: Set of structural parameters only (the FMUs have none)
    "ConfigurationMode": ("fmi3ExitConfigurationMode",),
    # 2.3.8 Terminated: Get and the computed quantities
    "Terminated": ((GET, _ALL), "fmi3GetContinuousStateDerivatives",
                   "fmi3GetContinuousStates", "fmi3GetNominalsOfContinuousStates", "fmi3GetEventIndicators",
                   *DERIVATIVES, "fmi3GetOutputDerivatives"),
}
#: FMI 3.0.2 section 2.3.1: "If any function called in super state FMU State Settable returns fmi3Error, the FMU
#: enters state Terminated": the FMUs' Error state (a model failure) is FMI 3.0's Terminated
FMI3_ERROR_IS = "Terminated"

#: FMI 3.0.2: functions of one interface only ("This function can only be called in Model Exchange", "Not allowed
#: in Co-Simulation and Scheduled Execution", sections 2.3.2-2.3.8, 3.2.1; Co-Simulation: 4.2.1 and fmi3DoStep)
FMI3_ME_ONLY = ("fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators", "fmi3GetContinuousStates",
                "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators", "fmi3GetNominalsOfContinuousStates",
                "fmi3SetTime", "fmi3SetContinuousStates", "fmi3CompletedIntegratorStep", "fmi3EnterContinuousTimeMode")
FMI3_CS_ONLY = ("fmi3DoStep", "fmi3EnterStepMode", "fmi3GetOutputDerivatives")
#: the states an instance of one interface can be in (Co-Simulation without event mode never enters Event Mode)
FMI3_INTERFACE_STATES = {
    "ModelExchange": ("Instantiated", "ConfigurationMode", "InitializationMode", "EventMode", "ContinuousTimeMode",
                      "Terminated", "Error"),
    "CoSimulation": ("Instantiated", "ConfigurationMode", "InitializationMode", "EventMode", "StepComplete",
                     "Terminated", "Error"),
}


def _fmi3_allowed(fn: str, kind: str | None = None) -> set[str]:
    """States in which FMI 3.0 allows ``fn`` (for Get and Set: for a variable of ``kind``)."""
    states = set()
    for state, calls in FMI3_STATES.items():
        for call in calls:
            name, kinds = call if isinstance(call, tuple) else (call, None)
            if name == fn and (kinds is None or kind in kinds):
                states.add(state)
    if fn in FMI3_SETTABLE:
        states |= set(FMI3_SETTABLE_STATES)
    if fn in FMI3_INITIALIZED:
        states |= set(FMI3_INITIALIZED_STATES)
    if FMI3_ERROR_IS in states:
        states.add("Error")
    interface = "ModelExchange" if fn in FMI3_ME_ONLY else "CoSimulation" if fn in FMI3_CS_ONLY else None
    return states & set(FMI3_INTERFACE_STATES[interface]) if interface else states


def _fmi2_allowed(fn: str, kind: str | None = None) -> set[str]:
    """States in which FMI 2.0 allows ``fn`` in either interface's table (Get and Set: for a variable of ``kind``)."""
    states = set()
    for table in (FMI2_CS, FMI2_ME):
        for state, cell in table.get(fn, {}).items():
            if fn == "fmi2SetTime" and state == "EventMode":
                ok = FMI2_SET_TIME_IN_EVENT_MODE
            else:
                ok = cell == "x" or kind is None or kind in FMI2_CONDITIONS[cell]
            if ok:
                states.add(state)
    return states


# ----------------------------------------------------------------------------------------- the FMUs' rows
class Row(NamedTuple):
    """An operation of the FMUs' state table: the standard's functions it serves, per FMI version, and the kinds
    of variable it reads or writes (None: not a value access)."""

    fmi2: tuple[str, ...]
    fmi3: tuple[str, ...]
    kinds: frozenset[str] | None = None


#: which standard functions each row of the FMUs' table answers (from the C layers, fmi2Functions.c and
#: fmi3Functions.c, and the value access of uavfmu_core.h: Get picks GetStart for inputs and parameters,
#: GetValue for the rest; Set picks SetInput, SetTunable or SetFixed by causality and variability)
ROWS: dict[str, Row] = {
    "SetDebugLogging": Row(("fmi2SetDebugLogging",), ("fmi3SetDebugLogging",)),
    "SetupExperiment": Row(("fmi2SetupExperiment",), ()),
    "EnterInitializationMode": Row(("fmi2EnterInitializationMode",), ("fmi3EnterInitializationMode",)),
    "ExitInitializationMode": Row(("fmi2ExitInitializationMode",), ("fmi3ExitInitializationMode",)),
    "Terminate": Row(("fmi2Terminate",), ("fmi3Terminate",)),
    "Reset": Row(("fmi2Reset",), ("fmi3Reset",)),
    "GetValue": Row(("fmi2GetReal", "fmi2GetBoolean"), (GET,), frozenset({COMPUTED})),
    "GetStart": Row(("fmi2GetReal", "fmi2GetBoolean"), (GET,), frozenset({INPUT, TUNABLE, FIXED})),
    "SetInput": Row(("fmi2SetReal",), (SET,), frozenset({INPUT})),  # every input is a Real
    "SetTunable": Row(("fmi2SetReal",), (SET,), frozenset({TUNABLE})),
    "SetFixed": Row(("fmi2SetReal",), (SET,), frozenset({FIXED})),
    "FMUState": Row(("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize",
                     "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate"), FMU_STATE),
    "DoStep": Row(("fmi2DoStep",), ("fmi3DoStep",)),
    "CancelStep": Row(("fmi2CancelStep",), ()),
    "GetStatus": Row(("fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus",
                      "fmi2GetStringStatus"), ()),
    "SetInputDerivatives": Row(("fmi2SetRealInputDerivatives",), ()),
    "GetOutputDerivatives": Row(("fmi2GetRealOutputDerivatives",), ("fmi3GetOutputDerivatives",)),
    "GetDirectionalDerivative": Row(("fmi2GetDirectionalDerivative",), DERIVATIVES),
    "EnterEventMode": Row(("fmi2EnterEventMode",), ("fmi3EnterEventMode",)),
    "NewDiscreteStates": Row(("fmi2NewDiscreteStates",), ("fmi3UpdateDiscreteStates", "fmi3EvaluateDiscreteStates")),
    "EnterContinuousTimeMode": Row(("fmi2EnterContinuousTimeMode",), ("fmi3EnterContinuousTimeMode",)),
    "CompletedIntegratorStep": Row(("fmi2CompletedIntegratorStep",), ("fmi3CompletedIntegratorStep",)),
    "SetTime": Row(("fmi2SetTime",), ("fmi3SetTime",)),
    "SetContinuousStates": Row(("fmi2SetContinuousStates",), ("fmi3SetContinuousStates",)),
    "GetContinuousStates": Row(("fmi2GetContinuousStates",), ("fmi3GetContinuousStates",)),
    "GetDerivatives": Row(("fmi2GetDerivatives",), ("fmi3GetContinuousStateDerivatives",)),
    "GetEventIndicators": Row(("fmi2GetEventIndicators",), ("fmi3GetEventIndicators",)),
    "GetNominals": Row(("fmi2GetNominalsOfContinuousStates",), ("fmi3GetNominalsOfContinuousStates",)),
    "GetNumberOfStates": Row((), ("fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators")),
    # fmi3GetNumberOfVariableDependencies / fmi3GetVariableDependencies: section 2.2.11 names no state; taken as
    # allowed wherever an instance lives (super state FMU State Settable)
    "GetNumber": Row((), ("fmi3GetNumberOfVariableDependencies",)),
    "EnterStepMode": Row((), ("fmi3EnterStepMode",)),
    "EnterConfigurationMode": Row((), ("fmi3EnterConfigurationMode",)),
    "ExitConfigurationMode": Row((), ("fmi3ExitConfigurationMode",)),
    # the clock interval and shift functions (the FMUs have no clocks: each answers an error where allowed)
    "Clock": Row((), ("fmi3GetIntervalDecimal", "fmi3GetIntervalFraction", "fmi3GetShiftDecimal",
                      "fmi3GetShiftFraction", "fmi3SetIntervalDecimal", "fmi3SetIntervalFraction",
                      "fmi3SetShiftDecimal", "fmi3SetShiftFraction")),
}
#: the states of each version's state machines that the FMUs' table has (FMI 2.0: both tables' columns; FMI 3.0:
#: the common, Model Exchange and Co-Simulation states; Error as in ``FMI3_ERROR_IS``)
STATES = {
    2: ("StartAndEnd", "Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "StepComplete",
        "StepInProgress", "StepFailed", "StepCanceled", "Terminated", "Error", "Fatal"),
    3: ("StartAndEnd", "Instantiated", "ConfigurationMode", "InitializationMode", "EventMode", "ContinuousTimeMode",
        "StepComplete", "Terminated", "Error", "Fatal"),
}


def standard_states(version: int, row: str) -> set[str] | None:
    """States in which FMI ``version`` allows the calls of ``row`` (any of its functions; the standard must treat
    every kind of variable the row serves alike); None when the version has no function of that row."""
    r = ROWS[row]
    functions = r.fmi2 if version == 2 else r.fmi3
    if not functions:
        return None
    if row == "GetNumber":
        return set(FMI3_SETTABLE_STATES) | {"Error"}
    allowed = _fmi2_allowed if version == 2 else _fmi3_allowed
    out: set[str] = set()
    for fn in functions:
        per_kind = [allowed(fn, kind) for kind in (sorted(r.kinds) if r.kinds else [None])]
        assert all(p == per_kind[0] for p in per_kind), f"FMI {version} {fn}: the kinds of {row} differ: {per_kind}"
        out |= per_kind[0]
    return out


def interface(row: str) -> str | None:
    """FMI 3.0: the interface whose instances may call the row's functions (None: both)."""
    fns = ROWS[row].fmi3
    if fns and all(f in FMI3_ME_ONLY for f in fns):
        return "ModelExchange"
    if fns and all(f in FMI3_CS_ONLY for f in fns):
        return "CoSimulation"
    return None


# ----------------------------------------------------------------------------------------- the FMUs' choices
class Deviation(NamedTuple):
    """A cell where the FMUs answer otherwise than the standard: allowed by them (True) or refused, and why."""

    allowed: bool
    why: str


_ERROR_GET = "the Get functions also answer in the Error state, for diagnostics"
_ERROR_TERMINATE = ("Terminate is also accepted in the Error state (importers such as FMPy terminate after a failed "
                    "step before freeing)")
_SYNCHRONOUS = "fmi2DoStep is synchronous: StepInProgress is never entered"
_NEVER_CANCELED = "fmi2CancelStep never succeeds (synchronous steps): StepCanceled is never entered"
_NO_CONFIGURATION = ("Configuration Mode is never entered: no structural parameters, fmi3EnterConfigurationMode "
                     "answers an error")
_INPUT_STARTS = ("inputs can be set in Instantiated (their start values), as FMI 3.0 allows; FMI 2.0's condition 1 "
                 "admits only variables with an initial attribute, which inputs lack")
_READ_BACK = ("inputs and parameters can be read back in Initialization Mode, as FMI 3.0 allows; FMI 2.0's "
              "condition 2 admits only outputs and initial unknowns")
_SET_TIME = ("fmi2SetTime is also accepted in Event Mode (FMI 2.0 allows it there only for a pure discrete-time "
             "FMU; FMI 3.0's table is stricter and is followed)")
_NOMINALS = ("fmi3GetNominalsOfContinuousStates also answers in Instantiated, as fmi2GetNominalsOfContinuousStates "
             "does (the nominals are constants of the model)")
_NUMBERS = ("fmi3GetNumberOfContinuousStates and fmi3GetNumberOfEventIndicators answer wherever an instance lives "
            "(the numbers never change: no structural parameters); a Co-Simulation instance gets an interface error")
#: (FMI version, row, state) -> the FMUs' answer and why; the same choices are listed in statemachine.py's docstring
DEVIATIONS: dict[tuple[int, str, str], Deviation] = {
    (2, "Terminate", "Error"): Deviation(True, _ERROR_TERMINATE),
    (3, "Terminate", "Error"): Deviation(True, _ERROR_TERMINATE),
    (2, "GetStatus", "Error"): Deviation(True, _ERROR_GET),
    (2, "GetStatus", "StepCanceled"): Deviation(True, _NEVER_CANCELED),
    (2, "GetStatus", "StepInProgress"): Deviation(False, _SYNCHRONOUS),
    (2, "SetDebugLogging", "StepInProgress"): Deviation(False, _SYNCHRONOUS),
    (2, "SetInput", "Instantiated"): Deviation(True, _INPUT_STARTS),
    (2, "GetStart", "InitializationMode"): Deviation(True, _READ_BACK),
    (2, "SetTime", "EventMode"): Deviation(True, _SET_TIME),
    **{(3, row, "ConfigurationMode"): Deviation(False, _NO_CONFIGURATION)
       for row in ("SetDebugLogging", "Reset", "FMUState", "GetNumber")},
    (3, "GetNominals", "Instantiated"): Deviation(True, _NOMINALS),
    **{(3, "GetNumberOfStates", state): Deviation(True, _NUMBERS)
       for state in ("InitializationMode", "ContinuousTimeMode", "StepComplete", "Terminated", "Error")},
}


def oracle_table(version: int) -> dict[str, tuple[str, ...]]:
    """Row -> states where the FMUs must accept its calls: the standard's table (``standard_states``) with the
    ``DEVIATIONS`` cells changed. Rows without a function in this version are left out."""
    out = {}
    for row in ROWS:
        states = standard_states(version, row)
        if states is None:
            continue
        for (v, r, state), d in DEVIATIONS.items():
            if v == version and r == row:
                (states.add if d.allowed else states.discard)(state)
        out[row] = tuple(s for s in STATES[version] if s in states)
    return out

"""The one FMI state machine of every uavfmu FMU: allowed-state masks and argument rules, as a table.

From this table ``header()`` generates ``uavfmu_states.h``, which the native FMI 2.0 / 3.0 layers
(``native/fmi2Functions.c``, ``native/fmi3Functions.c`` over ``native/uavfmu_core.h``) and the pythonfmu guard
(``shim.py``) include. States follow the FMI 2.0.4 (sections 3.2.3, 4.2.4) and FMI 3.0 state machines; FMI 3.0's
Step Mode is FMI 2.0's stepComplete. The call-sequence tests (tests/fmu_models/fmi/test_fmi_sequences.py, FMI 2.0
on every backend, and test_fmi3_sequences.py, FMI 3.0) do not judge by this table but by the standards' tables
written out in tests/fmu_models/fmi/fmi_standard.py, and test_fmi_standard_tables.py compares this table with them
cell by cell. Deliberate, documented choices beyond the standards' tables (listed there too):

* the Get functions (values, status, continuous states) also answer in the Error state, for diagnostics;
* Terminate is also accepted in the Error state (importers such as FMPy terminate after a failed step before
  freeing; it only moves the instance to Terminated, from which Reset starts again);
* fmi2DoStep is synchronous: the StepInProgress state is never entered, so fmi2CancelStep always answers
  "not allowed in state" (and the Get*Status kinds about a pending step are never available);
* FMI 2.0 as FMI 3.0 allows: inputs can be set in Instantiated (their start values) and inputs and parameters read
  back in Initialization Mode (FMI 2.0's table admits only variables with an initial attribute, and outputs and
  initial unknowns); fmi2SetTime is also accepted in Event Mode (FMI 2.0: only for a pure discrete-time FMU);
* FMI 3.0: fmi3GetNominalsOfContinuousStates also answers in Instantiated (as in FMI 2.0), the numbers of
  continuous states and event indicators wherever an instance lives (they never change);
* no structural parameters, clocks or event mode in Co-Simulation: the FMI 3.0 configuration and clock
  functions answer an error (Configuration Mode is never entered);
* a refused call (state, arguments, interface) changes nothing, in FMI 3.0 too (where the standard lets an FMU
  that returned fmi3Error go to Terminated); a model failure moves the instance to the Error state, which
  answers what FMI 3.0's Terminated answers (Get, Reset, FMU state) and Terminate;
* a communication step that would need more than ``MAX_INTERNAL_STEPS`` internal RK4 steps is refused with an
  error before any work (so an enormous step can neither hang the host nor overflow a counter).
"""

from __future__ import annotations

from dataclasses import dataclass

#: one bit per state (the bit values are shared by the FMI 2.0 and FMI 3.0 layers)
STATES: dict[str, int] = {
    "StartAndEnd": 1 << 0,
    "Instantiated": 1 << 1,
    "InitializationMode": 1 << 2,
    "EventMode": 1 << 3,
    "ContinuousTimeMode": 1 << 4,
    "StepComplete": 1 << 5,
    "StepInProgress": 1 << 6,
    "StepFailed": 1 << 7,
    "StepCanceled": 1 << 8,
    "Terminated": 1 << 9,
    "Error": 1 << 10,
    "Fatal": 1 << 11,
    "ConfigurationMode": 1 << 12,
}
STATE_TEXT = {
    "StartAndEnd": "start/end", "Instantiated": "instantiated", "InitializationMode": "initialization mode",
    "EventMode": "event mode", "ContinuousTimeMode": "continuous-time mode", "StepComplete": "step complete",
    "StepInProgress": "step in progress", "StepFailed": "step failed", "StepCanceled": "step canceled",
    "Terminated": "terminated", "Error": "error", "Fatal": "fatal", "ConfigurationMode": "configuration mode",
}

#: the largest number of internal RK4 steps one communication step may take (1e6 x ~1 us: about a second)
MAX_INTERNAL_STEPS = 1_000_000
#: |currentCommunicationPoint - last communication point| allowed, relative to max(1, |last|)
TIME_TOLERANCE = 1e-9


def _mask(*names: str) -> int:
    return sum(STATES[n] for n in names)


LIVE = ("Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "StepComplete", "StepFailed",
        "StepCanceled", "Terminated", "Error")
INITIALIZED = ("EventMode", "ContinuousTimeMode", "StepComplete", "StepFailed", "StepCanceled", "Terminated")

#: operation -> states in which it is allowed (anything else: error "not allowed in state ...")
MASKS: dict[str, tuple[str, ...]] = {
    "SetDebugLogging": LIVE,
    "SetupExperiment": ("Instantiated",),
    "EnterInitializationMode": ("Instantiated",),
    "ExitInitializationMode": ("InitializationMode",),
    "Terminate": ("EventMode", "ContinuousTimeMode", "StepComplete", "StepFailed", "Error"),
    "Reset": LIVE,
    "GetValue": ("InitializationMode", *INITIALIZED, "Error"),
    "GetStart": ("InitializationMode", *INITIALIZED, "Error"),  # inputs and parameters: FMI 2.0 reads them alike
    "SetInput": ("Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "StepComplete"),
    "SetTunable": ("Instantiated", "InitializationMode", "EventMode", "StepComplete"),
    "SetFixed": ("Instantiated", "InitializationMode"),
    "FMUState": LIVE,
    "DoStep": ("StepComplete",),
    "CancelStep": ("StepInProgress",),
    "GetStatus": ("StepComplete", "StepFailed", "StepCanceled", "Terminated", "Error"),
    "SetInputDerivatives": ("Instantiated", "InitializationMode", "StepComplete"),
    "GetOutputDerivatives": ("StepComplete", "StepFailed", "StepCanceled", "Terminated", "Error"),
    "GetDirectionalDerivative": ("InitializationMode", *INITIALIZED, "Error"),
    "EnterEventMode": ("EventMode", "ContinuousTimeMode"),
    "NewDiscreteStates": ("EventMode",),
    "EnterContinuousTimeMode": ("EventMode",),
    "CompletedIntegratorStep": ("ContinuousTimeMode",),
    "SetTime": ("EventMode", "ContinuousTimeMode"),
    "SetContinuousStates": ("ContinuousTimeMode",),
    "GetContinuousStates": ("InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated", "Error"),
    "GetDerivatives": ("InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated", "Error"),
    "GetEventIndicators": ("InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated", "Error"),
    "GetNominals": ("Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated", "Error"),
    "GetNumber": LIVE,
    "GetNumberOfStates": LIVE,
    "EnterStepMode": ("EventMode",),
    "EnterConfigurationMode": ("Instantiated", "StepComplete", "EventMode"),
    "ExitConfigurationMode": ("ConfigurationMode",),
    "Clock": ("InitializationMode", "EventMode"),
}

#: where the FMI 3.0 state machine differs from the FMI 2.0 one (FMI 3.0 sections 2.3.1, 3.2.1): Get of inputs
#: and parameters (``GetStart``) also answers in Instantiated, with their start values, while every other variable
#: (``GetValue``) is read from initialization mode on, as in FMI 2.0; the value layers pick the row by the
#: variable's causality, as Set does; Event Mode offers neither fmi3EnterEventMode nor fmi3SetTime (Model Exchange
#: sets the time in Continuous-Time Mode; a Co-Simulation FMU without event mode never enters Event Mode)
FMI3_MASKS: dict[str, tuple[str, ...]] = {
    "GetStart": ("Instantiated", *MASKS["GetStart"]),
    "EnterEventMode": ("ContinuousTimeMode",),
    "SetTime": ("ContinuousTimeMode",),
}

#: the operations of one interface only (FMI 3.0 sections 3.2.1, 4.2.1: e.g. fmi3EnterStepMode is a Co-Simulation
#: function, fmi3GetContinuousStates a Model Exchange one, whatever the state): the FMI 3.0 layer refuses them
#: for an instance of the other interface (an error, not a state error); every other operation serves both
INTERFACE: dict[str, str] = {
    **dict.fromkeys(("DoStep", "CancelStep", "GetStatus", "SetInputDerivatives", "GetOutputDerivatives",
                     "EnterStepMode"), "CoSimulation"),
    **dict.fromkeys(("EnterContinuousTimeMode", "CompletedIntegratorStep", "SetTime", "SetContinuousStates",
                     "GetContinuousStates", "GetDerivatives", "GetEventIndicators", "GetNominals", "GetNumberOfStates"),
                    "ModelExchange"),
}

@dataclass(frozen=True)
class Rule:
    """One argument rule: a C function ``uavfmu_rule_<name>(msg, n, args...)`` returning 1 when every
    ``(condition, message format, format arguments)`` holds, else 0 with the first failing message."""

    name: str
    params: str
    checks: tuple[tuple[str, str, str], ...]


RULES: tuple[Rule, ...] = (
    Rule("setup", "int tolerance_defined, double tolerance, double start, int stop_defined, double stop", (
        ("isfinite(start)", "startTime %g is not finite", "start"),
        ("!tolerance_defined || (isfinite(tolerance) && tolerance > 0.0)",
         "tolerance %g must be finite and > 0", "tolerance"),
        ("!stop_defined || (isfinite(stop) && stop >= start)",
         "stopTime %g must be finite and >= startTime %g", "stop, start"),
    )),
    Rule("step", "double t, double h, double last", (
        ("isfinite(h) && h > 0.0", "communication step size %g must be finite and > 0", "h"),
        ("isfinite(t) && fabs(t - last) <= UAVFMU_TIME_TOLERANCE * (fabs(last) > 1.0 ? fabs(last) : 1.0)",
         "currentCommunicationPoint %.17g is not the last communication point %.17g", "t, last"),
    )),
    Rule("internal_steps", "double h, double internal_step", (
        ("isfinite(internal_step) && internal_step > 0.0",
         "the internal step %g s must be finite and > 0", "internal_step"),
        ("h / internal_step <= UAVFMU_MAX_INTERNAL_STEPS + 0.5",
         "a step of %g s needs %.3g internal steps of %g s, more than the %d allowed per communication step "
         "(make smaller communication steps or a larger step_internal_s)",
         "h, ceil(h / internal_step), internal_step, UAVFMU_MAX_INTERNAL_STEPS"),
    )),
    Rule("time", "double t", (("isfinite(t)", "time %g is not finite", "t"),)),
    Rule("name", "const char* name", (("name && name[0]", "instanceName must be a non-empty string", ""),)),
)


#: the log categories of every FMU (modelDescription ``LogCategories``; SetDebugLogging refuses others)
LOG_CATEGORIES = ("logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll")


INTERFACE_CODE = {"ModelExchange": 1, "CoSimulation": 0, None: -1}


def masks(version: int) -> dict[str, tuple[str, ...]]:
    """The state table of FMI ``version`` (2 or 3)."""
    return {**MASKS, **FMI3_MASKS} if version == 3 else MASKS


def allowed(op: str, version: int = 2) -> int:
    """The state mask of ``op`` in FMI ``version`` (for tests and the shim)."""
    return _mask(*masks(version)[op])


def header() -> str:
    """C text of ``uavfmu_states.h``: state bits, their names, the masks and the argument rules."""
    lines = [
        "/* Generated by uavfmu (fmu_models/fmi/statemachine.py): the one FMI state machine table. Do not edit. */",
        "#ifndef UAVFMU_STATES_H", "#define UAVFMU_STATES_H", "#include <math.h>", "#include <stdio.h>",
        "#include <string.h>", "",
        f"#define UAVFMU_MAX_INTERNAL_STEPS {MAX_INTERNAL_STEPS}",
        f"#define UAVFMU_TIME_TOLERANCE {TIME_TOLERANCE!r}", "",
        "typedef enum {",
        *(f"    {name} = {bit}," for name, bit in STATES.items()),
        "} UavfmuState;", "",
        *(f"#define MASK_{op} {allowed(op)} /* {' | '.join(states)} */" for op, states in MASKS.items()), "",
        "/* the FMI 3.0 layer's masks (FMI3_MASKS: where the FMI 3.0 state machine differs) */",
        *(f"#define MASK3_{op} {allowed(op, 3)}" for op in MASKS), "",
        "/* the interface an operation belongs to: 1 Model Exchange, 0 Co-Simulation, -1 both */",
        *(f"#define INTERFACE_{op} {INTERFACE_CODE[INTERFACE.get(op)]}" for op in MASKS), "",
        "static inline const char* uavfmu_state_name(int s) {",
        "    switch (s) {",
        *(f'    case {name}: return "{STATE_TEXT[name]}";' for name in STATES),
        "    }", '    return "unknown";', "}", "",
    ]
    for rule in RULES:
        lines.append(f"static inline int uavfmu_rule_{rule.name}(char* msg, size_t n, {rule.params}) {{")
        for cond, fmt, args in rule.checks:
            call = f'snprintf(msg, n, "{fmt}"{", " + args if args else ""})'
            lines.append(f"    if (!({cond})) {{ {call}; return 0; }}")
        lines += ["    (void)msg; (void)n;", "    return 1;", "}", ""]
    known = " && ".join(f'strcmp(k, "{c}")' for c in LOG_CATEGORIES)
    lines += [
        "/* SetDebugLogging: every category one of the modelDescription's LogCategories */",
        "static inline int uavfmu_rule_categories(char* msg, size_t n, size_t count, const char* const* cats) {",
        "    if (count > 0 && !cats) {",
        '        snprintf(msg, n, "categories is NULL with nCategories = %zu", count);',
        "        return 0;",
        "    }",
        "    for (size_t i = 0; i < count; ++i) {",
        "        const char* k = cats[i];",
        f'        if (!k || ({known})) {{',
        '            snprintf(msg, n, "unknown log category %s", k ? k : "(null)");',
        "            return 0;",
        "        }",
        "    }",
        "    return 1;",
        "}", "",
        "/* FMI 2.0 Get*Status: 1 if the function answering status kind `answered` (-1: none) answers `asked`.",
        "   Synchronous DoStep: the kinds about an asynchronous step (fmi2DoStepStatus 0, fmi2PendingStatus 1) are",
        "   never available; fmi2LastSuccessfulTime (2) and fmi2Terminated (3) are. */",
        "static inline int uavfmu_status_available(int answered, int asked) {",
        "    return answered >= 2 && asked == answered;",
        "}", "",
        "#endif", ""]
    return "\n".join(lines)

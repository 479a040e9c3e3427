"""Generated FMI 3.0 call sequences against the native FMI 3.0 FMU (Co-Simulation and Model Exchange instances): it
never crashes its host and follows the one state machine table both directions.

As test_fmi_sequences.py for FMI 2.0: Hypothesis builds sequences of calls (life-cycle calls in any order, both
interfaces' calls on instances of either, value references valid, unknown or of the wrong type, nValues that
does not match, NaN/inf/huge values, NULL arrays, outputs and instances, steps from the wrong time or with a bad
or huge size, FMU states of the other instance or model, damaged and truncated serialized states, the
configuration, clock, event and derivative functions this FMU does not provide, bad instantiations: eventModeUsed,
Scheduled Execution, wrong token...) and ``fmi_worker.py 3`` runs each with plain ctypes in a subprocess. The oracle
of ``fmi_oracle.py`` judges every answer by the FMI 3.0 state machine written out from the standard in
``fmi_standard.py`` (states and the interface of each call; the argument rules of ``statemachine.py``), FMI 3.0's
Step Mode being the table's StepComplete. At least 1000 sequences (printed).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from typing import Any, ClassVar

import pytest
from fmpy import extract
from hypothesis import strategies as st

from fmu_models.fmi import zigcc
from tests.fmu_models.fmi import fmi_oracle as fo
from tests.fmu_models.fmi.fmi_oracle import (
    ERROR,
    MODEL,
    MODEL_DEPENDENT,
    MODELS,
    OK,
    OUT,
    SETUP,
    SLOT,
    VALUES,
    Life,
    Oracle,
)
from tests.fmu_models.fmi.fmi_standard import interface, oracle_table

EXAMPLES = 1000
ME = 7  # the instantiation variant that makes a Model Exchange instance
OWN = "own"  # in a burst of calls: the model of the instance the burst is aimed at


@pytest.fixture(scope="module")
def fmi3(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """A worker over both vehicles as native FMI 3.0 Co-Simulation + Model Exchange FMUs (this platform only);
    the oracle's variable tables."""
    from build_fmus import BuildOptions, build

    out = tmp_path_factory.mktemp("native_fmi3")
    opts = BuildOptions(fmi_version=3, kinds=("cs", "me"), platforms=(zigcc.host_platform().fmi_name,))
    fmus = {p.stem: p for p in build(None, out, options=opts)}
    folders = [extract(str(fmus[m]), str(tmp_path_factory.mktemp(f"fmi3_{m}"))) for m in MODELS]
    worker = fo.Worker(3, folders)
    yield {"worker": worker, "vars": [fo.variables(fmus[m]) for m in MODELS]}
    worker.close()


# ----------------------------------------------------------------------------------------- strategies
NULL_FUNCTIONS = ("fmi3ExitInitializationMode", "fmi3EnterStepMode", "fmi3Terminate", "fmi3Reset",
                  "fmi3EnterConfigurationMode", "fmi3EnterEventMode", "fmi3EnterContinuousTimeMode",
                  "fmi3EvaluateDiscreteStates", "fmi3FreeInstance")
NO_ARGUMENTS = ("stepMode", "eventMode", "config", "exitConfig", "evaluate", "ctMode", "update", "partition",
                "dependencies")


@functools.cache  # built once: a strategy built anew for every sequence costs Hypothesis more than the FMU calls
def _call_ops(every_vr: tuple[int, ...], settable: tuple[int, ...]) -> st.SearchStrategy[list[list[Any]]]:
    """One call, or a burst of calls on one instance: values set into inputs and parameters (``settable``), then
    what makes the model check them (a step, the end of initialisation, outputs, derivatives)."""
    single = st.one_of(
        *fo.shared_ops(list(every_vr), ["Float64", "Float64", "Float64", "Boolean", "Int32", "String"],
                       (st.sampled_from([0, 0, 0, 1]),), 3),
        st.tuples(st.just("inst"), MODEL, SLOT, st.integers(0, ME)).map(list),
        st.tuples(st.just("enter"), MODEL, SLOT, *SETUP).map(list),
        st.tuples(st.sampled_from(NO_ARGUMENTS), MODEL, SLOT).map(list),
        st.tuples(st.just("clock"), MODEL, SLOT, st.integers(0, 9)).map(list),
        st.tuples(st.just("deriv"), MODEL, SLOT, st.integers(0, 2)).map(list),
        st.tuples(st.just("setTime"), MODEL, SLOT, VALUES).map(list),
        st.tuples(st.just("me"), MODEL, SLOT, st.integers(0, 7), st.integers(0, 3)).map(list),
        st.tuples(st.just("null"), MODEL, SLOT, st.sampled_from(NULL_FUNCTIONS)).map(list),
    ).map(lambda op: [op])
    then = st.sampled_from([["step", 0, 0, 0, 0.0, 0.01, 0], ["exit", 0, 0], ["getState", 0, 0], ["me", 0, 0, 1, 0],
                            ["get", 0, 0, "Float64", [OUT, OUT + 1], [], 0], ["me", 0, 0, 7, 0]])
    burst = st.tuples(st.lists(st.sampled_from(list(settable)), min_size=1, max_size=2), st.lists(VALUES, max_size=2),
                      st.lists(then, min_size=1, max_size=3))
    own_state = st.one_of(  # "own": an FMU state of the instance's own model
        st.tuples(st.sampled_from(["setState", "freeState"]), st.just(0), st.just(0), st.just(OWN),
                  st.integers(0, 5)),
        st.tuples(st.just("serial"), st.just(0), st.just(0), st.just(OWN), st.integers(0, 5), st.integers(0, 2),
                  st.integers(0, 400))).map(list)
    ending = st.sampled_from([["terminate", 0, 0], ["get", 0, 0, "Float64", [OUT], [], 0], ["reset", 0, 0],
                              ["getState", 0, 0]])
    return st.one_of(single, burst.map(lambda b: [["set", 0, 0, "Float64", b[0], b[1], 0], *b[2]]),
                     st.lists(st.one_of(then, own_state), max_size=3).map(lambda b: [["getState", 0, 0], *b]),
                     st.lists(ending, min_size=1, max_size=3))


@st.composite
def sequences(draw: st.DrawFn, every_vr: list[int], settable: list[int]) -> list[list[Any]]:
    """A valid start of one or two Co-Simulation or Model Exchange lives (so deep states are reached), then any
    calls, three in four aimed at an instance that start made (a burst always is)."""
    seq: list[list[Any]] = []
    lives = []
    for slot in range(draw(st.integers(1, 2))):
        model, me = draw(MODEL), draw(st.sampled_from([False, False, True]))
        life = [["inst", model, slot, ME if me else 0], ["enter", model, slot, 0, 0.0, 0.0, 0, 0.0],
                ["exit", model, slot]]
        if me:
            life += [["ctMode", model, slot], ["me", model, slot, 1, 0], ["me", model, slot, 7, 0]]
        else:
            life += [["step", model, slot, 0, 0.0, 0.01, 0]] * draw(st.integers(0, 3))
        seq += life[: draw(st.integers(1, len(life)))]
        lives.append([model, slot])
    for calls in draw(st.lists(_call_ops(tuple(every_vr), tuple(settable)), min_size=1, max_size=12)):
        target = draw(st.sampled_from(lives))
        aim = len(calls) > 1 or (calls[0][0] != "null" and draw(st.integers(0, 3)) > 0)
        seq += [[op[0], *target, *(target[0] if a == OWN else a for a in op[3:])] if aim else op for op in calls]
    return seq


#: instantiate (Co-Simulation), initialise and make one step (slot 0 of the quadrotor), for explicit examples
LIFE = [["inst", 0, 0, 0], ["enter", 0, 0, 0, 0.0, 0.0, 0, 0.0], ["exit", 0, 0], ["step", 0, 0, 0, 0.0, 0.01, 0]]
#: the same as a Model Exchange instance, into Continuous-Time Mode
ME_LIFE = [["inst", 0, 0, ME], *LIFE[1:3], ["ctMode", 0, 0]]


# ----------------------------------------------------------------------------------------- the oracle
#: "me" op function -> its MASKS row
ME_MASK = ("GetContinuousStates", "GetDerivatives", "GetNominals", "SetContinuousStates", "GetEventIndicators",
           "GetNumberOfStates", "GetNumberOfStates", "CompletedIntegratorStep")


class Oracle3(Oracle):
    """The FMI 3.0 state machine (Co-Simulation without event mode: initialisation exits into Step Mode, the
    table's StepComplete; Model Exchange into Event Mode) and the interface of each call."""

    MASKS: ClassVar[dict[str, tuple[str, ...]]] = oracle_table(3)
    OP_MASK: ClassVar[dict[str, str]] = {
        "enter": "EnterInitializationMode", "exit": "ExitInitializationMode", "terminate": "Terminate",
        "reset": "Reset", "getState": "FMUState", "setState": "FMUState", "freeState": "FMUState",
        "serial": "FMUState", "step": "DoStep", "get": "GetStart", "set": "SetInput", "debug": "SetDebugLogging",
        "stepMode": "EnterStepMode", "eventMode": "EnterEventMode", "config": "EnterConfigurationMode",
        "exitConfig": "ExitConfigurationMode", "partition": "Clock", "dependencies": "GetNumber",
        "update": "NewDiscreteStates", "evaluate": "NewDiscreteStates", "ctMode": "EnterContinuousTimeMode",
        "setTime": "SetTime"}
    DERIV_MASK = ("GetDirectionalDerivative", "GetDirectionalDerivative", "GetOutputDerivatives")
    VALID_INST = (0, 5, ME)
    MOVES: ClassVar[dict[str, str]] = {**Oracle.MOVES, "enter": "InitializationMode", "stepMode": "StepComplete",
                                       "eventMode": "EventMode", "ctMode": "ContinuousTimeMode"}
    #: not provided by this FMU: an error wherever the state allows the call
    UNSUPPORTED = ("config", "exitConfig", "partition", "dependencies", "deriv")

    def new_life(self, variant: int) -> Life:
        return Life(model_exchange=variant == ME)

    def mask(self, name: str, args: list[Any], life: Life) -> str:
        if name == "clock":  # 0..7 the interval/shift functions, 8 GetClock, 9 SetClock
            return ("GetStart", "SetInput")[args[0] - 8] if args[0] >= 8 else "Clock"
        if name == "me":
            return ME_MASK[args[0]]
        return super().mask(name, args, life)

    def expect(self, name: str, model: int, slot: int, args: list[Any], life: Life) -> tuple[Any, ...]:
        only = interface(self.mask(name, args, life))
        if only and (only == "ModelExchange") != life.model_exchange:
            return (ERROR,)  # a function of the other interface
        if name in self.UNSUPPORTED or (name == "clock" and args[0] < 8):
            return (ERROR,)
        if name == "enter":
            return (ERROR,) if fo.bad_setup(*args) else (OK,)
        if name == "setTime":
            return (OK,) if math.isfinite(args[0]) else (ERROR,)
        if name in ("clock", "stepMode", "eventMode", "ctMode", "update", "evaluate"):
            return (OK,)
        if name == "me":
            return self.expect_me(args[0], args[1], life)
        if name == "step" and args[3]:
            return (ERROR,)  # NULL output arguments
        if name in ("get", "set") and args[3] == 3:
            return (ERROR,)  # nValues does not match the value references
        return super().expect(name, model, slot, args, life)

    @staticmethod
    def expect_me(fn: int, variant: int, life: Life) -> tuple[Any, ...]:
        """Model Exchange array calls (see ``Fmi3.model_exchange`` in the worker)."""
        bad = {0: (1, 2), 1: (1, 2), 2: (1, 2), 3: (1, 2, 3), 4: (1,), 5: (2,), 6: (2,), 7: (2,)}[fn]
        if variant in bad:
            return (ERROR,)
        computed = fn == 1 or fn == 7 or (fn == 0 and life.state == "InitializationMode")
        return MODEL_DEPENDENT if computed and life.suspect else (OK,)

    def advance(self, name: str, model: int, slot: int, args: list[Any], life: Life, status: Any) -> None:
        super().advance(name, model, slot, args, life, status)
        if status != OK:
            return
        if name == "enter":
            life.time = args[2]
        elif name == "exit":
            life.state = "EventMode" if life.model_exchange else "StepComplete"
        elif name == "me" and args[0] == 3:
            life.suspect = True  # states set: the model may refuse them


EXPLICIT = [
    [*LIFE[:1], ["enter", 0, 0, 1, math.nan, 0.0, 0, 0.0], ["enter", 0, 0, 0, 0.0, 0.0, 1, math.inf],
     ["enter", 0, 0, 1, 1e-6, 0.0, 1, 10.0], ["exit", 0, 0], ["step", 0, 0, 0, 0.0, 0.01, 1]],
    [["inst", 0, 0, 5], *LIFE[1:], ["inst", 1, 1, 2], ["inst", 1, 1, 6], ["inst", 1, 1, 3], ["inst", 1, 1, 4]],
    [*LIFE, ["set", 0, 0, "Float64", [0], [math.nan], 0], ["step", 0, 0, 0, 0.0, 0.01, 0],
     ["get", 0, 0, "Float64", [OUT], [], 0], ["terminate", 0, 0], ["reset", 0, 0]],  # a rejected step
    [*LIFE, ["config", 0, 0], ["exitConfig", 0, 0], ["eventMode", 0, 0], ["clock", 0, 0, 0], ["clock", 0, 0, 8],
     ["partition", 0, 0], ["deriv", 0, 0, 0], ["deriv", 0, 0, 2], ["update", 0, 0]],
    [*ME_LIFE, ["me", 0, 0, 3, 0], ["me", 0, 0, 7, 0], ["eventMode", 0, 0], ["update", 0, 0], ["ctMode", 0, 0],
     ["setTime", 0, 0, 0.5], ["me", 0, 0, 1, 0], ["terminate", 0, 0], ["me", 0, 0, 0, 0]],
    # found by the generated sequences (fixed in fmi3Functions.c): a Co-Simulation instance handed out continuous
    # states, an ME instance entered Step Mode and stepped, nValues was not checked for the types without variables
    [*LIFE[:2], ["me", 0, 0, 0, 0]],
    [*ME_LIFE[:3], ["stepMode", 0, 0], ["step", 0, 0, 0, 0.0, 0.01, 0]],
    [*LIFE, ["set", 0, 0, "Boolean", [], [], 3], ["get", 0, 0, "Int32", [], [], 3]],
    # read in the FMI 3.0 standard: Get answers start values in Instantiated (inputs, parameters; not outputs);
    # Event Mode has no fmi3EnterEventMode or fmi3SetTime
    [LIFE[0], ["get", 0, 0, "Float64", [0, OUT - 1], [], 0], ["get", 0, 0, "Float64", [OUT], [], 0],
     ["get", 0, 0, "Boolean", [], [], 0]],
    [*ME_LIFE[:3], ["setTime", 0, 0, 0.5], ["eventMode", 0, 0], ["ctMode", 0, 0], ["setTime", 0, 0, 0.5],
     ["eventMode", 0, 0]],
    # the clock interval and shift functions are allowed in Initialization Mode, the derivative functions in
    # Terminated (here the Error state after a rejected step): refused as not provided, not as a state error
    [*LIFE[:2], ["clock", 0, 0, 0], ["clock", 0, 0, 2], ["clock", 0, 0, 5]],
    [*LIFE, ["set", 0, 0, "Float64", [0], [math.nan], 0], ["step", 0, 0, 0, 0.0, 0.01, 0], ["deriv", 0, 0, 0],
     ["deriv", 0, 0, 2]],
]


def test_fmi3_call_sequences_follow_the_state_machine_table(fmi3: dict) -> None:
    worker, tables = fmi3["worker"], fmi3["vars"]
    every_vr = sorted({r for table in tables for r in table})
    settable = sorted({r for table in tables for r, v in table.items() if v.causality in ("input", "parameter")})

    count = fo.run_generated(sequences(every_vr, settable), EXPLICIT, EXAMPLES,
                             lambda seq: fo.check(seq, {"native FMI 3.0": worker.run(seq)}, tables, Oracle3))
    print(f"\nFMI 3.0 call sequences: {count} generated on the native FMU: all as the table says")
    assert count >= EXAMPLES

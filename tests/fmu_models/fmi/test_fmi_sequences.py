"""Generated FMI 2.0 call sequences, the same ones against every backend: the FMU never crashes
its host, follows the FMI 2.0 state machine both directions, and every backend answers alike.

Hypothesis builds sequences of calls (life-cycle calls in any order, value references valid, unknown or of
the wrong type, NaN/inf/huge values, NULL arrays and components, steps from the wrong time or with a bad or
huge size, FMU states of the other instance or the other model, damaged and truncated serialized states, status
queries, the unsupported derivative functions, debug-logging categories, bad instantiations) and
``fmi_worker.py`` runs each sequence with plain ctypes in one subprocess per backend (the native FMI 2.0
Co-Simulation FMU and the pythonfmu FMU behind its guard), so a crash fails the test with the sequence that
caused it. Every answer is judged by the oracle of ``fmi_oracle.py`` (built on the FMI 2.0 tables written out from
the standard in ``fmi_standard.py``, not on ``fmu_models/fmi/statemachine.py``, in both directions). The two
backends must return identical statuses for every call. At least 1000 sequences run (printed).
test_fmi3_sequences.py does the same for FMI 3.0.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import pytest
from fmpy import extract
from hypothesis import strategies as st

from fmu_models.fmi import zigcc
from tests.fmu_models.fmi.fmi_oracle import (
    DISCARD,
    ERROR,
    MODEL,
    MODELS,
    OK,
    OUT,
    SETUP,
    SLOT,
    Life,
    Oracle,
    Worker,
    bad_setup,
    check,
    run_generated,
    shared_ops,
    variables,
)

EXAMPLES = 1000
BACKENDS = ("native", "python")


@pytest.fixture(scope="module")
def backends(python_fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """A worker per backend: the native FMI 2.0 Co-Simulation FMUs (the same variables as the pythonfmu ones)
    and the pythonfmu FMUs; the oracle's variable tables (identical in both, checked)."""
    from build_fmus import BuildOptions, build

    out = tmp_path_factory.mktemp("native_cs")
    opts = BuildOptions(kinds=("cs",), platforms=(zigcc.host_platform().fmi_name,))
    native = {p.stem: p for p in build(None, out, options=opts)}
    workers, tables = {}, {}
    for name, fmus in (("native", native), ("python", python_fmus)):
        folders = [extract(str(fmus[m]), str(tmp_path_factory.mktemp(f"{name}_{m}"))) for m in MODELS]
        workers[name] = Worker(2, folders)
        tables[name] = [variables(fmus[m]) for m in MODELS]
    assert tables["native"] == tables["python"]
    yield {"workers": workers, "vars": tables["native"]}
    for w in workers.values():
        w.close()


# ----------------------------------------------------------------------------------------- strategies
@functools.cache  # built once: a strategy built anew for every sequence costs Hypothesis more than the FMU calls
def _call_ops(every_vr: tuple[int, ...]) -> st.SearchStrategy[list[Any]]:
    null_comp = st.sampled_from(["fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                                 "fmi2Reset", "fmi2CancelStep", "fmi2FreeInstance"])
    return st.one_of(
        *shared_ops(list(every_vr), ["Real", "Real", "Real", "Boolean", "Integer", "String"], (), 2),
        st.tuples(st.just("inst"), MODEL, SLOT, st.integers(0, 5)).map(list),
        st.tuples(st.sampled_from(["enter", "cancel"]), MODEL, SLOT).map(list),
        st.tuples(st.just("setup"), MODEL, SLOT, *SETUP).map(list),
        st.tuples(st.just("status"), MODEL, SLOT, st.integers(0, 4), st.integers(-1, 5), st.integers(0, 1)).map(list),
        st.tuples(st.just("deriv"), MODEL, SLOT, st.integers(0, 2)).map(list),
        st.tuples(st.just("null"), MODEL, SLOT, null_comp).map(list),
    )


@st.composite
def sequences(draw: st.DrawFn, every_vr: list[int]) -> list[list[Any]]:
    """A valid start of a life (so deep states are reached) then any calls."""
    seq: list[list[Any]] = []
    for slot in range(draw(st.integers(0, 2))):
        model = draw(MODEL)
        life = [["inst", model, slot, 0], ["setup", model, slot, 0, 0.0, 0.0, 0, 0.0], ["enter", model, slot],
                ["exit", model, slot]]
        life += [["step", model, slot, 0, 0.0, 0.01]] * draw(st.integers(0, 3))
        seq += life[: draw(st.integers(1, len(life)))]
    return seq + draw(st.lists(_call_ops(tuple(every_vr)), min_size=1, max_size=20))


#: instantiate, set up, initialise and make one step (slot 0 of the quadrotor), for explicit examples
LIFE = [["inst", 0, 0, 0], ["setup", 0, 0, 0, 0.0, 0.0, 0, 0.0], ["enter", 0, 0], ["exit", 0, 0],
        ["step", 0, 0, 0, 0.0, 0.01]]


# ----------------------------------------------------------------------------------------- the oracle
class Oracle2(Oracle):
    """The FMI 2.0 Co-Simulation state machine: SetupExperiment, Cancel, the Get*Status functions."""

    OP_MASK: ClassVar[dict[str, str]] = {
        "setup": "SetupExperiment", "enter": "EnterInitializationMode", "exit": "ExitInitializationMode",
        "terminate": "Terminate", "reset": "Reset", "cancel": "CancelStep", "getState": "FMUState",
        "setState": "FMUState", "freeState": "FMUState", "serial": "FMUState", "step": "DoStep", "get": "GetValue",
        "set": "SetInput", "status": "GetStatus", "debug": "SetDebugLogging"}
    DERIV_MASK = ("GetDirectionalDerivative", "SetInputDerivatives", "GetOutputDerivatives")
    MOVES: ClassVar[dict[str, str]] = {**Oracle.MOVES, "enter": "InitializationMode", "exit": "StepComplete"}
    #: status function (worker index) -> the one status kind it answers (fmi2LastSuccessfulTime, fmi2Terminated)
    STATUS_KIND: ClassVar[dict[int, int]] = {1: 2, 2: 3}

    def expect(self, name: str, model: int, slot: int, args: list[Any], life: Life) -> tuple[Any, ...]:
        if name in ("cancel", "deriv"):
            return (ERROR,)  # never in StepInProgress / not supported: both refused
        if name == "setup":
            return (ERROR,) if bad_setup(*args) else (OK,)
        if name == "enter":
            return (OK,)
        if name == "status":
            fn, kind, null = args
            if null:
                return (ERROR,)
            return (OK,) if self.STATUS_KIND.get(fn) == kind else (DISCARD,)
        return super().expect(name, model, slot, args, life)

    def advance(self, name: str, model: int, slot: int, args: list[Any], life: Life, status: Any) -> None:
        super().advance(name, model, slot, args, life, status)
        if name == "setup" and status == OK:
            life.time = args[2]


EXPLICIT = [
    [*LIFE[:2], ["setup", 0, 0, 1, math.nan, 0.0, 0, 0.0], ["setup", 0, 0, 0, 0.0, 0.0, 1, math.inf],
     ["setup", 0, 0, 1, 1e-6, 0.0, 1, 10.0]],  # NaN tolerance and stopTime = inf refused; a good one accepted
    [["inst", 0, 0, 5], *LIFE[1:], ["inst", 1, 1, 5], ["step", 0, 0, 0, 0.0, 0.01]],  # NULL resource location
    [*LIFE, *[["status", 0, 0, fn, kind, 0] for fn in range(5) for kind in (-1, 0, 1, 2, 3)]],  # Get*Status
    [["inst", 0, 0, 0], ["cancel", 0, 0], ["deriv", 0, 0, 0], ["deriv", 0, 0, 1], ["deriv", 0, 0, 2],
     *LIFE[1:], ["cancel", 0, 0], ["deriv", 0, 0, 0], ["deriv", 0, 0, 1], ["deriv", 0, 0, 2]],
    [*LIFE, ["set", 0, 0, "Real", [0], [math.nan], 0], ["step", 0, 0, 0, 0.0, 0.01],
     ["get", 0, 0, "Real", [OUT], [], 0], ["status", 0, 0, 1, 2, 0], ["reset", 0, 0]],  # a rejected step
    [*LIFE, ["set", 0, 0, "Real", [0], [1600.0], 0], ["get", 0, 0, "Real", [OUT, OUT + 1], [], 0],
     ["step", 0, 0, 0, 0.0, 1e9], ["step", 0, 0, 0, 0.0, 1e5], ["step", 0, 0, 0, 0.0, 0.01]],
    [*LIFE, ["terminate", 0, 0], ["terminate", 0, 0], ["reset", 0, 0], ["debug", 0, 0, 1, 2, 0]],
    # after a rejected step (Error state) the derivative functions are allowed by the standard (values for
    # debugging): refused as not provided, not as a state error
    [*LIFE, ["set", 0, 0, "Real", [0], [math.nan], 0], ["step", 0, 0, 0, 0.0, 0.01], ["deriv", 0, 0, 0],
     ["deriv", 0, 0, 2]],
]


def test_the_same_call_sequences_give_the_same_answers_on_every_backend(backends: dict) -> None:
    workers, tables = backends["workers"], backends["vars"]
    every_vr = sorted({r for table in tables for r in table})

    count = run_generated(sequences(every_vr), EXPLICIT, EXAMPLES, lambda seq: check(
        seq, {name: workers[name].run(seq) for name in BACKENDS}, tables, Oracle2))
    print(f"\nFMI call sequences: {count} generated, each on {', '.join(BACKENDS)}: same answers")
    assert count >= EXAMPLES

"""Generated FMI 2.0 call sequences against both backends (issue 16): the FMU never crashes its host.

Hypothesis builds sequences of calls (life-cycle calls in any order, value references valid, unknown or of
the wrong type, NaN/inf/huge values, NULL arrays and components, steps from the wrong time or with a bad size,
FMU states of the other instance or the other model, damaged and truncated serialized states, status queries,
bad instantiations) and ``fmi_worker.py`` runs them with plain ctypes in a subprocess, one per backend, so a
crash fails the test with the sequence that caused it. Each answer is checked against the FMI 2.0
Co-Simulation state machine: a call the standard forbids in the current state, a step that does not start at
the last communication point or has a non-positive or non-finite size, and a NULL component return
fmi2Error; every fmi2Error is logged; bad instantiations return NULL with a message; afterwards every instance
frees cleanly and a fresh one initialises and steps. At least 1000 sequences run per backend (printed).
"""

from __future__ import annotations

import json
import math
import os
import selectors
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fmpy import extract, read_model_description
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

WORKER = Path(__file__).with_name("fmi_worker.py")
EXAMPLES = 1000
TIMEOUT_S = 30.0
MODELS = ("quadrotor", "fixed_wing")
COUNTS: dict[str, int] = {}
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
NULL_INSTANCE, SKIPPED = -1, -2


class Worker:
    """The worker subprocess of one backend, restarted after it dies."""

    def __init__(self, folders: list[str]) -> None:
        self.folders = folders
        self.proc: subprocess.Popen[str] | None = None

    def _start(self) -> subprocess.Popen[str]:
        env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
        return subprocess.Popen([sys.executable, str(WORKER), *self.folders], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)

    def run(self, seq: list[list[Any]]) -> list[Any]:
        if self.proc is None or self.proc.poll() is not None:
            self.proc = self._start()
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(seq) + "\n")
        self.proc.stdin.flush()
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        ready = sel.select(TIMEOUT_S)
        sel.close()
        line = self.proc.stdout.readline() if ready else ""
        if not line:
            self.close()
            why = "hung" if not ready else f"died with exit code {self.proc.returncode}"
            err = self.proc.stderr.read()[-3000:] if self.proc.stderr and ready else ""
            pytest.fail(f"FMU worker {why} on sequence {seq}\n{err}")
        return json.loads(line)

    def close(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
        if self.proc is not None:
            self.proc.wait(timeout=10)


def _vrs(fmu: Path) -> dict[str, list[int]]:
    md = read_model_description(str(fmu))
    out: dict[str, list[int]] = {"Real": [], "Boolean": [], "Integer": [], "String": []}
    for v in md.modelVariables:
        out.setdefault(v.type, []).append(v.valueReference)
    return out


@pytest.fixture(scope="module", params=["native", "python"])
def backend(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple]:
    fmus = request.getfixturevalue("built_fmus" if request.param == "native" else "python_fmus")
    folders = [extract(str(fmus[m]), str(tmp_path_factory.mktemp(f"{request.param}_{m}"))) for m in MODELS]
    worker = Worker(folders)
    yield request.param, worker, [_vrs(fmus[m]) for m in MODELS]
    worker.close()


# ----------------------------------------------------------------------------------------- strategies
SLOT, MODEL = st.integers(0, 1), st.integers(0, 1)
BAD_TIMES = (-5.0, 1e6, math.nan, math.inf)
STEP_SIZES = (0.001, 0.01, 0.1, 1.0, 0.0, -0.01, math.nan, math.inf, 1e9)
VALUES = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([math.nan, math.inf, -math.inf, 1e300, 0.0, 1500.0]))


def _call_ops(vrs: list[dict[str, list[int]]]) -> st.SearchStrategy[list[Any]]:
    kinds = st.sampled_from(["Real", "Real", "Real", "Boolean", "Integer", "String"])
    every_vr = sorted({r for model in vrs for refs in model.values() for r in refs})
    refs = st.lists(st.one_of(st.sampled_from(every_vr), st.integers(0, 2**32 - 1)), max_size=6)
    null_comp = st.sampled_from(["fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                                 "fmi2Reset", "fmi2CancelStep", "fmi2FreeInstance"])
    return st.one_of(
        st.tuples(st.just("inst"), MODEL, SLOT, st.integers(0, 4)).map(list),
        st.tuples(st.sampled_from(["enter", "exit", "terminate", "reset", "cancel", "free", "getState"]),
                  MODEL, SLOT).map(list),
        st.tuples(st.just("setup"), MODEL, SLOT, st.integers(0, 1), VALUES, st.sampled_from([0.0, 2.5, -1.0]),
                  st.integers(0, 1), VALUES).map(list),
        st.tuples(st.just("step"), MODEL, SLOT, st.just(0), st.just(0.0), st.sampled_from(STEP_SIZES)).map(list),
        st.tuples(st.just("step"), MODEL, SLOT, st.just(1), st.sampled_from(BAD_TIMES), st.just(0.01)).map(list),
        st.tuples(st.sampled_from(["get", "set"]), MODEL, SLOT, kinds, refs, st.lists(VALUES, max_size=6),
                  st.integers(0, 2)).map(list),
        st.tuples(st.sampled_from(["setState", "freeState"]), MODEL, SLOT, MODEL, st.integers(0, 5)).map(list),
        st.tuples(st.just("serial"), MODEL, SLOT, MODEL, st.integers(0, 5), st.integers(0, 2),
                  st.integers(0, 400)).map(list),
        st.tuples(st.just("status"), MODEL, SLOT, st.integers(0, 4), st.integers(-1, 5), st.integers(0, 1)).map(list),
        st.tuples(st.just("debug"), MODEL, SLOT, st.integers(0, 1), st.integers(0, 2), st.integers(0, 1)).map(list),
        st.tuples(st.just("null"), MODEL, SLOT, null_comp).map(list),
    )


@st.composite
def sequences(draw: st.DrawFn, vrs: list[dict[str, list[int]]]) -> list[list[Any]]:
    """A valid start of a life (so deep states are reached) then any calls."""
    seq: list[list[Any]] = []
    for slot in range(draw(st.integers(0, 2))):
        model = draw(MODEL)
        life = [["inst", model, slot, 0], ["setup", model, slot, 0, 0.0, 0.0, 0, 0.0], ["enter", model, slot],
                ["exit", model, slot]]
        life += [["step", model, slot, 0, 0.0, 0.01]] * draw(st.integers(0, 3))
        seq += life[: draw(st.integers(1, len(life)))]
    return seq + draw(st.lists(_call_ops(vrs), min_size=1, max_size=20))


#: instantiate, set up, initialise and make one step (slot 0 of the quadrotor), for explicit examples
LIFE = [["inst", 0, 0, 0], ["setup", 0, 0, 0, 0.0, 0.0, 0, 0.0], ["enter", 0, 0], ["exit", 0, 0],
        ["step", 0, 0, 0, 0.0, 0.01]]


# ----------------------------------------------------------------------------------------- the oracle
FORBIDDEN = {  # FMI 2.0 CS state machine (spec 2.0.4, 4.2.4): states in which a call must return fmi2Error
    "setup": {"init", "step", "terminated"},
    "enter": {"init", "step", "terminated"},
    "exit": {"instantiated", "step", "terminated"},
    "step": {"instantiated", "init", "terminated"},
    "terminate": {"instantiated", "init", "terminated"},
    "get": {"instantiated"},
    "set": {"terminated"},
}
AFTER_OK = {"enter": "init", "exit": "step", "terminate": "terminated", "reset": "instantiated",
            "step": "step", "setup": "instantiated"}


def check(seq: list[list[Any]], answer: list[Any]) -> None:
    *results, healthy = answer
    assert healthy, "after freeing everything, a fresh instance no longer initialises and steps"
    state: dict[tuple[int, int], str | None] = {}
    for op, (status, logged) in zip(seq, results, strict=True):
        name, model, slot, *args = op
        key = (model, slot)
        where = f"{op} returned {status} (logged {logged})"
        assert status is None or status in (NULL_INSTANCE, SKIPPED) or OK <= status <= FATAL, where
        if status in (ERROR, FATAL) and name != "null":
            assert logged >= 1, f"{where}: an fmi2Error without a logged message"
        if name == "null":
            assert status in (None, ERROR), where
            continue
        if name == "inst":
            assert (status == OK) == (args[0] == 0), where  # empty/NULL name, ME type, wrong GUID: NULL
            assert status == OK or logged >= 1, f"{where}: refused instantiation not logged"
            state[key] = "instantiated" if status == OK else None
            if status != OK:
                state.pop(key, None)
            continue
        if status == SKIPPED:
            continue
        if name == "free":
            state.pop(key, None)
            continue
        current = state.get(key)
        if current is not None and current in FORBIDDEN.get(name, ()):
            assert status == ERROR, f"{where}: not allowed in state {current}"
        if name == "step" and current == "step" and (args[0] == 1 or not args[2] > 0 or not math.isfinite(args[2])):
            assert status == ERROR, f"{where}: wrong communication point or step size"
        if name == "status" and args[0] == 3:  # FMI 2.0 CS defines no Integer status: never answered fmi2OK
            assert status != OK, f"{where}: fmi2GetIntegerStatus answered"
        if name == "setup" and current == "instantiated" and args[0] == 1 and not math.isfinite(args[1]):
            assert status == ERROR, f"{where}: non-finite tolerance"
        if status in (OK, WARNING) and name in AFTER_OK and current is not None:
            state[key] = AFTER_OK[name]
        elif status not in (OK, WARNING) or name == "setState":
            state[key] = None  # an error or a restored state: the oracle stops judging this slot
        if name == "reset" and status == OK:
            state[key] = "instantiated"


def test_generated_call_sequences_never_crash_and_follow_the_state_machine(backend: tuple) -> None:
    name, worker, vrs = backend

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(sequences(vrs))
    @example([*LIFE, ["status", 0, 0, 3, -1, 0], ["status", 0, 0, 3, 2, 0], ["status", 0, 0, 1, 2, 0]])
    def run(seq: list[list[Any]]) -> None:
        COUNTS[name] = COUNTS.get(name, 0) + 1
        check(seq, worker.run(seq))

    run()
    print(f"\nFMI call sequences ({name} backend): {COUNTS[name]} generated, none crashed")
    assert COUNTS[name] >= EXAMPLES

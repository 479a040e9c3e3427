"""Generated FMI 2.0 call sequences, the same ones against every backend (issues 16, 25): the FMU never crashes
its host, follows the one state machine table both directions, and every backend answers alike.

Hypothesis builds sequences of calls (life-cycle calls in any order, value references valid, unknown or of
the wrong type, NaN/inf/huge values, NULL arrays and components, steps from the wrong time or with a bad or
huge size, FMU states of the other instance or the other model, damaged and truncated serialized states, status
queries, the unsupported derivative functions, debug-logging categories, bad instantiations) and
``fmi_worker.py`` runs each sequence with plain ctypes in one subprocess per backend (the native FMI 2.0
Co-Simulation FMU and the pythonfmu FMU behind its guard), so a crash fails the test with the sequence that
caused it. Every answer is judged by an oracle built on ``fmu_models/fmi/statemachine.py`` (the table the C
layers are generated from), in both directions: a call the table forbids, or with arguments its rules refuse,
must return fmi2Error (with a logged state error when it is the state); an allowed call with valid arguments
must succeed (fmi2OK), except where the outcome depends on values the sequence set (then either, and an
error moves the oracle to the Error state); the oracle keeps judging after errors. The two backends must
return identical statuses for every call. At least 1000 sequences run (printed).
"""

from __future__ import annotations

import json
import math
import os
import selectors
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pytest
from fmpy import extract, read_model_description
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from build_fmus import make_model
from fmu_models.fmi import zigcc
from fmu_models.fmi.statemachine import MASKS, MAX_INTERNAL_STEPS

WORKER = Path(__file__).with_name("fmi_worker.py")
EXAMPLES = 1000
TIMEOUT_S = 30.0
MODELS = ("quadrotor", "fixed_wing")
COUNTS: dict[str, int] = {}
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
NULL_INSTANCE, SKIPPED = -1, -2
BACKENDS = ("native", "python")


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


@dataclass(frozen=True)
class Var:
    """What the oracle knows of a variable: type and how it may be set."""

    type: str
    causality: str
    variability: str
    name: str


def _vars(fmu: Path) -> dict[int, Var]:
    return {v.valueReference: Var(v.type, v.causality, v.variability, v.name)
            for v in read_model_description(str(fmu)).modelVariables}


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
        workers[name] = Worker(folders)
        tables[name] = [_vars(fmus[m]) for m in MODELS]
    assert tables["native"] == tables["python"]
    yield {"workers": workers, "vars": tables["native"]}
    for w in workers.values():
        w.close()


# ----------------------------------------------------------------------------------------- strategies
SLOT, MODEL = st.integers(0, 1), st.integers(0, 1)
BAD_TIMES = (-5.0, 1e6, math.nan, math.inf)
STEP_SIZES = (0.001, 0.01, 0.1, 1.0, 0.0, -0.01, math.nan, math.inf, 1e5, 1e9)
VALUES = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([math.nan, math.inf, -math.inf, 1e300, 0.0, 1500.0]))


def _call_ops(every_vr: list[int]) -> st.SearchStrategy[list[Any]]:
    kinds = st.sampled_from(["Real", "Real", "Real", "Boolean", "Integer", "String"])
    refs = st.lists(st.one_of(st.sampled_from(every_vr), st.integers(0, 2**32 - 1)), max_size=6)
    null_comp = st.sampled_from(["fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
                                 "fmi2Reset", "fmi2CancelStep", "fmi2FreeInstance"])
    return st.one_of(
        st.tuples(st.just("inst"), MODEL, SLOT, st.integers(0, 5)).map(list),
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
    return seq + draw(st.lists(_call_ops(every_vr), min_size=1, max_size=20))


#: instantiate, set up, initialise and make one step (slot 0 of the quadrotor), for explicit examples
LIFE = [["inst", 0, 0, 0], ["setup", 0, 0, 0, 0.0, 0.0, 0, 0.0], ["enter", 0, 0], ["exit", 0, 0],
        ["step", 0, 0, 0, 0.0, 0.01]]


# ----------------------------------------------------------------------------------------- the oracle
#: worker operation -> the state-machine operation of fmu_models/fmi/statemachine.py (MASKS)
OP_MASK = {"setup": "SetupExperiment", "enter": "EnterInitializationMode", "exit": "ExitInitializationMode",
           "terminate": "Terminate", "reset": "Reset", "cancel": "CancelStep", "getState": "FMUState",
           "setState": "FMUState", "freeState": "FMUState", "serial": "FMUState", "step": "DoStep",
           "get": "GetValue", "set": "SetInput", "status": "GetStatus", "debug": "SetDebugLogging"}
DERIV_MASK = ("GetDirectionalDerivative", "SetInputDerivatives", "GetOutputDerivatives")
#: status function (worker index) -> the one status kind it answers (fmi2LastSuccessfulTime, fmi2Terminated)
STATUS_KIND = {1: 2, 2: 3}
INTERNAL_STEP_S = 0.001  # the models' default step_internal_s (a parameter the sequences may change: then "either")
MODEL_DEPENDENT = (OK, ERROR)
#: the first output's value reference of the quadrotor (inputs, then parameters, then outputs)
_QUAD = make_model("quadrotor", None, "defaults")
OUT = len(_QUAD.inputs) + len(_QUAD.params)


@dataclass
class Life:
    """What the oracle knows of one instance: its state, last communication point, whether values were set
    that the model may refuse (then model-dependent outcomes are "OK or error")."""

    state: str = "Instantiated"
    time: float = 0.0
    suspect: bool = False
    internal_step_s: float = INTERNAL_STEP_S


@dataclass
class Oracle:
    """Expected answers of the FMI 2.0 Co-Simulation state machine for one sequence (see the module docstring)."""

    vars: list[dict[int, Var]]
    lives: dict[tuple[int, int], Life] = field(default_factory=dict)
    saved: dict[int, list[tuple[int, Life]]] = field(default_factory=lambda: {0: [], 1: []})

    def drop(self, model: int, slot: int) -> None:
        self.lives.pop((model, slot), None)
        self.saved[model] = [e for e in self.saved[model] if e[0] != slot]

    def judge(self, op: list[Any], status: Any, state_error: bool) -> None:
        """Assert ``status`` is an allowed answer to ``op`` and advance the oracle."""
        name, model, slot, *args = op
        where = f"{op} returned {status}"
        if name == "null":
            assert status in (None, ERROR), where
            return
        if name == "inst":
            self.drop(model, slot)
            assert (status == OK) == (args[0] in (0, 5)), where  # 5: NULL resource location is allowed
            if status == OK:
                self.lives[(model, slot)] = Life()
            return
        life = self.lives.get((model, slot))
        if life is None:
            assert status == SKIPPED, where
            return
        if name == "free":
            self.drop(model, slot)
            return
        mask = DERIV_MASK[args[0]] if name == "deriv" else OP_MASK[name]
        if life.state not in MASKS[mask]:
            assert status == ERROR and state_error, f"{where}: not allowed in state {life.state}"
            return
        assert not state_error, f"{where}: a state error in allowed state {life.state}"
        expected = self.expect(name, model, slot, args, life)
        assert status in expected, f"{where}: expected one of {expected} in state {life.state}"
        if expected == MODEL_DEPENDENT and status == ERROR:
            life.state = "Error"  # the model refused a value the sequence set: the instance is in the Error state
            return
        self.advance(name, model, slot, args, life, status)

    def expect(self, name: str, model: int, slot: int, args: list[Any], life: Life) -> tuple[Any, ...]:
        """The allowed statuses; ``MODEL_DEPENDENT`` when only the model's checks of set values decide."""
        either = MODEL_DEPENDENT
        if name in ("cancel", "deriv"):
            return (ERROR,)  # never in StepInProgress / not supported: both refused
        if name == "setup":
            td, tol, t0, sd, t1 = args
            bad = (td and not (math.isfinite(tol) and tol > 0)) or (sd and not (math.isfinite(t1) and t1 >= t0))
            return (ERROR,) if bad else (OK,)
        if name == "exit":
            return either if life.suspect else (OK,)
        if name == "step":
            t = life.time if args[0] == 0 else args[1]
            h = args[2]
            if not (math.isfinite(h) and h > 0) or not math.isfinite(t) or abs(t - life.time) > 1e-9 * max(
                    1.0, abs(life.time)):
                return (ERROR,)
            dt = life.internal_step_s
            if not (math.isfinite(dt) and dt > 0) or h / dt > MAX_INTERNAL_STEPS + 0.5:
                return (ERROR,)  # refused before any work (uavfmu_rule_internal_steps): nothing changes
            return either if life.suspect else (OK,)  # set values: the model may refuse them
        if name in ("get", "set"):
            return self.expect_values(name, model, args, life)
        if name == "status":
            fn, kind, null = args
            if null:
                return (ERROR,)
            return (OK,) if STATUS_KIND.get(fn) == kind else (DISCARD,)
        if name == "debug":
            _on, n, null = args
            return (OK,) if n == 0 or (not null and n == 1) else (ERROR,)  # categories: logAll, nonsense
        if name in ("enter", "terminate", "reset", "getState"):
            return (OK,)
        return self.expect_states(name, model, slot, args)

    def expect_values(self, name: str, model: int, args: list[Any], life: Life) -> tuple[Any, ...]:
        kind, refs, _values, null = args
        if not refs:
            return (OK,)
        if null:
            return (ERROR,)
        table = self.vars[model]
        for r in refs:
            v = table.get(r)
            if v is None or v.type != kind:
                return (ERROR,)
            if name == "set":
                op = {"input": "SetInput", "parameter": "SetTunable" if v.variability == "tunable" else "SetFixed"}
                if v.causality not in op or life.state not in MASKS[op[v.causality]]:
                    return (ERROR,)
        outputs = any(table[r].causality == "output" for r in refs)
        if name == "get" and outputs and life.suspect and life.state != "Error":
            return MODEL_DEPENDENT  # outputs recomputed from values the model may refuse
        return (OK,)

    def expect_states(self, name: str, model: int, slot: int, args: list[Any]) -> tuple[Any, ...]:
        owner, idx = args[0], args[1]
        entries = self.saved[owner]
        if not entries:
            return (SKIPPED,)
        mine = owner == model and entries[idx % len(entries)][0] == slot
        if not mine:
            return (ERROR,)
        if name == "serial":
            return (OK,) if args[2] == 0 else (ERROR,)  # a damaged or truncated serialized state is refused
        return (OK,)

    def advance(self, name: str, model: int, slot: int, args: list[Any], life: Life, status: Any) -> None:
        if status not in (OK, WARNING):
            return
        moves = {"enter": "InitializationMode", "exit": "StepComplete", "terminate": "Terminated",
                 "reset": "Instantiated"}
        if name in moves:
            life.state = moves[name]
        if name == "reset":
            life.time, life.suspect, life.internal_step_s = 0.0, False, INTERNAL_STEP_S
        elif name == "setup":
            life.time = args[2]
        elif name == "step":
            life.time = (life.time if args[0] == 0 else args[1]) + args[2]
        elif name == "set" and args[1]:
            life.suspect = True
            values = (args[2] + [0.0] * len(args[1]))[: len(args[1])]  # as the worker pads them
            for r, value in zip(args[1], values, strict=True):
                if self.vars[model][r].name == "step_internal_s":
                    life.internal_step_s = float(value)
        elif name == "getState":
            self.saved[model].append((slot, replace(life)))
        elif name in ("setState", "freeState", "serial"):
            entries = self.saved[args[0]]
            idx = args[1] % len(entries)
            if name == "setState":
                restored = entries[idx][1]
                life.state, life.time, life.suspect = restored.state, restored.time, restored.suspect
                life.internal_step_s = restored.internal_step_s
            elif name == "freeState":
                del entries[idx]
            else:
                entries.append((slot, replace(entries[idx][1])))


def check(seq: list[list[Any]], answers: dict[str, list[Any]], tables: list[dict[int, Var]]) -> None:
    """Identical statuses from every backend, each judged by the oracle; every error logged; all healthy."""
    statuses = {name: [r[0] for r in a[:-1]] for name, a in answers.items()}
    first, *others = BACKENDS
    for other in others:
        diff = [(op, statuses[first][k], statuses[other][k]) for k, op in enumerate(seq)
                if statuses[first][k] != statuses[other][k]]
        assert not diff, f"backends disagree ({first}, {other}): {diff[:5]} in {seq}"
    for name, answer in answers.items():
        *results, healthy = answer
        assert healthy, f"{name}: after freeing everything, a fresh instance no longer initialises and steps"
        oracle = Oracle(tables)
        for op, (status, logged, state_error) in zip(seq, results, strict=True):
            if status in (ERROR, FATAL, DISCARD) and op[0] != "null":
                assert logged >= 1, f"{name}: {op} returned {status} without a logged message"
            oracle.judge(op, status, state_error)


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
]


def test_the_same_call_sequences_give_the_same_answers_on_every_backend(backends: dict) -> None:
    workers, tables = backends["workers"], backends["vars"]
    every_vr = sorted({r for table in tables for r in table})

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(sequences(every_vr))
    def run(seq: list[list[Any]]) -> None:
        COUNTS["sequences"] = COUNTS.get("sequences", 0) + 1
        check(seq, {name: workers[name].run(seq) for name in BACKENDS}, tables)

    for seq in EXPLICIT:
        run = example(seq)(run)
    run()
    print(f"\nFMI call sequences: {COUNTS['sequences']} generated, each on {', '.join(BACKENDS)}: same answers")
    assert COUNTS["sequences"] >= EXAMPLES

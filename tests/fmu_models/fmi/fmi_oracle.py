"""What the generated FMI call-sequence tests share (test_fmi_sequences.py: FMI 2.0, test_fmi3_sequences.py: FMI 3.0).

``Worker`` runs sequences in an ``fmi_worker.py`` subprocess; ``Oracle`` judges every answer by the state tables of
the FMI standards written out in ``fmi_standard.py`` (not by ``fmu_models/fmi/statemachine.py``, the table the C
layers are generated from: a wrong row there fails here), with the FMUs' listed deviations, in both directions:
a call the table forbids, or with arguments its rules refuse, must return Error (with a logged state error when it
is the state); an allowed call with valid arguments must succeed (OK), except where the outcome depends on values
the sequence set (then either, and an error moves the oracle to the Error state); the oracle keeps judging after
errors. The version subclasses map their calls onto table rows (``OP_MASK``) and add their own calls.
"""

from __future__ import annotations

import json
import math
import os
import selectors
import subprocess
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import pytest
from fmpy import read_model_description
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from build_fmus import make_model
from fmu_models.fmi.statemachine import MAX_INTERNAL_STEPS, TIME_TOLERANCE
from tests.fmu_models.fmi.fmi_standard import oracle_table

WORKER = Path(__file__).with_name("fmi_worker.py")
TIMEOUT_S = 30.0
MODELS = ("quadrotor", "fixed_wing")
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
NULL_INSTANCE, SKIPPED = -1, -2
INTERNAL_STEP_S = 0.001  # the models' default step_internal_s (a parameter the sequences may change: then "either")
MODEL_DEPENDENT = (OK, ERROR)
#: the first output's value reference of the quadrotor (inputs, then parameters, then outputs)
_QUAD = make_model("quadrotor", None, "defaults")
OUT = len(_QUAD.inputs) + len(_QUAD.params)


class Worker:
    """The worker subprocess of one backend and FMI version, restarted after it dies."""

    def __init__(self, version: int, folders: list[str]) -> None:
        self.args = [str(version), *folders]
        self.proc: subprocess.Popen[str] | None = None

    def _start(self) -> subprocess.Popen[str]:
        env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
        return subprocess.Popen([sys.executable, str(WORKER), *self.args], stdin=subprocess.PIPE,
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


def variables(fmu: Path) -> dict[int, Var]:
    return {v.valueReference: Var(v.type, v.causality, v.variability, v.name)
            for v in read_model_description(str(fmu)).modelVariables}


# ----------------------------------------------------------------------------------------- strategies
SLOT, MODEL = st.integers(0, 1), st.integers(0, 1)
BAD_TIMES = (-5.0, 1e6, math.nan, math.inf)
STEP_SIZES = (0.001, 0.01, 0.1, 1.0, 0.0, -0.01, math.nan, math.inf, 1e5, 1e9)
VALUES = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([math.nan, math.inf, -math.inf, 1e300, 0.0, 1500.0]))
#: toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime (FMI 2.0 SetupExperiment, FMI 3.0 Enter...)
SETUP = (st.integers(0, 1), VALUES, st.sampled_from([0.0, 2.5, -1.0]), st.integers(0, 1), VALUES)


def shared_ops(every_vr: list[int], kinds: list[str], step_tail: tuple[st.SearchStrategy, ...],
               n_null: int) -> list[st.SearchStrategy[list[Any]]]:
    """The operations alike in both versions (``step_tail``: the version's extra step arguments, ``n_null``: how
    many kinds of bad array arguments the get/set calls know)."""
    refs = st.lists(st.one_of(st.sampled_from(every_vr), st.integers(0, 2**32 - 1)), max_size=6)
    return [
        st.tuples(st.sampled_from(["exit", "terminate", "reset", "free", "getState"]), MODEL, SLOT).map(list),
        st.tuples(st.just("step"), MODEL, SLOT, st.just(0), st.just(0.0), st.sampled_from(STEP_SIZES),
                  *step_tail).map(list),
        st.tuples(st.just("step"), MODEL, SLOT, st.just(1), st.sampled_from(BAD_TIMES), st.just(0.01),
                  *step_tail).map(list),
        st.tuples(st.sampled_from(["get", "set"]), MODEL, SLOT, st.sampled_from(kinds), refs,
                  st.lists(VALUES, max_size=6), st.integers(0, n_null)).map(list),
        st.tuples(st.sampled_from(["setState", "freeState"]), MODEL, SLOT, MODEL, st.integers(0, 5)).map(list),
        st.tuples(st.just("serial"), MODEL, SLOT, MODEL, st.integers(0, 5), st.integers(0, 2),
                  st.integers(0, 400)).map(list),
        st.tuples(st.just("debug"), MODEL, SLOT, st.integers(0, 1), st.integers(0, 2), st.integers(0, 1)).map(list),
    ]


# ----------------------------------------------------------------------------------------- the oracle
def bad_setup(tolerance_defined: int, tolerance: float, _start: float, stop_defined: int, stop: float) -> bool:
    """uavfmu_rule_setup refuses these experiment settings (``_start`` is always finite in the sequences)."""
    return bool((tolerance_defined and not (math.isfinite(tolerance) and tolerance > 0))
                or (stop_defined and not (math.isfinite(stop) and stop >= _start)))


@dataclass
class Life:
    """What the oracle knows of one instance: its state, last communication point, whether values were set
    that the model may refuse (then model-dependent outcomes are "OK or error"), its interface."""

    state: str = "Instantiated"
    time: float = 0.0
    suspect: bool = False
    internal_step_s: float = INTERNAL_STEP_S
    model_exchange: bool = False


@dataclass
class Oracle:
    """Expected answers of one FMI version's state machine for one sequence (see the module docstring)."""

    vars: list[dict[int, Var]]
    lives: dict[tuple[int, int], Life] = field(default_factory=dict)
    saved: dict[int, list[tuple[int, Life]]] = field(default_factory=lambda: {0: [], 1: []})

    #: the version's state table, from the standard (fmi_standard.py)
    MASKS: ClassVar[dict[str, tuple[str, ...]]] = oracle_table(2)
    #: worker operation -> the state-machine operation of that table
    OP_MASK: ClassVar[dict[str, str]] = {}
    #: "deriv" op argument -> the MASKS row of that (unsupported) derivative function
    DERIV_MASK: ClassVar[tuple[str, ...]] = ()
    #: the instantiation variants that must succeed
    VALID_INST: ClassVar[tuple[int, ...]] = (0, 5)
    #: worker operation -> the state it leads to when it succeeds
    MOVES: ClassVar[dict[str, str]] = {"terminate": "Terminated", "reset": "Instantiated"}

    def drop(self, model: int, slot: int) -> None:
        self.lives.pop((model, slot), None)
        self.saved[model] = [e for e in self.saved[model] if e[0] != slot]

    def new_life(self, variant: int) -> Life:
        return Life()

    def mask(self, name: str, args: list[Any], life: Life) -> str:
        return self.DERIV_MASK[args[0]] if name == "deriv" else self.OP_MASK[name]

    def judge(self, op: list[Any], status: Any, state_error: bool) -> None:
        """Assert ``status`` is an allowed answer to ``op`` and advance the oracle."""
        name, model, slot, *args = op
        where = f"{op} returned {status}"
        if name == "null":
            assert status in (None, ERROR), where
            return
        if name == "inst":
            self.drop(model, slot)
            assert (status == OK) == (args[0] in self.VALID_INST), where
            if status == OK:
                self.lives[(model, slot)] = self.new_life(args[0])
            return
        life = self.lives.get((model, slot))
        if life is None:
            assert status == SKIPPED, where
            return
        if name == "free":
            self.drop(model, slot)
            return
        if life.state not in self.MASKS[self.mask(name, args, life)]:
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
        """The allowed statuses of the calls both versions have; ``MODEL_DEPENDENT`` when only the model's checks
        of set values decide."""
        if name == "exit":
            return MODEL_DEPENDENT if life.suspect else (OK,)
        if name == "step":
            return self.expect_step(args, life)
        if name in ("get", "set"):
            return self.expect_values(name, model, args, life)
        if name == "debug":
            _on, n, null = args
            return (OK,) if n == 0 or (not null and n == 1) else (ERROR,)  # categories: logAll, nonsense
        if name in ("terminate", "reset", "getState"):
            return (OK,)
        return self.expect_states(name, model, slot, args)

    @staticmethod
    def expect_step(args: list[Any], life: Life) -> tuple[Any, ...]:
        t = life.time if args[0] == 0 else args[1]
        h = args[2]
        if not (math.isfinite(h) and h > 0) or not math.isfinite(t) or abs(t - life.time) > TIME_TOLERANCE * max(
                1.0, abs(life.time)):
            return (ERROR,)
        dt = life.internal_step_s
        if not (math.isfinite(dt) and dt > 0) or h / dt > MAX_INTERNAL_STEPS + 0.5:
            return (ERROR,)  # refused before any work (uavfmu_rule_internal_steps): nothing changes
        return MODEL_DEPENDENT if life.suspect else (OK,)  # set values: the model may refuse them

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
                if v.causality not in op or life.state not in self.MASKS[op[v.causality]]:
                    return (ERROR,)
            elif life.state not in self.MASKS["GetStart" if v.causality in ("input", "parameter") else "GetValue"]:
                return (ERROR,)  # FMI 3.0: only start values before initialisation
        if name == "get" and life.suspect:
            outputs = any(table[r].causality == "output" for r in refs)
            derivatives = any(table[r].name.startswith("der(") for r in refs)
            if derivatives or (outputs and life.state != "Error"):
                return MODEL_DEPENDENT  # computed from values the model may refuse
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
        if name in self.MOVES:
            life.state = self.MOVES[name]
        if name == "reset":
            life.time, life.suspect, life.internal_step_s = 0.0, False, INTERNAL_STEP_S
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


def check(seq: list[list[Any]], answers: dict[str, list[Any]], tables: list[dict[int, Var]],
          oracle: type[Oracle]) -> None:
    """Identical statuses from every backend, each judged by the oracle; every error logged; all healthy."""
    statuses = {name: [r[0] for r in a[:-1]] for name, a in answers.items()}
    first, *others = list(answers)
    for other in others:
        diff = [(op, statuses[first][k], statuses[other][k]) for k, op in enumerate(seq)
                if statuses[first][k] != statuses[other][k]]
        assert not diff, f"backends disagree ({first}, {other}): {diff[:5]} in {seq}"
    for name, answer in answers.items():
        *results, healthy = answer
        assert healthy, f"{name}: after freeing everything, a fresh instance no longer initialises and steps"
        judge = oracle(tables)
        for op, (status, logged, state_error) in zip(seq, results, strict=True):
            if status in (ERROR, FATAL, DISCARD) and op[0] != "null":
                assert logged >= 1, f"{name}: {op} returned {status} without a logged message"
            judge.judge(op, status, state_error)


def run_generated(sequences: st.SearchStrategy[list[list[Any]]], explicit: list[list[list[Any]]], count: int,
                  run_one: Any) -> int:
    """``run_one(seq)`` on the explicit sequences, then on ``count`` generated ones (fixed seed: the same every run);
    the number of sequences run."""
    done = [0]

    @settings(max_examples=count, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(sequences)
    def run(seq: list[list[Any]]) -> None:
        done[0] += 1
        run_one(seq)

    for seq in explicit:
        run = example(seq)(run)
    run()
    return done[0]

"""Runs FMI 2.0 or FMI 3.0 call sequences on the FMU binaries with plain ctypes; one JSON line in, one JSON line out.

``python tests/fmu_models/fmi/fmi_worker.py VERSION UNZIPPED_QUADROTOR UNZIPPED_FIXED_WING`` (VERSION 2 or 3). Each
input line is a list of operations (``[op, model, slot, args...]``, see ``run_op`` and the ``Fmi2`` / ``Fmi3``
classes) run on up to two instance slots per model; the answer line holds, per operation, the returned status
(``null`` for void calls, ``-1`` for an instantiation that returned NULL, ``-2`` for a call the worker skipped
because its slot is empty), the number of messages the FMU logged during the call and whether one of them was a
state-machine refusal ("not allowed in state"). After the sequence every live instance is freed and a fresh
instance must initialise and step: the last entry says whether it did. Run in a subprocess by
test_fmi_sequences.py and test_fmi3_sequences.py: a crash here kills only this process, and the test names the
sequence that did it.
"""

from __future__ import annotations

import ctypes as C  # noqa: N812 (the usual short name in ctypes code)
import json
import math
import sys
from pathlib import Path
from typing import Any, ClassVar

from fmpy import read_model_description
from fmpy.fmi2 import (
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2StepFinishedTYPE,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))  # run as a script: the repository's packages
from fmu_models.fmi.zigcc import host_platform  # the platform folders and library suffix of our builds

MODELS = ("quadrotor", "fixed_wing")
SLOTS = 2
libc = C.CDLL(None)
libc.calloc.restype = C.c_void_p
libc.calloc.argtypes = [C.c_size_t, C.c_size_t]
libc.free.argtypes = [C.c_void_p]
LOGGED = [0]
STATE_ERROR = [False]


def _note(message: bytes | None) -> None:
    LOGGED[0] += 1
    STATE_ERROR[0] |= b"not allowed in state" in (message or b"")


def _logger2(env: Any, name: Any, status: int, category: Any, message: Any) -> None:
    _note(message)


def _logger3(env: Any, status: int, category: Any, message: Any) -> None:
    _note(message)


def _calloc(n: int, size: int) -> int | None:
    return libc.calloc(n, size)


def _free(ptr: int | None) -> None:
    libc.free(ptr)


CALLBACKS = fmi2CallbackFunctions(fmi2CallbackLoggerTYPE(_logger2), fmi2CallbackAllocateMemoryTYPE(_calloc),
                                  fmi2CallbackFreeMemoryTYPE(_free), fmi2StepFinishedTYPE(), None)
LOG3 = C.CFUNCTYPE(None, C.c_void_p, C.c_int, C.c_char_p, C.c_char_p)(_logger3)

V, P, U, B, Z, PV = C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.c_int, C.c_double, C.POINTER(C.c_void_p)
#: the FMU-state functions, alike in both versions: (ctypes signature, FMI 2.0 name, FMI 3.0 name)
STATE_FUNCTIONS = {
    "get": ((B, [V, PV]), "fmi2GetFMUstate", "fmi3GetFMUState"),
    "set": ((B, [V, V]), "fmi2SetFMUstate", "fmi3SetFMUState"),
    "free": ((B, [V, PV]), "fmi2FreeFMUstate", "fmi3FreeFMUState"),
    "size": ((B, [V, V, C.POINTER(C.c_size_t)]), "fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize"),
    "serialize": ((B, [V, V, V, U]), "fmi2SerializeFMUstate", "fmi3SerializeFMUState"),
    "deserialize": ((B, [V, V, U, PV]), "fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"),
}
#: worker op -> the FMI function taking only the instance, by version
SIMPLE = {
    2: {"enter": "fmi2EnterInitializationMode", "exit": "fmi2ExitInitializationMode", "terminate": "fmi2Terminate",
        "reset": "fmi2Reset", "cancel": "fmi2CancelStep"},
    3: {"exit": "fmi3ExitInitializationMode", "terminate": "fmi3Terminate", "reset": "fmi3Reset",
        "stepMode": "fmi3EnterStepMode", "eventMode": "fmi3EnterEventMode", "config": "fmi3EnterConfigurationMode",
        "exitConfig": "fmi3ExitConfigurationMode", "evaluate": "fmi3EvaluateDiscreteStates",
        "ctMode": "fmi3EnterContinuousTimeMode"},
}


class Model:
    """One FMU's library, its instances (slots) and the FMU states they handed out (version-independent part)."""

    version = 0
    signatures: ClassVar[dict[str, tuple[Any, list[Any]]]] = {}

    def __init__(self, unzipped: Path) -> None:
        md = read_model_description(str(unzipped))
        ident = (md.coSimulation or md.modelExchange).modelIdentifier
        suffix = host_platform().suffix
        self.lib = C.CDLL(str(unzipped / "binaries" / self.platform_folder() / f"{ident}{suffix}"))
        self.state_fn = {k: names[self.version - 2] for k, (_sig, *names) in STATE_FUNCTIONS.items()}
        state_sigs = {self.state_fn[k]: sig for k, (sig, *_names) in STATE_FUNCTIONS.items()}
        for name, (res, args) in {**self.signatures, **state_sigs}.items():
            fn = getattr(self.lib, name)
            fn.restype, fn.argtypes = res, args
        self.md = md
        self.slots: list[int | None] = [None] * SLOTS
        self.time_s = [0.0] * SLOTS  # last communication point the worker believes each slot is at
        self.states: list[tuple[int, int]] = []  # (slot it came from, pointer)

    @staticmethod
    def platform_folder() -> str:
        return host_platform().fmi_name

    def call(self, name: str, *args: Any) -> Any:
        return getattr(self.lib, name)(*args)

    def fmi(self, name: str) -> str:
        return f"fmi{self.version}{name}"

    def instantiate(self, variant: int, name: bytes = b"seq") -> int | None:
        raise NotImplementedError

    def healthy(self) -> bool:
        raise NotImplementedError

    def free_slot(self, slot: int) -> None:
        if self.slots[slot]:
            self.call(self.fmi("FreeInstance"), self.slots[slot])
        self.slots[slot] = None
        self.states[:] = [s for s in self.states if s[0] != slot]

    def free_all(self) -> None:
        for k in range(SLOTS):
            self.free_slot(k)
        self.states.clear()

    def special(self, name: str, comp: int, slot: int, args: list[Any]) -> int | None:
        """The version's own operations (the worker op ``name`` on instance ``comp``)."""
        raise NotImplementedError


# ----------------------------------------------------------------------------------------- FMI 2.0
class Fmi2(Model):
    version = 2
    signatures: ClassVar[dict[str, tuple[Any, list[Any]]]] = {
        "fmi2Instantiate": (V, [C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_void_p, B, B]),
        "fmi2FreeInstance": (None, [V]),
        "fmi2SetDebugLogging": (B, [V, B, U, C.c_void_p]),
        "fmi2SetupExperiment": (B, [V, B, Z, Z, B, Z]),
        **{f"fmi2{f}": (B, [V]) for f in ("EnterInitializationMode", "ExitInitializationMode", "Terminate", "Reset",
                                          "CancelStep")},
        **{f"fmi2{op}{t}": (B, [V, P, U, C.c_void_p]) for op in ("Get", "Set")
           for t in ("Real", "Integer", "Boolean", "String")},
        "fmi2DoStep": (B, [V, Z, Z, B]),
        **{f"fmi2Get{t}Status": (B, [V, B, C.c_void_p]) for t in ("", "Real", "Boolean", "Integer", "String")},
        "fmi2GetDirectionalDerivative": (B, [V, P, U, P, U, C.c_void_p, C.c_void_p]),
        "fmi2SetRealInputDerivatives": (B, [V, P, U, C.c_void_p, C.c_void_p]),
        "fmi2GetRealOutputDerivatives": (B, [V, P, U, C.c_void_p, C.c_void_p]),
    }
    DERIVATIVE_FUNCTIONS = ("fmi2GetDirectionalDerivative", "fmi2SetRealInputDerivatives",
                            "fmi2GetRealOutputDerivatives")
    STATUS_FUNCTIONS = ("fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetBooleanStatus", "fmi2GetIntegerStatus",
                        "fmi2GetStringStatus")

    def __init__(self, unzipped: Path) -> None:
        super().__init__(unzipped)
        self.guid = self.md.guid.encode()
        self.resources = (unzipped / "resources").as_uri().encode()

    def instantiate(self, variant: int, name: bytes | None = b"seq") -> int | None:
        # 0 valid, 1 empty name, 2 an fmuType that does not exist, 3 wrong GUID, 4 NULL name,
        # 5 valid with a NULL resource location (allowed: the FMU finds what it needs itself)
        name, kind, guid, resources = {0: (name, 1, self.guid, self.resources), 1: (b"", 1, self.guid, self.resources),
                                       2: (name, 7, self.guid, self.resources), 3: (name, 1, b"{bad}", self.resources),
                                       4: (None, 1, self.guid, self.resources), 5: (name, 1, self.guid, None)}[variant]
        return self.call("fmi2Instantiate", name, kind, guid, resources, C.cast(C.pointer(CALLBACKS), C.c_void_p), 0, 0)

    def healthy(self) -> bool:
        """A fresh instance initialises and steps (the library and the process are not damaged)."""
        comp = self.instantiate(0, b"check")
        if not comp:
            return False
        ok = (self.call("fmi2SetupExperiment", comp, 0, 0.0, 0.0, 0, 0.0) == 0
              and self.call("fmi2EnterInitializationMode", comp) == 0
              and self.call("fmi2ExitInitializationMode", comp) == 0
              and self.call("fmi2DoStep", comp, 0.0, 0.01, 1) == 0)
        self.call("fmi2FreeInstance", comp)
        return ok

    def do_step(self, comp: int, t: float, h: float, _args: list[Any]) -> int:
        return self.call("fmi2DoStep", comp, t, h, 1)

    def array_call(self, comp: int, op: str, kind: str, refs: Any, n: int, vals: Any, _null: int) -> int:
        return self.call(f"fmi2{op}{kind}", comp, refs, n, vals)

    def special(self, name: str, comp: int, slot: int, args: list[Any]) -> int | None:
        if name == "setup":
            status = self.call("fmi2SetupExperiment", comp, *args)
            if status == 0:
                self.time_s[slot] = args[2]
            return status
        if name == "status":
            out = (C.c_double * 2)()
            return self.call(self.STATUS_FUNCTIONS[args[0]], comp, args[1], None if args[2] else C.cast(out, V))
        if name == "deriv":  # the derivative functions this FMU declares unsupported, nvr = 0
            fn = self.DERIVATIVE_FUNCTIONS[args[0]]
            if fn == "fmi2GetDirectionalDerivative":
                return self.call(fn, comp, None, 0, None, 0, None, None)
            return self.call(fn, comp, None, 0, None, None)
        raise KeyError(name)


# ----------------------------------------------------------------------------------------- FMI 3.0
I3 = [C.c_char_p, C.c_char_p, C.c_char_p, C.c_bool, C.c_bool]
#: FMI 3.0 functions the worker calls beyond the FMU-state ones; the clock functions take (instance, vr, n, array...)
CLOCK_FUNCTIONS = ("fmi3GetIntervalDecimal", "fmi3GetIntervalFraction", "fmi3GetShiftDecimal", "fmi3GetShiftFraction",
                   "fmi3SetIntervalDecimal", "fmi3SetIntervalFraction", "fmi3SetShiftDecimal", "fmi3SetShiftFraction",
                   "fmi3GetClock", "fmi3SetClock")
#: the Model Exchange functions taking (instance, array, size) ("me" op 0..4)
ME_ARRAYS = ("fmi3GetContinuousStates", "fmi3GetContinuousStateDerivatives", "fmi3GetNominalsOfContinuousStates",
             "fmi3SetContinuousStates", "fmi3GetEventIndicators")
#: FMI 3.0 value types the worker gets and sets -> ctypes element type
TYPES3 = {"Float64": C.c_double, "Boolean": C.c_bool, "Int32": C.c_int32, "String": C.c_char_p}


class Fmi3(Model):
    version = 3
    signatures: ClassVar[dict[str, tuple[Any, list[Any]]]] = {
        "fmi3InstantiateCoSimulation": (V, [*I3, C.c_bool, C.c_bool, P, U, V, V, V]),
        "fmi3InstantiateModelExchange": (V, [*I3, V, V]),
        "fmi3InstantiateScheduledExecution": (V, [*I3, V, V, V, V, V]),
        "fmi3FreeInstance": (None, [V]),
        "fmi3SetDebugLogging": (B, [V, C.c_bool, U, V]),
        "fmi3EnterInitializationMode": (B, [V, C.c_bool, Z, Z, C.c_bool, Z]),
        **{name: (B, [V]) for name in SIMPLE[3].values()},
        **{f"fmi3{op}{t}": (B, [V, P, U, V, U]) for op in ("Get", "Set") for t in TYPES3},
        "fmi3DoStep": (B, [V, Z, Z, C.c_bool, V, V, V, V]),
        "fmi3GetDirectionalDerivative": (B, [V, P, U, P, U, V, U, V, U]),
        "fmi3GetAdjointDerivative": (B, [V, P, U, P, U, V, U, V, U]),
        "fmi3GetOutputDerivatives": (B, [V, P, U, V, V, U]),
        **{name: (B, [V, P, U, V, V, V]) for name in CLOCK_FUNCTIONS},
        "fmi3ActivateModelPartition": (B, [V, C.c_uint, Z]),
        "fmi3GetNumberOfVariableDependencies": (B, [V, C.c_uint, C.POINTER(C.c_size_t)]),
        "fmi3UpdateDiscreteStates": (B, [V, V, V, V, V, V, V]),
        "fmi3SetTime": (B, [V, Z]),
        **{name: (B, [V, V, U]) for name in ME_ARRAYS},
        "fmi3GetNumberOfContinuousStates": (B, [V, V]),
        "fmi3GetNumberOfEventIndicators": (B, [V, V]),
        "fmi3CompletedIntegratorStep": (B, [V, C.c_bool, V, V]),
    }
    DERIVATIVE_FUNCTIONS = ("fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative", "fmi3GetOutputDerivatives")

    def __init__(self, unzipped: Path) -> None:
        super().__init__(unzipped)
        self.token = self.md.instantiationToken.encode()
        self.resources = str(unzipped / "resources").encode() + b"/"
        self.nx = sum(v.name.startswith("der(") for v in self.md.modelVariables)

    @staticmethod
    def platform_folder() -> str:
        return host_platform().fmi3_name

    def instantiate(self, variant: int, name: bytes | None = b"seq") -> int | None:
        """0 valid Co-Simulation, 1 empty name, 2 eventModeUsed (the FMU has no event mode), 3 wrong token,
        4 NULL name, 5 valid with a NULL resource path, 6 Scheduled Execution (not provided), 7 Model Exchange."""
        head = {1: b"", 4: None}.get(variant, name), b"{bad}" if variant == 3 else self.token
        common = (*head, None if variant == 5 else self.resources, False, False)
        if variant == 6:
            return self.call("fmi3InstantiateScheduledExecution", *common, None, LOG3, None, None, None)
        if variant == 7:
            return self.call("fmi3InstantiateModelExchange", *common, None, LOG3)
        return self.call("fmi3InstantiateCoSimulation", *common, variant == 2, False, None, 0, None, LOG3, None)

    def healthy(self) -> bool:
        comp = self.instantiate(0, b"check")
        if not comp:
            return False
        ok = (self.call("fmi3EnterInitializationMode", comp, False, 0.0, 0.0, False, 0.0) == 0
              and self.call("fmi3ExitInitializationMode", comp) == 0
              and self.do_step(comp, 0.0, 0.01, [0, 0.0, 0.01, 0]) == 0)
        self.call("fmi3FreeInstance", comp)
        return ok

    def do_step(self, comp: int, t: float, h: float, args: list[Any]) -> int:
        flags = [C.c_bool() for _ in range(3)]
        last = C.c_double()
        outs = [None] * 4 if args[3] else [*(C.byref(f) for f in flags), C.byref(last)]
        return self.call("fmi3DoStep", comp, t, h, True, *outs)

    def array_call(self, comp: int, op: str, kind: str, refs: Any, n: int, vals: Any, null: int) -> int:
        return self.call(f"fmi3{op}{kind}", comp, refs, n, vals, n + 1 if null == 3 else n)

    def special(self, name: str, comp: int, slot: int, args: list[Any]) -> int | None:
        if name == "enter":  # [toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime]
            status = self.call("fmi3EnterInitializationMode", comp, *args)
            if status == 0:
                self.time_s[slot] = args[2]
            return status
        buf = (C.c_double * 4)()
        if name == "deriv":  # unsupported: providesDirectionalDerivatives/AdjointDerivatives false, order 0
            fn = self.DERIVATIVE_FUNCTIONS[args[0]]
            if fn == "fmi3GetOutputDerivatives":
                return self.call(fn, comp, None, 0, None, None, 0)
            return self.call(fn, comp, None, 0, None, 0, None, 0, None, 0)
        if name == "clock":  # the FMU has no clocks
            return self.call(CLOCK_FUNCTIONS[args[0]], comp, None, 0, buf, buf, buf)
        if name == "partition":
            return self.call("fmi3ActivateModelPartition", comp, 0, 0.0)
        if name == "dependencies":
            return self.call("fmi3GetNumberOfVariableDependencies", comp, 0, C.byref(C.c_size_t()))
        if name == "update":  # every output argument may be NULL
            return self.call("fmi3UpdateDiscreteStates", comp, *([None] * 6))
        if name == "setTime":
            return self.call("fmi3SetTime", comp, args[0])
        if name == "me":
            return self.model_exchange(comp, args[0], args[1])
        raise KeyError(name)

    def model_exchange(self, comp: int, fn: int, variant: int) -> int:
        """Model Exchange call ``fn`` (0..4 ``ME_ARRAYS``, 5/6 the numbers of states/event indicators, 7
        CompletedIntegratorStep); variant 0 valid (states set: zeros; no event indicators), 1 a wrong size,
        2 NULL arrays or outputs, 3 NaN states."""
        if fn < len(ME_ARRAYS):
            n = 0 if fn == 4 else self.nx
            arr = (C.c_double * (self.nx + 1))(*([math.nan] * (self.nx + 1) if variant == 3 else []))
            return self.call(ME_ARRAYS[fn], comp, None if variant == 2 else arr, n + (variant == 1))
        flags = [C.c_bool(), C.c_size_t()]
        if fn in (5, 6):
            fn_name = ("fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators")[fn - 5]
            return self.call(fn_name, comp, None if variant == 2 else C.byref(flags[1]))
        outs = [None, None] if variant == 2 else [C.byref(flags[0]), C.byref(C.c_bool())]
        return self.call("fmi3CompletedIntegratorStep", comp, True, *outs)


VERSIONS: dict[int, type[Model]] = {2: Fmi2, 3: Fmi3}


# ----------------------------------------------------------------------------------------- operations
def _refs(vrs: list[int]) -> Any:
    return (C.c_uint * max(1, len(vrs)))(*vrs)


def _values(kind: str, values: list[Any], n: int) -> Any:
    """A ctypes array of ``n`` values of ``kind`` ("Boolean3": FMI 3.0's one-byte bool, FMI 2.0's is an int)."""
    if kind in ("Real", "Float64"):
        return (C.c_double * max(1, n))(*[float(v) for v in values[:n]])
    if kind == "String":
        return (C.c_char_p * max(1, n))(*[str(v).encode() for v in values[:n]])
    ints = [int(max(-2**31, min(2**31 - 1, v))) if math.isfinite(v) else 1 for v in values[:n]]
    return ({"Boolean3": C.c_bool, "Int32": C.c_int32}.get(kind, C.c_int) * max(1, n))(*ints)


def _array_call(m: Model, comp: int, op: str, kind: str, vrs: list[int], values: list[Any], null: int) -> int:
    n = len(vrs)
    buf = _values("Boolean3" if (kind, m.version) == ("Boolean", 3) else kind, values + [0.0] * n, n)
    refs = None if null == 1 else _refs(vrs)
    vals = None if null == 2 else C.cast(buf, C.c_void_p)
    return m.array_call(comp, op, kind, refs, n, vals, null)


def _state_op(m: Model, comp: int, op: str, models: dict[str, Model], args: list[Any]) -> int:
    fn = m.state_fn
    if op == "getState":
        ptr = C.c_void_p()
        status = m.call(fn["get"], comp, C.byref(ptr))
        if status == 0 and ptr.value:
            m.states.append((args[0], ptr.value))
        return status
    owner = models[MODELS[args[1]]]  # a state handed out by this or the other model
    if not owner.states:
        return -2
    idx = args[2] % len(owner.states)
    ptr = owner.states[idx][1]
    if op == "setState":
        return m.call(fn["set"], comp, ptr)
    if op == "freeState":
        box = C.c_void_p(ptr)
        status = m.call(fn["free"], comp, C.byref(box))
        if status == 0 and owner is m:
            del owner.states[idx]
        return status
    size = C.c_size_t()
    status = m.call(fn["size"], comp, ptr, C.byref(size))
    if status != 0 or size.value > 1 << 20:
        return status
    data = (C.c_ubyte * max(1, size.value))()
    status = m.call(fn["serialize"], comp, ptr, data, size.value)
    if status != 0:
        return status
    raw = bytearray(data)
    mode, where = args[3], args[4]
    if mode == 1 and raw:
        raw[where % len(raw)] ^= 0xFF  # one damaged byte
    elif mode == 2:
        raw = raw[: where % max(1, len(raw))]  # truncated
    back = (C.c_ubyte * max(1, len(raw)))(*raw)
    out = C.c_void_p()
    status = m.call(fn["deserialize"], comp, back, len(raw), C.byref(out))
    if status == 0 and out.value:
        m.states.append((args[0], out.value))
    return status


def run_op(models: dict[str, Model], op: list[Any]) -> int | None:
    name, model, slot, *args = op
    m = models[MODELS[model]]
    if name == "inst":
        m.free_slot(slot)
        comp = m.instantiate(args[0])
        m.slots[slot] = comp or None
        m.time_s[slot] = 0.0
        return 0 if comp else -1
    if name == "null":  # a NULL instance given to a one-argument function
        return m.call(args[0], None)
    comp = m.slots[slot]
    if not comp:
        return -2
    if name == "free":
        m.free_slot(slot)
        return None
    simple = SIMPLE[m.version]
    if name in simple:
        status = m.call(simple[name], comp)
        if name == "reset" and status == 0:
            m.time_s[slot] = 0.0
        return status
    if name == "step":  # [mode, t, h, ...]: mode 0 steps from the slot's current time, 1 from t
        t = m.time_s[slot] if args[0] == 0 else args[1]
        status = m.do_step(comp, t, args[2], args)
        if status in (0, 1):
            m.time_s[slot] = t + args[2]
        return status
    if name in ("get", "set"):
        return _array_call(m, comp, name.capitalize(), args[0], args[1], args[2], args[3])
    if name == "debug":
        cats = (C.c_char_p * 2)(b"logAll", b"nonsense")
        return m.call(m.fmi("SetDebugLogging"), comp, args[0], args[1], None if args[2] else C.cast(cats, V))
    if name in ("getState", "setState", "freeState", "serial"):
        return _state_op(m, comp, name, models, [slot, *args])
    return m.special(name, comp, slot, args)


def run_sequence(models: dict[str, Model], seq: list[list[Any]]) -> list[Any]:
    out: list[Any] = []
    for op in seq:
        LOGGED[0] = 0
        STATE_ERROR[0] = False
        status = run_op(models, op)
        out.append([status, LOGGED[0], STATE_ERROR[0]])
    for m in models.values():
        m.free_all()
    out.append(all(m.healthy() for m in models.values()))
    return out


def main(version: str, folders: list[str]) -> None:
    cls = VERSIONS[int(version)]
    models = {name: cls(Path(f)) for name, f in zip(MODELS, folders, strict=True)}
    for line in sys.stdin:
        answer = run_sequence(models, json.loads(line))
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])

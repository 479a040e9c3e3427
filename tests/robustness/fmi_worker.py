"""Runs FMI 2.0 call sequences on the FMU binaries with plain ctypes; one JSON line in, one JSON line out.

``python tests/robustness/fmi_worker.py UNZIPPED_QUADROTOR UNZIPPED_FIXED_WING``. Each input line is a list of
operations (``[op, slot, args...]``, see ``OPS``) run on up to two instance slots per model; the answer line
holds, per operation, the returned status (``null`` for void calls, ``-1`` for an ``fmi2Instantiate`` that
returned NULL, ``-2`` for a call the worker skipped because its slot is empty), the number of messages the
FMU logged during the call and whether one of them was a state-machine refusal ("not allowed in state").
After the sequence every live instance is freed and a fresh instance must
initialise and step: the last entry says whether it did. Run in a subprocess by test_fmi_sequences.py: a
crash here kills only this process, and the test names the sequence that did it.
"""

from __future__ import annotations

import ctypes as C  # noqa: N812 (the usual short name in ctypes code)
import json
import math
import sys
from pathlib import Path
from typing import Any

from fmpy import read_model_description
from fmpy.fmi2 import (
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2StepFinishedTYPE,
)

MODELS = ("quadrotor", "fixed_wing")
SLOTS = 2
libc = C.CDLL(None)
libc.calloc.restype = C.c_void_p
libc.calloc.argtypes = [C.c_size_t, C.c_size_t]
libc.free.argtypes = [C.c_void_p]
LOGGED = [0]
STATE_ERROR = [False]


def _logger(env: Any, name: Any, status: int, category: Any, message: Any) -> None:
    LOGGED[0] += 1
    STATE_ERROR[0] |= b"not allowed in state" in (message or b"")


def _calloc(n: int, size: int) -> int | None:
    return libc.calloc(n, size)


def _free(ptr: int | None) -> None:
    libc.free(ptr)


CALLBACKS = fmi2CallbackFunctions(fmi2CallbackLoggerTYPE(_logger), fmi2CallbackAllocateMemoryTYPE(_calloc),
                                  fmi2CallbackFreeMemoryTYPE(_free), fmi2StepFinishedTYPE(), None)

V, P, U, B, Z = C.c_void_p, C.POINTER(C.c_uint), C.c_size_t, C.c_int, C.c_double
SIGNATURES: dict[str, tuple[Any, list[Any]]] = {
    "fmi2Instantiate": (V, [C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_void_p, B, B]),
    "fmi2FreeInstance": (None, [V]),
    "fmi2SetDebugLogging": (B, [V, B, U, C.c_void_p]),
    "fmi2SetupExperiment": (B, [V, B, Z, Z, B, Z]),
    "fmi2EnterInitializationMode": (B, [V]),
    "fmi2ExitInitializationMode": (B, [V]),
    "fmi2Terminate": (B, [V]),
    "fmi2Reset": (B, [V]),
    "fmi2GetReal": (B, [V, P, U, C.c_void_p]),
    "fmi2SetReal": (B, [V, P, U, C.c_void_p]),
    "fmi2GetInteger": (B, [V, P, U, C.c_void_p]),
    "fmi2SetInteger": (B, [V, P, U, C.c_void_p]),
    "fmi2GetBoolean": (B, [V, P, U, C.c_void_p]),
    "fmi2SetBoolean": (B, [V, P, U, C.c_void_p]),
    "fmi2GetString": (B, [V, P, U, C.c_void_p]),
    "fmi2SetString": (B, [V, P, U, C.c_void_p]),
    "fmi2DoStep": (B, [V, Z, Z, B]),
    "fmi2CancelStep": (B, [V]),
    "fmi2GetStatus": (B, [V, B, C.c_void_p]),
    "fmi2GetRealStatus": (B, [V, B, C.c_void_p]),
    "fmi2GetBooleanStatus": (B, [V, B, C.c_void_p]),
    "fmi2GetIntegerStatus": (B, [V, B, C.c_void_p]),
    "fmi2GetStringStatus": (B, [V, B, C.c_void_p]),
    "fmi2GetFMUstate": (B, [V, C.POINTER(C.c_void_p)]),
    "fmi2SetFMUstate": (B, [V, V]),
    "fmi2FreeFMUstate": (B, [V, C.POINTER(C.c_void_p)]),
    "fmi2SerializedFMUstateSize": (B, [V, V, C.POINTER(C.c_size_t)]),
    "fmi2SerializeFMUstate": (B, [V, V, C.c_void_p, U]),
    "fmi2DeSerializeFMUstate": (B, [V, C.c_void_p, U, C.POINTER(C.c_void_p)]),
    "fmi2GetDirectionalDerivative": (B, [V, P, U, P, U, C.c_void_p, C.c_void_p]),
    "fmi2SetRealInputDerivatives": (B, [V, P, U, C.c_void_p, C.c_void_p]),
    "fmi2GetRealOutputDerivatives": (B, [V, P, U, C.c_void_p, C.c_void_p]),
}
DERIVATIVE_FUNCTIONS = ("fmi2GetDirectionalDerivative", "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives")


class Model:
    """One FMU's library, its instances (slots) and the FMU states they handed out."""

    def __init__(self, unzipped: Path) -> None:
        md = read_model_description(str(unzipped))
        ident = md.coSimulation.modelIdentifier
        suffix = {"linux": ".so", "darwin": ".dylib", "win32": ".dll"}[sys.platform]
        plat = {"linux": "linux64", "darwin": "darwin64", "win32": "win64"}[sys.platform]
        self.lib = C.CDLL(str(unzipped / "binaries" / plat / f"{ident}{suffix}"))
        for name, (res, args) in SIGNATURES.items():
            fn = getattr(self.lib, name)
            fn.restype, fn.argtypes = res, args
        self.guid = md.guid.encode()
        self.resources = (unzipped / "resources").as_uri().encode()
        self.slots: list[int | None] = [None] * SLOTS
        self.time_s = [0.0] * SLOTS  # last communication point the worker believes each slot is at
        self.states: list[tuple[int, int]] = []  # (slot it came from, pointer)

    def call(self, name: str, *args: Any) -> Any:
        return getattr(self.lib, name)(*args)

    def instantiate(self, name: bytes | None = b"seq", kind: int = 1, guid: bytes | None = None,
                    resources: bool = True) -> int | None:
        return self.call("fmi2Instantiate", name, kind, self.guid if guid is None else guid,
                         self.resources if resources else None, C.cast(C.pointer(CALLBACKS), C.c_void_p), 0, 0)

    def free_all(self) -> None:
        for k, comp in enumerate(self.slots):
            if comp:
                self.call("fmi2FreeInstance", comp)
            self.slots[k] = None
        self.states.clear()

    def healthy(self) -> bool:
        """A fresh instance initialises and steps (the library and the process are not damaged)."""
        comp = self.instantiate(b"check")
        if not comp:
            return False
        ok = (self.call("fmi2SetupExperiment", comp, 0, 0.0, 0.0, 0, 0.0) == 0
              and self.call("fmi2EnterInitializationMode", comp) == 0
              and self.call("fmi2ExitInitializationMode", comp) == 0
              and self.call("fmi2DoStep", comp, 0.0, 0.01, 1) == 0)
        self.call("fmi2FreeInstance", comp)
        return ok


def _refs(vrs: list[int]) -> Any:
    return (C.c_uint * max(1, len(vrs)))(*vrs)


def _values(kind: str, values: list[Any], n: int) -> Any:
    if kind == "Real":
        return (C.c_double * max(1, n))(*[float(v) for v in values[:n]])
    if kind in ("Integer", "Boolean"):
        return (C.c_int * max(1, n))(*[int(max(-2**31, min(2**31 - 1, v))) if math.isfinite(v) else 1
                                       for v in values[:n]])
    return (C.c_char_p * max(1, n))(*[str(v).encode() for v in values[:n]])


def _array_call(m: Model, comp: int, op: str, kind: str, vrs: list[int], values: list[Any], null: int) -> int:
    n = len(vrs)
    buf = _values(kind, values + [0.0] * n, n)
    refs = None if null == 1 else _refs(vrs)
    vals = None if null == 2 else C.cast(buf, C.c_void_p)
    return m.call(f"fmi2{op}{kind}", comp, refs, n, vals)


def _state_op(m: Model, comp: int, op: str, models: dict[str, Model], args: list[Any]) -> int:
    if op == "getState":
        ptr = C.c_void_p()
        status = m.call("fmi2GetFMUstate", comp, C.byref(ptr))
        if status == 0 and ptr.value:
            m.states.append((args[0], ptr.value))
        return status
    owner = models[MODELS[args[1]]]  # a state handed out by this or the other model
    if not owner.states:
        return -2
    idx = args[2] % len(owner.states)
    ptr = owner.states[idx][1]
    if op == "setState":
        return m.call("fmi2SetFMUstate", comp, ptr)
    if op == "freeState":
        box = C.c_void_p(ptr)
        status = m.call("fmi2FreeFMUstate", comp, C.byref(box))
        if status == 0 and owner is m:
            del owner.states[idx]
        return status
    size = C.c_size_t()
    status = m.call("fmi2SerializedFMUstateSize", comp, ptr, C.byref(size))
    if status != 0 or size.value > 1 << 20:
        return status
    data = (C.c_ubyte * max(1, size.value))()
    status = m.call("fmi2SerializeFMUstate", comp, ptr, data, size.value)
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
    status = m.call("fmi2DeSerializeFMUstate", comp, back, len(raw), C.byref(out))
    if status == 0 and out.value:
        m.states.append((args[0], out.value))
    return status


def run_op(models: dict[str, Model], op: list[Any]) -> int | None:
    name, model, slot, *args = op
    m = models[MODELS[model]]
    if name == "inst":
        if m.slots[slot]:
            m.call("fmi2FreeInstance", m.slots[slot])
            m.states[:] = [s for s in m.states if s[0] != slot]
        # 0 valid, 1 empty name, 2 an fmuType that does not exist, 3 wrong GUID, 4 NULL name,
        # 5 valid with a NULL resource location (allowed: the FMU finds what it needs itself)
        comp = m.instantiate(*({0: (), 1: (b"",), 2: (b"seq", 7), 3: (b"seq", 1, b"{bad-guid}"),
                                4: (None,), 5: (b"seq", 1, None, False)}[args[0]]))
        m.slots[slot] = comp or None
        m.time_s[slot] = 0.0
        return 0 if comp else -1
    if name == "null":  # a NULL component given to a one-argument function
        return m.call(args[0], None)
    comp = m.slots[slot]
    if not comp:
        return -2
    if name == "free":
        m.call("fmi2FreeInstance", comp)
        m.slots[slot] = None
        m.states[:] = [s for s in m.states if s[0] != slot]
        return None
    simple = {"enter": "fmi2EnterInitializationMode", "exit": "fmi2ExitInitializationMode",
              "terminate": "fmi2Terminate", "reset": "fmi2Reset", "cancel": "fmi2CancelStep"}
    if name in simple:
        status = m.call(simple[name], comp)
        if name == "reset" and status == 0:
            m.time_s[slot] = 0.0
        return status
    if name == "setup":
        status = m.call("fmi2SetupExperiment", comp, args[0], args[1], args[2], args[3], args[4])
        if status == 0:
            m.time_s[slot] = args[2]
        return status
    if name == "step":  # [mode, t, h]: mode 0 steps from the slot's current time, 1 from t
        t = m.time_s[slot] if args[0] == 0 else args[1]
        status = m.call("fmi2DoStep", comp, t, args[2], 1)
        if status in (0, 1):
            m.time_s[slot] = t + args[2]
        return status
    if name in ("get", "set"):
        return _array_call(m, comp, name.capitalize(), args[0], args[1], args[2], args[3])
    if name == "status":
        out = (C.c_double * 2)()
        fn = ("fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetBooleanStatus", "fmi2GetIntegerStatus",
              "fmi2GetStringStatus")[args[0]]
        return m.call(fn, comp, args[1], None if args[2] else C.cast(out, C.c_void_p))
    if name == "deriv":  # the derivative functions this FMU declares unsupported, nvr = 0
        fn = DERIVATIVE_FUNCTIONS[args[0]]
        if fn == "fmi2GetDirectionalDerivative":
            return m.call(fn, comp, None, 0, None, 0, None, None)
        return m.call(fn, comp, None, 0, None, None)
    if name == "debug":
        cats = (C.c_char_p * 2)(b"logAll", b"nonsense")
        return m.call("fmi2SetDebugLogging", comp, args[0], args[1], None if args[2] else C.cast(cats, C.c_void_p))
    return _state_op(m, comp, name, models, [slot, *args])


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


def main(folders: list[str]) -> None:
    models = {name: Model(Path(f)) for name, f in zip(MODELS, folders, strict=True)}
    for line in sys.stdin:
        answer = run_sequence(models, json.loads(line))
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])

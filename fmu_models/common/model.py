"""What a vehicle model tells the generic layers: variables, and four pure functions.

A model supplies ``derivatives(t, x, u, p)``, ``outputs(x, u, p)``, ``initial_state(p, u)`` and
``post_step(x, u, p)`` (e.g. quaternion renormalisation), all written in CasADi so that one set of
equations serves simulation (generated C), exact derivatives (identification) and code generation.
The generic step (``step_function``) and the FMI layer only see these and the variable lists.
"""

from __future__ import annotations

import dataclasses
import json
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Protocol, TypeVar

import casadi as ca
import numpy as np

from fmu_models.common.integrators import rk4_step


@dataclass(frozen=True)
class Variable:
    """One scalar of a model vector, with its unit and meaning (ends up in modelDescription.xml)."""

    name: str
    unit: str
    description: str
    start: float = 0.0
    min: float | None = None
    max: float | None = None
    boolean: bool = False


class Layout:
    """Names of the elements of a vector, and named access to a CasADi or numeric vector."""

    def __init__(self, variables: tuple[Variable, ...]) -> None:
        self.variables = variables
        self.names = tuple(v.name for v in variables)
        self.index = {n: i for i, n in enumerate(self.names)}
        if len(self.index) != len(self.names):
            raise ValueError(f"duplicate variable names in {self.names}")

    def __len__(self) -> int:
        return len(self.names)

    def view(self, vec: Any) -> SimpleNamespace:
        """Named elements of ``vec`` (``view(x).pos_north_m``)."""
        return SimpleNamespace(**{n: vec[i] for i, n in enumerate(self.names)})

    def starts(self) -> list[float]:
        return [float(v.start) for v in self.variables]

    def sym(self, name: str) -> ca.SX:
        return ca.SX.sym(name, len(self.names))


class VehicleModel(Protocol):
    """The contract between a vehicle model and the generic layers."""

    name: str
    description: str
    states: Layout
    inputs: Layout
    params: Layout
    outputs: Layout
    #: largest magnitude each state may reach before the integration counts as diverged
    state_limits: tuple[float, ...]

    def derivatives(self, t: Any, x: Any, u: Any, p: Any) -> Any: ...

    def outputs_fn(self, x: Any, u: Any, p: Any) -> Any: ...

    def initial_state(self, p: Any, u: Any) -> Any: ...

    def post_step(self, x: Any, u: Any, p: Any) -> Any: ...


def fingerprint(value: Any) -> str | None:
    """A string equal for equal values of plain data (numbers, strings, None, tuples, lists, dicts and dataclasses
    of them; floats to the last bit), None for anything else: a key :func:`traced` can trust."""
    def plain(v: Any) -> Any:
        if v is None or isinstance(v, (bool, int, str)):
            return v
        if isinstance(v, float):
            return ["float", v.hex()]
        if isinstance(v, (tuple, list)):
            return [type(v).__name__, [plain(x) for x in v]]
        if isinstance(v, dict):
            return ["dict", [[plain(k), plain(x)] for k, x in v.items()]]
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return [type(v).__module__, type(v).__qualname__,
                    [[f.name, plain(getattr(v, f.name))] for f in dataclasses.fields(v)]]
        raise TypeError(type(v).__name__)

    try:
        return json.dumps(plain(value), separators=(",", ":"))
    except TypeError:
        return None


_T = TypeVar("_T")


class BoundedCache:
    """What ``make`` gives, kept per key for the ``max_items`` keys used last, under a lock (threads may share it;
    two threads missing the same key at once both make it and the second is kept: ``make`` must be pure)."""

    def __init__(self, max_items: int) -> None:
        self.max_items = max_items
        self._items: OrderedDict[Any, Any] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key: object) -> bool:
        return key in self._items

    def get(self, key: Any, make: Callable[[], _T]) -> _T:
        """The item kept for ``key``, else ``make()``, kept."""
        with self._lock:
            item = self._items.get(key)
            if item is not None:
                self._items.move_to_end(key)
                return item
        item = make()
        with self._lock:
            self._items[key] = item
            while len(self._items) > self.max_items:
                self._items.popitem(last=False)
        return item


#: most symbolic functions :func:`traced` keeps per process
TRACED_MAX = 64
_TRACED = BoundedCache(TRACED_MAX)


def traced(kind: str, model: VehicleModel, args: tuple[Any, ...], make: Callable[[], _T]) -> _T:
    """The function ``make()`` traces from ``model``'s equations, kept per process and reused for a model of the
    same structure. Tracing a model (and eliminating its common subexpressions) takes a good part of a second,
    and one process builds the same model's functions many times over: every simulator, estimator, excitation
    check and FMU build. The key is the model's ``structure_key()`` (a string that determines every function of
    the model, e.g. its class and parameter defaults), ``kind`` and ``args``; a model without one, or whose key is
    None, is traced every time. CasADi functions are immutable, so callers share one safely (what ``make``
    returns besides a function, e.g. an estimator's compiled steps, must be as safe to share)."""
    key_of = getattr(model, "structure_key", None)
    structure = key_of() if callable(key_of) else None
    if structure is None:
        return make()
    return _TRACED.get((kind, structure, args), make)


class NumericCall:
    """``f`` called on numbers many times over: its results as new 1-D arrays (column-major for a matrix output),
    through CasADi's buffer interface into arrays kept per caller. A call converting to and from CasADi matrices
    costs several times a model step itself. Each argument is
    copied in (any array-like with the argument's number of elements, a scalar for a scalar; a matrix argument's
    elements in CasADi's column-major order, as a ``DM`` gives them); one caller is not to be shared between
    threads."""

    def __init__(self, f: ca.Function) -> None:
        self.function = f
        self._args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self._res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        self._buf, self._evaluate = f.buffer()
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._res):
            self._buf.set_res(i, memoryview(r))

    def __call__(self, *args: Any) -> tuple[np.ndarray, ...]:
        if len(args) != len(self._args):
            raise TypeError(f"{self.function.name()}: {len(args)} arguments given, {len(self._args)} taken")
        for i, (a, v) in enumerate(zip(self._args, args, strict=True)):
            v = v.full().ravel(order="F") if isinstance(v, ca.DM) else np.ravel(v)
            if v.size != a.size:
                raise ValueError(f"{self.function.name()}: argument {self.function.name_in(i)} has {v.size} "
                                 f"elements, allowed {a.size}")
            a[:] = v
        self._evaluate()
        return tuple(r.copy() for r in self._res)


def step_function(model: VehicleModel, name: str = "step", with_outputs: bool = True) -> ca.Function:
    """``step(x, u, p, dt) -> (x_next, y_next)``: one fixed RK4 step and the outputs after it (``x_next`` alone
    without ``with_outputs``: a caller that sub-steps evaluates the outputs once, after the last step)."""
    full = traced("step", model, (), lambda: _step_function(model))
    if name == "step" and with_outputs:
        return full
    return traced("step", model, (name, with_outputs), lambda: renamed(full, name, 2 if with_outputs else 1))


def _step_function(model: VehicleModel) -> ca.Function:
    x = model.states.sym("x")
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    dt = ca.SX.sym("dt")

    def f(t: Any, xx: Any) -> Any:
        return model.derivatives(t, xx, u, p)

    x1 = model.post_step(rk4_step(f, 0.0, x, dt), u, p)
    y1 = model.outputs_fn(x1, u, p)
    # u and p are constant over the step, so the four RK4 stages share much work: eliminate it once.
    x1, y1 = ca.cse([x1, y1])
    return ca.Function("step", [x, u, p, dt], [x1, y1], ["x", "u", "p", "dt"], ["x_next", "y"])


def renamed(f: ca.Function, name: str, n_out: int | None = None, eliminate: bool = False) -> ca.Function:
    """``f`` (SX) under another name with its first ``n_out`` outputs (all: None), each output's common
    subexpressions eliminated with ``eliminate``: milliseconds, where tracing the model's equations again takes a
    good part of a second (an SX function's expressions hold only what its outputs need)."""
    args = [ca.SX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    outs = f.call(args)[:n_out]
    if eliminate:
        outs = [ca.cse(r) for r in outs]
    return ca.Function(name, args, outs, f.name_in(), [f.name_out(i) for i in range(len(outs))])


def init_function(model: VehicleModel, name: str = "init") -> ca.Function:
    """``init(u, p) -> (x0, y0)``: the initial state from the parameters and the outputs there."""
    full = traced("init", model, (), lambda: _init_function(model))
    return full if name == "init" else traced("init", model, (name,), lambda: renamed(full, name, 2))


def _init_function(model: VehicleModel) -> ca.Function:
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    x0 = model.initial_state(p, u)
    x0, y0 = ca.cse([x0, model.outputs_fn(x0, u, p)])
    return ca.Function("init", [u, p], [x0, y0], ["u", "p"], ["x0", "y0"])


def derivative_function(model: VehicleModel) -> ca.Function:
    """``f(x, u, p) -> x_dot``, for linearisation, trim and identification."""
    def make() -> ca.Function:
        x, u, p = model.states.sym("x"), model.inputs.sym("u"), model.params.sym("p")
        return ca.Function("f", [x, u, p], [model.derivatives(0.0, x, u, p)], ["x", "u", "p"], ["x_dot"])

    return traced("derivatives", model, (), make)


def output_function(model: VehicleModel) -> ca.Function:
    """``h(x, u, p) -> y``."""
    def make() -> ca.Function:
        x, u, p = model.states.sym("x"), model.inputs.sym("u"), model.params.sym("p")
        return ca.Function("h", [x, u, p], [model.outputs_fn(x, u, p)], ["x", "u", "p"], ["y"])

    return traced("outputs", model, (), make)

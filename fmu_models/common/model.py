"""What a vehicle model tells the generic layers: variables, and four pure functions.

A model supplies ``derivatives(t, x, u, p)``, ``outputs(x, u, p)``, ``initial_state(p, u)`` and
``post_step(x, u, p)`` (e.g. quaternion renormalisation), all written in CasADi so that one set of
equations serves simulation (generated C), exact derivatives (identification) and code generation.
The generic step (``step_function``) and the FMI layer only see these and the variable lists.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Protocol

import casadi as ca

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


def step_function(model: VehicleModel, name: str = "step", with_outputs: bool = True) -> ca.Function:
    """``step(x, u, p, dt) -> (x_next, y_next)``: one fixed RK4 step and the outputs after it (``x_next`` alone
    without ``with_outputs``: a caller that sub-steps evaluates the outputs once, after the last step)."""
    x = model.states.sym("x")
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    dt = ca.SX.sym("dt")

    def f(t: Any, xx: Any) -> Any:
        return model.derivatives(t, xx, u, p)

    x1 = model.post_step(rk4_step(f, 0.0, x, dt), u, p)
    if not with_outputs:
        return ca.Function(name, [x, u, p, dt], [ca.cse(x1)], ["x", "u", "p", "dt"], ["x_next"])
    y1 = model.outputs_fn(x1, u, p)
    # u and p are constant over the step, so the four RK4 stages share much work: eliminate it once.
    x1, y1 = ca.cse([x1, y1])
    return ca.Function(name, [x, u, p, dt], [x1, y1], ["x", "u", "p", "dt"], ["x_next", "y"])


def init_function(model: VehicleModel, name: str = "init") -> ca.Function:
    """``init(u, p) -> (x0, y0)``: the initial state from the parameters and the outputs there."""
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    x0 = model.initial_state(p, u)
    x0, y0 = ca.cse([x0, model.outputs_fn(x0, u, p)])
    return ca.Function(name, [u, p], [x0, y0], ["u", "p"], ["x0", "y0"])


def derivative_function(model: VehicleModel) -> ca.Function:
    """``f(x, u, p) -> x_dot``, for linearisation, trim and identification."""
    x = model.states.sym("x")
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    return ca.Function("f", [x, u, p], [model.derivatives(0.0, x, u, p)], ["x", "u", "p"], ["x_dot"])


def output_function(model: VehicleModel) -> ca.Function:
    """``h(x, u, p) -> y``."""
    x = model.states.sym("x")
    u = model.inputs.sym("u")
    p = model.params.sym("p")
    return ca.Function("h", [x, u, p], [model.outputs_fn(x, u, p)], ["x", "u", "p"], ["y"])

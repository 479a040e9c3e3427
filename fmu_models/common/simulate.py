"""Numeric simulation of a ``VehicleModel`` in Python through the same CasADi functions the FMU compiles.

Used by tests (FMU vs pure-Python physics), trim and identification. No FMI involved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from fmu_models.common.model import (
    NumericCall,
    VehicleModel,
    derivative_function,
    init_function,
    output_function,
    step_function,
)


@dataclass
class Simulator:
    """Fixed-step RK4 of ``model`` with named access to parameters, inputs and outputs."""

    model: VehicleModel
    step: ca.Function = field(init=False)
    init: ca.Function = field(init=False)
    f: ca.Function = field(init=False)
    h: ca.Function = field(init=False)

    def __post_init__(self) -> None:
        self.step = step_function(self.model)
        self.init = init_function(self.model)
        self.f = derivative_function(self.model)
        self.h = output_function(self.model)
        self._step_numeric: NumericCall | None = None

    def step_arrays(self, x: Any, u: Any, p: Any, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``step`` on numbers: (next state, outputs after the step) as new 1-D arrays (``NumericCall``: several
        times faster per call than ``step`` with its conversions to and from CasADi matrices). It keeps its
        buffers in the simulator: one simulator per thread."""
        if self._step_numeric is None:
            self._step_numeric = NumericCall(self.step)
        x1, y1 = self._step_numeric(x, self.full_inputs(u), p, dt_s)
        return x1, y1

    def params(self, **overrides: float) -> np.ndarray:
        """Default parameter vector with ``overrides`` by name (KeyError naming the unknown one)."""
        p = np.array(self.model.params.starts())
        for name, value in overrides.items():
            if name not in self.model.params.index:
                raise KeyError(f"{name} is not a parameter of {self.model.name}")
            p[self.model.params.index[name]] = value
        return p

    def inputs(self, **values: float) -> np.ndarray:
        u = np.array(self.model.inputs.starts())
        for name, value in values.items():
            u[self.model.inputs.index[name]] = value
        return u

    def full_inputs(self, u: Any) -> Any:
        """``u`` padded with the start values of trailing inputs it leaves out (e.g. battery voltage)."""
        n = len(self.model.inputs)
        if isinstance(u, ca.SX | ca.MX) or np.size(u) >= n:
            return u
        return np.concatenate([np.ravel(u), np.array(self.model.inputs.starts())[np.size(u):]])

    def initial(self, u: Any, p: Any) -> tuple[np.ndarray, np.ndarray]:
        x0, y0 = self.init(self.full_inputs(u), p)
        return np.asarray(x0).ravel(), np.asarray(y0).ravel()

    def output(self, y: np.ndarray, name: str) -> float:
        return float(y[self.model.outputs.index[name]])

    def run(self, u_of_t: Any, p: Any, duration_s: float, dt_s: float = 0.001,
            x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Simulate; ``u_of_t`` is an input vector or a function of time. Returns ``(t, X, Y)``."""
        n = math.ceil(duration_s / dt_s - 1e-9)
        u0 = self.full_inputs(u_of_t(0.0) if callable(u_of_t) else u_of_t)
        x, y = self.initial(u0, p)
        if x0 is not None:
            x = np.asarray(x0, dtype=float)
            y = np.asarray(self.h(x, u0, p)).ravel()
        ts, xs, ys = [0.0], [x], [y]
        for k in range(n):
            u = self.full_inputs(u_of_t(k * dt_s)) if callable(u_of_t) else u0
            x, y = self.step_arrays(x, u, p, dt_s)
            ts.append((k + 1) * dt_s)
            xs.append(x)
            ys.append(y)
        return np.array(ts), np.array(xs), np.array(ys)

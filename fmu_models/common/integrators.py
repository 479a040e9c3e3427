"""Fixed-step integration that knows a model only through the function it is given."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Derivative = Callable[[Any, Any], Any]


def rk4_step(f: Derivative, t: Any, x: Any, dt: Any) -> Any:
    """One classical Runge-Kutta step of ``x_dot = f(t, x)`` over ``dt``."""
    k1 = f(t, x)
    k2 = f(t + dt / 2, x + dt / 2 * k1)
    k3 = f(t + dt / 2, x + dt / 2 * k2)
    k4 = f(t + dt, x + dt * k3)
    return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

"""What the commands share: comma-separated options, a vehicle's default for an option not given, and the exit
status of ``uavfmu excite`` (one for both vehicles: ``excite --vehicle quadrotor`` dispatches to its own module)."""

from __future__ import annotations

#: ``uavfmu excite``: 0 done, 2 bad input, 3 ``--check`` found a set not well conditioned (files still written)
EXCITE_EXIT_OK, EXCITE_EXIT_BAD_INPUT, EXCITE_EXIT_ILL_CONDITIONED = 0, 2, 3


def comma_list(text: str | None) -> tuple[str, ...]:
    """``"a, b,,c"`` -> ``("a", "b", "c")``; None or blank -> ``()``."""
    return tuple(s.strip() for s in (text or "").split(",") if s.strip())


def or_default(value: float | None, default: float) -> float:
    """An option's value, or the vehicle's default when it was not given."""
    return default if value is None else value

"""Small exception classes shared by the physics layer (subclasses of built-ins)."""

from __future__ import annotations


class ParameterError(ValueError):
    """A parameter set is invalid; the message lists every problem found, one per line."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{source}: {len(self.problems)} invalid parameter(s):\n{lines}")


class ProblemList:
    """Collects load-time problems so that one error names all of them (like FMPy's validation)."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[str] = []

    def add(self, message: str) -> None:
        self.items.append(message)

    def check_range(self, name: str, value: float, lo: float | None, hi: float | None) -> None:
        """Record a problem when ``value`` is not finite or outside ``[lo, hi]``."""
        try:
            v = float(value)
        except (TypeError, ValueError):
            self.add(f"{name} = {value!r} is not a number")
            return
        if v != v or v in (float("inf"), float("-inf")):
            self.add(f"{name} = {v} is not finite")
            return
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            self.add(f"{name} = {v} is outside the allowed range [{lo}, {hi}]")

    def raise_if_any(self) -> None:
        if self.items:
            raise ParameterError(self.source, self.items)

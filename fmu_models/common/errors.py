"""Errors of the physics layer: an invalid parameter set is a :class:`fmu_models.config.ConfigError`."""

from __future__ import annotations

from fmu_models.config import ConfigError

__all__ = ["ParameterError", "ProblemList"]


class ParameterError(ConfigError):
    """A parameter set is invalid; ``problems`` lists every problem found, one line each.

    A :class:`~fmu_models.config.ConfigError` (and so a ``ValueError``): callers catch either name.
    """


class ProblemList:
    """Collects the cross-field problems checked after the schema (e.g. idle PWM below the thrust band)."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[str] = []

    def add(self, message: str) -> None:
        self.items.append(message)

    def raise_if_any(self) -> None:
        if self.items:
            raise ParameterError(self.source, self.items)

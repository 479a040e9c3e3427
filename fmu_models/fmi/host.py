"""Hosting an FMU with FMPy as any importer would, without leaking instances or losing its messages.

``fmpy.simulate_fmu`` instantiates, and frees, its own instance; when a step fails it raises before freeing,
and an instance left holding a logger callback that Python has collected crashes the host later. Here the
instance and its logger callback belong to one object whose ``close()`` always frees the instance, and
``simulate_fmu`` runs on it (``fmu_instance=``), so validation uses FMPy's own simulation loop with a
structured input array, and an FMU error becomes a message instead of a crash.

The host also refuses, before the binary sees them, the calls FMI 2.0 forbids (a step before ``start`` or
after ``terminate``, a step that does not continue the last communication point, calls on a freed instance),
whatever the FMU's backend. After a fatal status the instance is freed and instantiated afresh
(``reinstantiate``; ``start`` does it by itself), never reset: FMI 2.0 allows only ``fmi2FreeInstance`` then,
and pythonfmu's library crashes on anything else (fmu_models/fmi/shim.py).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable, Mapping, Sequence
from ctypes import Array, c_char_p, c_double, c_int, c_uint, c_void_p
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)

from fmu_models.quadrotor.constants import MOTOR_PWM_INPUTS

STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")


class FmuRunError(RuntimeError):
    """The FMU failed to load or returned an error; the message carries the FMU's own log lines."""


class FmuHost:
    """One FMI 2.0 co-simulation instance of ``fmu`` driven through FMPy; use as a context manager."""

    def __init__(self, fmu: str | Path, instance_name: str = "uavfmu") -> None:
        self.path = Path(fmu)
        if not self.path.is_file():
            raise FmuRunError(f"{fmu}: FMU not found")
        try:
            self.md = read_model_description(str(fmu))
            self.unzip = extract(str(fmu))
        except Exception as err:  # zipfile, lxml and FMPy each raise their own types for a broken FMU
            raise FmuRunError(f"{fmu}: cannot read the FMU ({type(err).__name__}: {err})") from err
        if self.md.coSimulation is None:
            raise FmuRunError(f"{fmu}: not a co-simulation FMU")
        self.variables = {v.name: v for v in self.md.modelVariables}
        self._vr = {n: v.valueReference for n, v in self.variables.items()}
        #: value-reference lists by the tuple of names they serve: built once, reused every step
        self._refs: dict[tuple[str, ...], list[int]] = {}
        #: ctypes value-reference and value arrays by names, made once: the step path calls FMPy's fmi2SetReal/
        #: fmi2DoStep/fmi2GetReal on them (FMPy's setReal/getReal build new arrays every call)
        self._arrays: dict[tuple[str, ...], tuple[Array, Array]] = {}
        self.messages: list[tuple[str, str]] = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._on_log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.instance_name = instance_name
        self.slave: FMU2Slave | None = None
        #: ``instantiated``, ``stepping``, ``terminated``, ``error`` (reset allowed) or ``fatal`` (free only)
        self.phase = "instantiated"
        #: the next communication point a step must start at [s]
        self.time_s = 0.0
        self.instantiate()

    def instantiate(self) -> None:
        """A fresh instance (after ``close`` or a fatal status); ``FmuRunError`` when the FMU refuses."""
        self._free()
        try:
            slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzip,
                              modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=self.instance_name)
            slave.instantiate(callbacks=self._callbacks, loggingOn=False)
        except Exception as err:  # FMPy raises plain Exception for a missing binary or failed instantiate
            raise FmuRunError(f"{self.path}: cannot instantiate ({err}){self._tail()}") from err
        self.slave = slave
        self.phase, self.time_s, self._used = "instantiated", 0.0, False

    def reinstantiate(self) -> None:
        """Free the instance and instantiate it afresh: the only way on after a fatal status (never reset)."""
        self.instantiate()

    @property
    def fatal(self) -> bool:
        """The FMU returned fmi2Fatal: only ``reinstantiate`` (or ``close``) may follow."""
        return self.phase == "fatal"

    def _failed(self, err: Exception) -> None:
        """Record the FMI status of a failed call (FMPy's FMICallException carries it)."""
        self.phase = "fatal" if getattr(err, "status", None) == 4 or self.phase == "fatal" else "error"

    def _live(self, what: str) -> FMU2Slave:
        if self.slave is None:
            raise FmuRunError(f"{self.path.name}: {what} on a closed FMU instance")
        if self.phase == "fatal":
            raise FmuRunError(f"{self.path.name}: {what} refused: the instance failed fatally; reinstantiate() it "
                              f"(FMI 2.0 allows only fmi2FreeInstance after fmi2Fatal){self._tail()}")
        return self.slave

    def _on_log(self, env: c_void_p, name: c_char_p, status: c_int, category: c_char_p, message: c_char_p) -> None:
        text = message.decode(errors="replace") if isinstance(message, bytes) else str(message)
        self.messages.append((STATUS_NAMES[int(status)] if 0 <= int(status) < 6 else str(status), text))

    def _tail(self, n: int = 5) -> str:
        lines = [f"[{s}] {m}" for s, m in self.messages[-n:]]
        return (": " + " | ".join(lines)) if lines else ""

    def __enter__(self) -> FmuHost:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _free(self) -> None:
        slave, self.slave = getattr(self, "slave", None), None
        if slave is not None:
            slave.freeInstance()

    def close(self) -> None:
        """Free the instance and delete the extracted FMU (idempotent)."""
        self._free()
        unzip, self.unzip = getattr(self, "unzip", None), None
        if unzip:
            shutil.rmtree(unzip, ignore_errors=True)

    def __del__(self) -> None:  # an unclosed host frees its instance while its logger callback still exists
        try:
            self.close()
        except Exception:  # never raise from a finaliser (interpreter shutdown)
            pass

    def start_value(self, name: str) -> float:
        """The modelDescription start value of a variable (KeyError naming it when absent)."""
        v = self.variables[name]
        return float(v.start) if v.start is not None else float("nan")

    def unit(self, name: str) -> str | None:
        v = self.variables[name]
        return v.unit or (v.declaredType.unit if v.declaredType is not None else None)

    def simulate(self, t_s: np.ndarray, inputs: Mapping[str, np.ndarray], outputs: Sequence[str],
                 start_values: Mapping[str, float] | None = None) -> np.ndarray:
        """``fmpy.simulate_fmu`` over the uniform grid ``t_s`` (first sample is time 0 for the FMU).

        ``inputs`` (by FMU input name, sampled at ``t_s``) go in as FMPy's structured input array (none: the
        inputs keep their start values, without FMPy's warning per input); the result has a row per sample of
        ``t_s``. Raises ``FmuRunError`` with the FMU's messages on failure, and naming any input, output or start
        value the FMU has no variable for (FMPy, not validating, would skip such a start value without a word).
        """
        unknown = [n for n in (*inputs, *outputs, *(start_values or {})) if n not in self.variables]
        if unknown:
            raise FmuRunError(f"{self.path.name}: no variable {', '.join(map(repr, dict.fromkeys(unknown)))}")
        dt = float(t_s[1] - t_s[0])
        rows = np.zeros(len(t_s), dtype=[("time", np.float64)] + [(n, np.float64) for n in inputs])
        rows["time"] = t_s - t_s[0]
        for n, v in inputs.items():
            rows[n] = v
        self._fresh()
        self.messages.clear()
        try:
            res: Any = simulate_fmu(self.unzip, model_description=self.md, fmu_instance=self._live("simulate"),
                                    start_values=dict(start_values or {}), input=rows if inputs else None,
                                    output=list(outputs),
                                    step_size=dt, output_interval=dt, stop_time=float(rows["time"][-1]),
                                    validate=False)
        except Exception as err:  # FMPy raises plain Exception (FMICallException) for fmi2Error/fmi2Fatal
            self._failed(err)
            raise FmuRunError(f"{self.path.name}: {err}{self._tail()}") from err
        self.phase = "terminated"  # simulate_fmu terminates an instance it was given (and does not free it)
        if len(res) != len(t_s):
            raise FmuRunError(f"{self.path.name}: {len(res)} result rows for {len(t_s)} samples")
        return res

    # -------------------------------------------------------------- step-by-step (HIL, closed-loop scenarios)
    def start(self, start_values: Mapping[str, float] | None = None) -> None:
        """(Re-)initialise the instance at time 0 with ``start_values``; ``FmuRunError`` on failure."""
        self._fresh()
        self.messages.clear()
        slave = self._live("start")
        try:
            slave.setupExperiment(startTime=0.0)
            if start_values:
                self.set(start_values)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
        except FmuRunError:
            raise
        except Exception as err:  # FMPy raises FMICallException (an Exception) for fmi2Error
            self._failed(err)
            raise FmuRunError(f"{self.path.name}: initialisation failed ({err}){self._tail()}") from err
        self.phase, self.time_s = "stepping", 0.0

    def _fresh(self) -> None:
        """An instance at time 0 for a new run: reset a used one, re-instantiate a fatal or closed one."""
        if self.slave is None or self.phase == "fatal":
            if self.unzip is None:
                raise FmuRunError(f"{self.path.name}: the host is closed")
            self.instantiate()
        elif self._used:
            try:
                self.slave.reset()
            except Exception as err:  # a reset the FMU refuses: start over on a new instance
                self._failed(err)
                self.instantiate()
        self._used = True
        self.phase, self.time_s = "instantiated", 0.0

    def terminate(self) -> None:
        """End the run (``fmi2Terminate``); only ``get``, ``start`` (reset) or ``close`` may follow."""
        slave = self._live("terminate")
        if self.phase != "stepping":
            raise FmuRunError(f"{self.path.name}: terminate refused in phase {self.phase} (start() first)")
        try:
            slave.terminate()
        except Exception as err:
            self._failed(err)
            raise FmuRunError(f"{self.path.name}: terminate failed ({err}){self._tail()}") from err
        self.phase = "terminated"

    def refs(self, names: Sequence[str]) -> list[int]:
        """Value references of ``names`` (cached: the same inputs and outputs are exchanged every step)."""
        key = tuple(names)
        found = self._refs.get(key)
        if found is None:
            found = self._refs[key] = [self._vr[n] for n in key]
        return found

    def _io(self, names: Sequence[str] | Mapping[str, float]) -> tuple[Array, Array]:
        """Preallocated (value references, values) ctypes arrays of ``names``."""
        key = tuple(names)
        found = self._arrays.get(key)
        if found is None:
            refs = self.refs(key)
            found = self._arrays[key] = ((c_uint * len(refs))(*refs), (c_double * len(refs))())
        return found

    @property
    def vehicle(self) -> str:
        """``quadrotor`` (motor PWM inputs) or ``fixed_wing`` (surface and throttle inputs) of our FMUs."""
        if all(name in self.variables for name in MOTOR_PWM_INPUTS):
            return "quadrotor"
        if all(n in self.variables for n in ("aileron_rad", "elevator_rad", "rudder_rad", "throttle")):
            return "fixed_wing"
        raise FmuRunError(f"{self.path}: neither motor PWM inputs pwm_1_us..pwm_4_us nor surface inputs "
                          "aileron_rad, elevator_rad, rudder_rad, throttle")

    def _real_io(self, slave: FMU2Slave, names: Sequence[str] | Mapping[str, float],
                 values: Iterable[float] | None = None) -> Array:
        """``fmi2SetReal`` of ``values`` to ``names``, or (``values`` None) ``fmi2GetReal`` of ``names`` into the
        preallocated buffer, which is returned; ``FmuRunError`` for an unknown name or a failed call."""
        try:
            vr, buf = self._io(names)
            if values is None:
                slave.fmi2GetReal(slave.component, vr, len(vr), buf)
            else:
                buf[:] = [float(v) for v in values]
                slave.fmi2SetReal(slave.component, vr, len(vr), buf)
        except KeyError as err:
            raise FmuRunError(f"{self.path.name}: no variable {err}") from None
        except Exception as err:
            self._failed(err)
            verb = "getting" if values is None else "setting"
            raise FmuRunError(f"{self.path.name}: {verb} {', '.join(names)} failed ({err}){self._tail()}") from err
        return buf

    def set(self, values: Mapping[str, float]) -> None:
        self._real_io(self._live("set"), values, values.values())

    def step(self, t_s: float, dt_s: float, inputs: Mapping[str, float] | None = None) -> None:
        """Set ``inputs`` and advance one communication step; ``FmuRunError`` with the FMU's messages."""
        slave = self._live("step")
        if self.phase != "stepping":
            raise FmuRunError(f"{self.path.name}: step refused in phase {self.phase} (start() first"
                              f"{'; reset with start()' if self.phase in ('error', 'terminated') else ''})")
        if not (dt_s > 0.0 and abs(t_s - self.time_s) <= 1e-9 * max(1.0, abs(self.time_s)) and dt_s < 1e300):
            raise FmuRunError(f"{self.path.name}: step refused: t = {t_s!r} s, dt = {dt_s!r} s; the step must start "
                              f"at the last communication point {self.time_s!r} s with 0 < dt (finite)")
        if inputs:
            self.set(inputs)
        try:
            slave.fmi2DoStep(slave.component, t_s, dt_s, 1)
        except Exception as err:
            self._failed(err)
            raise FmuRunError(f"{self.path.name}: step at t = {t_s:.4f} s failed ({err}){self._tail()}") from err
        self.time_s = t_s + dt_s

    def get(self, names: Sequence[str]) -> dict[str, float]:
        slave = self._live("get")
        if self.phase == "instantiated":
            raise FmuRunError(f"{self.path.name}: get refused before start() (FMI 2.0: no outputs yet)")
        buf = self._real_io(slave, names)
        return dict(zip(names, buf[:], strict=True))

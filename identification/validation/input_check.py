"""Logged inputs checked against what the FMU was built for, before a replay is scored.

A replay feeds the log's inputs to the FMU. When an input lies far outside what the FMU was built for, the
verdict answers another question than the user asked (a 4S log's 15-16 V fed to a 3S model whose
``battery_voltage_V`` refers to 11.1 V scales its thrust by 1.4). Each check gives an :class:`InputFinding`
naming the input, what was logged, what the FMU expects and what it was fed; the replay lists them in the
console, ``metrics.json`` (``input_checks``) and the report. They do not change the exit status: the user
decides, and ``--set NAME=VALUE`` on an FMU input feeds that constant instead of the log (said so in the
finding).

* **battery voltage**: the logged pack voltage over the scored samples against the FMU's
  ``battery_nominal_V``, as LiPo cell counts (``round(V / CELL_NOMINAL_V)``); a finding when the counts differ
  or the median lies outside ``cells x [CELL_EMPTY_V, CELL_FULL_V]`` of the FMU's pack.
* **motor PWM** (quadrotor): scored samples above the FMU's ``pwm_full_us`` (the command ``u`` exceeds 1 and
  the thrust map extrapolates; below ``pwm_idle_us`` a motor gives no thrust, as an ESC at idle does).
* **servo PWM** (fixed wing): scored samples outside the mapping channel's ``[min_us, max_us]`` (the mapping
  clamps them: the FMU sees the range's end).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from fmu_models.quadrotor.constants import CELL_EMPTY_V, CELL_FULL_V, CELL_NOMINAL_V, N_MOTORS

BATTERY_INPUT = "battery_voltage_V"
#: PWM more than this beyond a range end counts as outside [us] (autopilots log integer microseconds)
PWM_TOLERANCE_US = 1.0


@dataclass(frozen=True)
class InputFinding:
    """One logged input outside what the FMU was built for: what was logged, expected and fed."""

    input: str
    check: str
    logged: str
    expected: str
    fed: str
    share: float  #: fraction of the scored samples concerned (1 for a whole-log finding)

    def line(self) -> str:
        return f"{self.input}: {self.check}: logged {self.logged}; the FMU expects {self.expected}; fed {self.fed}"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def cells_of(volt_V: float) -> int:
    """LiPo cells of a pack voltage [V] (its nominal ``CELL_NOMINAL_V`` per cell), at least 1."""
    return max(1, round(float(volt_V) / CELL_NOMINAL_V))


def battery_finding(logged_V: np.ndarray, nominal_V: float, fed: str) -> InputFinding | None:
    """A finding when the logged pack voltage ``logged_V`` [V] (scored samples) is not the FMU's pack."""
    v = np.asarray(logged_V, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    median = float(np.median(v))
    want = cells_of(nominal_V)
    got = cells_of(median)
    lo, hi = want * CELL_EMPTY_V, want * CELL_FULL_V
    if got == want and lo <= median <= hi:
        return None
    return InputFinding(BATTERY_INPUT, "battery cells", f"{v.min():.2f}..{v.max():.2f} V (median {median:.2f} V, "
                        f"{got}S)", f"{want}S (battery_nominal_V {nominal_V:g} V, {lo:.1f}..{hi:.1f} V)", fed, 1.0)


def pwm_finding(name: str, pwm_us: np.ndarray, lo_us: float, hi_us: float, what: str, fed: str,
                check_low: np.ndarray | None = None) -> InputFinding | None:
    """A finding when scored PWM samples ``pwm_us`` lie above ``hi_us`` or (where ``check_low``, default
    everywhere) below ``lo_us``; ``what`` names the range."""
    p = np.asarray(pwm_us, float)
    ok = np.isfinite(p)
    low_mask = np.ones(p.size, bool) if check_low is None else np.asarray(check_low, bool)
    above = ok & (p > hi_us + PWM_TOLERANCE_US)
    below = ok & low_mask & (p < lo_us - PWM_TOLERANCE_US)
    n = int(ok.sum())
    if n == 0 or not (above.any() or below.any()):
        return None
    parts = [f"{above.sum()} above {hi_us:g} us (max {p[above].max():.0f})" if above.any() else "",
             f"{below.sum()} below {lo_us:g} us (min {p[below].min():.0f})" if below.any() else ""]
    share = float((above | below).sum()) / n
    return InputFinding(name, "PWM outside the range", f"{', '.join(s for s in parts if s)} of {n} scored samples "
                        f"({share:.1%})", f"{lo_us:g}..{hi_us:g} us ({what})", fed, share)


def check_inputs(vehicle: str, inputs: Mapping[str, np.ndarray], raw_pwm: Mapping[str, tuple[np.ndarray, Any]],
                 params: Mapping[str, float], logged_V: np.ndarray | None, fed: Mapping[str, str],
                 scored: np.ndarray) -> list[InputFinding]:
    """Every finding of a replay's inputs on its scored samples (``scored``, a mask of the grid).

    ``raw_pwm``: per FMU input, the logged PWM on the grid and its range (``(lo_us, hi_us, what)``); the
    quadrotor's motors are read from ``inputs``. ``logged_V``: the log's battery voltage on the grid (None: not
    logged). ``fed``: per input, what the FMU was fed when it was not the log (``--set``, a battery-state model).
    """
    out: list[InputFinding] = []
    if logged_V is not None and BATTERY_INPUT in inputs and "battery_nominal_V" in params:
        f = battery_finding(np.asarray(logged_V)[scored], float(params["battery_nominal_V"]),
                            fed.get(BATTERY_INPUT, "the logged voltage"))
        out += [f] if f is not None else []
    if vehicle == "quadrotor" and "pwm_full_us" in params:
        idle, full = float(params.get("pwm_idle_us", 0.0)), float(params["pwm_full_us"])
        for k in range(1, N_MOTORS + 1):
            name = f"pwm_{k}_us"
            if name not in inputs:
                continue
            p = np.asarray(inputs[name], float)[scored]
            f = pwm_finding(name, p, idle, full, "the FMU's pwm_idle_us..pwm_full_us", fed.get(
                name, "as logged (above pwm_full_us the command exceeds 1 and the thrust map extrapolates)"),
                np.zeros(p.size, bool))
            out += [f] if f is not None else []
    for name, (pwm, (lo, hi, what)) in raw_pwm.items():
        f = pwm_finding(name, np.asarray(pwm, float)[scored], lo, hi, what,
                        fed.get(name, "the range's end (the mapping clamps)"))
        out += [f] if f is not None else []
    return out

"""The prediction band of each recorded output in the HIL record (``uavfmu hil --record-band``).

The band is the model's discrepancy learned by ``uavfmu discrepancy`` (the ``discrepancy`` block of the parameter
file, :class:`fmu_models.common.params.Discrepancy`, read through ``fmu_models`` alone: ``hil_adapter`` never
imports ``identification``): where the real vehicle would be, given the same inputs, around the FMU's output, at
the nominal level ``BAND`` (5-95 %). The discrepancy was learned on replays restarted from the logged state every
``window_s``; the record lays the same windows over the run (window k starts at the record's first step plus k
``window_s``), so each row's horizon and the scale of the learned quantiles (the model's departure since its
window's first step, its magnitude, or its slope since the previous row:
``fmu_models.common.params.discrepancy_scale``) are the ones ``validate --mc`` uses on a log. What the band
leaves out: the parameter spread (one FMU runs in real time, no Monte Carlo draws) and the drift an autopilot
corrects in closed loop beyond a window (the horizon restarts every window, as in a replay).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from fmu_models.common.params import Discrepancy, discrepancy_of, discrepancy_quantile, read_json
from fmu_models.signals.names import OUTPUT_TO_LOG

#: the band's quantile levels (nominal 90 %, the same 5-95 % as ``validate --mc``)
BAND = (0.05, 0.95)


def read_band_discrepancy(fmu: Path, params_file: Path | None = None) -> Discrepancy:
    """The ``discrepancy`` block of ``params_file``, else of the parameter file embedded in ``fmu`` (``build
    --params``). ValueError naming the file when there is none (or it is malformed: ``ParameterError``)."""
    if params_file is not None:
        found = discrepancy_of(read_json(params_file), str(params_file))
        where = str(params_file)
    else:
        from fmu_models.fmi.fmuzip import embedded_params

        embedded = embedded_params(Path(fmu))
        found = None if embedded is None else discrepancy_of(*embedded)
        where = f"{fmu} (no parameter file embedded)" if embedded is None else embedded[1]
    if found is None:
        raise ValueError(f"--record-band: {where} has no 'discrepancy' block; learn one with `uavfmu discrepancy "
                         "FMU LOG... --params FILE` and build with --params FILE (or give --band-params FILE)")
    return found


class RecordBand:
    """Per recorded FMU output the discrepancy covers: the lower and upper band columns of each row."""

    def __init__(self, disc: Discrepancy, outputs: Sequence[str]) -> None:
        self.disc = disc
        self.names = [o for o in outputs if o in disc.signals]
        if not self.names:
            raise ValueError(f"--record-band: the discrepancy covers {', '.join(sorted(disc.signals))}, none of the "
                             f"recorded outputs ({', '.join(outputs)})")
        #: window length [s]; a discrepancy learned on whole-log replays (``window_s`` 0): one window, the whole run
        self.window_s = disc.window_s if disc.window_s > 0 else math.inf
        self.columns = [f"{OUTPUT_TO_LOG.get(o, o)}_band_{side}" for o in self.names for side in ("lo", "hi")]
        self._t0_s: float | None = None
        self._window = -1
        self._first: dict[str, float] = {}
        self._last: dict[str, tuple[float, float]] = {}  #: previous row's (time [s], output) for the slope

    def values(self, t_s: float, outputs: Mapping[str, float]) -> list[float]:
        """The band columns of the row at simulation time ``t_s`` [s] with FMU outputs ``outputs``."""
        if self._t0_s is None:
            self._t0_s = t_s
        since = t_s - self._t0_s
        k = 0 if math.isinf(self.window_s) else int(since // self.window_s)
        if k != self._window:  # a new window: the departure is measured from here
            self._window, self._first = k, {o: float(outputs[o]) for o in self.names}
        h = np.array([since - (0.0 if math.isinf(self.window_s) else k * self.window_s)])
        out: list[float] = []
        for o in self.names:
            y = float(outputs[o])
            last = self._last.get(o)
            d = 0.0 if last is None or t_s <= last[0] else y - last[1]
            if self.disc.signals[o].wrap:
                d = (d + math.pi) % (2.0 * math.pi) - math.pi
            slope = np.array([abs(d) / (t_s - last[0]) if d else 0.0])
            self._last[o] = (t_s, y)
            yy, first = np.array([y]), np.array([self._first[o]])
            out += [y + float(discrepancy_quantile(self.disc, o, level, h, yy, first, slope)[0]) for level in BAND]
        return out

"""The fixed wing trimmed in level flight with aileron steps on top: the test input of the estimator's roll tests."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim


def trimmed_aileron_steps(n: int, steps: Sequence[tuple[int, int, float]], airspeed_m_s: float = 25.0
                          ) -> tuple[FixedWingModel, np.ndarray, Any, np.ndarray]:
    """``(model, parameters, trim, inputs)``: ``n`` samples of the default fixed wing's trim inputs at
    ``airspeed_m_s``, with ``aileron_rad`` raised by ``delta`` over samples ``[k0, k1)`` for each
    ``(k0, k1, delta)``."""
    model = FixedWingModel()
    p = np.array(model.params.starts())
    tr = trim(model, p, airspeed_m_s)
    i_ail = list(model.inputs.index).index("aileron_rad")
    u = np.tile(tr.u, (n, 1))
    for k0, k1, delta in steps:
        u[k0:k1, i_ail] += delta
    return model, p, tr, u

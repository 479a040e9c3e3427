"""The quadrotor model as the estimator steps it: the motor lag discretised exactly at the log's sample time.

The FMU integrates ``tau dT/dt = T_cmd - T`` with its other states by RK4 at ``step_internal_s`` (1 ms). The
estimator steps at the log's rate (4 ms at 250 Hz), where RK4 no longer follows a fast motor: its decay per
step, ``1 - z + z^2/2 - z^3/6 + z^4/24`` with ``z = dt / tau``, never falls below 0.27 (reached at
``z = 1.6``), while the true one, ``exp(-z)``, does below ``tau = dt / 1.3`` (3 ms at 250 Hz), and at
``tau = dt / 2`` RK4 says 0.33 for a true 0.14. A fitted time constant then absorbs the integrator's error
(biased at small truths), and the residual it leaves is coloured.

:class:`ExactLagModel` removes that error at no extra cost. The command is held over a step (the logged PWM is
held between samples), so the lag has the exact solution ``T(t) = T_cmd + (T_k - T_cmd) exp(-t / tau)``:

- the lag states are frozen during the RK4 stages (their derivative is 0), and the body's forces and moments at
  a stage ``t`` into the step use ``T(t)`` above (the estimator passes each stage its time since the step's
  start, 0, dt/2, dt/2, dt, as ``fmu_models.common.integrators.rk4_step`` does), plus a bump that is zero at
  both ends of the step and makes RK4's Simpson weights integrate the transient exactly (for a motor much
  faster than the step they overstate it: 10 % at ``tau = dt / 5``, which biased such a fit by -20 %);
- after the step the lag states jump to ``T(dt)`` (``post_step``; ``dt`` is the model's ``sample_s``, which
  every record fitted with it must have).

Everything else (forces, moments, outputs, initial state) is the FMU's model, unchanged.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams


class ExactLagModel(QuadrotorModel):
    """:class:`QuadrotorModel` with the motor lag solved exactly over steps of ``sample_s`` [s] (inputs held)."""

    def __init__(self, params: QuadrotorParams | None = None, sample_s: float = 0.004) -> None:
        if not 0.0 < sample_s <= 1.0:
            raise ValueError(f"ExactLagModel: sample_s = {sample_s!r} s (allowed 0..1 s, > 0)")
        super().__init__(params)
        self.sample_s = float(sample_s)
        self.lag0 = int(self.states.index["thrust_state_1_N"])  #: motor 1's lag state (after the body states)

    def structure_key(self) -> str | None:
        """The quadrotor's key and the step ``sample_s`` the exact lag is solved over."""
        key = super().structure_key()
        return None if key is None else f"{key}:sample_s={self.sample_s.hex()}"

    def _lag_at(self, x: Any, u: Any, p: Any, t: Any, impulse: bool = False) -> list[Any]:
        """Per-motor thrust [N] ``t`` [s] after the step's start from the lag states ``x`` held then.

        ``impulse``: the thrust the RK4 stages see. RK4 weighs its stages at 0, dt/2 and dt as Simpson's rule,
        which overstates the integral of a transient much faster than the step (by 10 % at ``tau = dt / 5``):
        a bump ``4 s (1 - s)`` (``s = t / dt``, zero at both ends) is added so that Simpson's rule gives the
        exact impulse ``tau (1 - exp(-dt / tau))`` of the transient over the step (0.5 % of it at
        ``tau = dt / 2``, nothing at slower motors)."""
        pv = self.params.view(p)
        cmd = self.commanded_thrust(u, p)
        tau = ca.fmax(pv.tau_motor_s, 1e-9)
        decay = ca.exp(-t / tau)
        if impulse:
            h = self.sample_s
            exact_mean = tau / h * (1.0 - ca.exp(-h / tau))
            simpson_mean = (1.0 + 4.0 * ca.exp(-h / (2.0 * tau)) + ca.exp(-h / tau)) / 6.0
            s = t / h
            decay = decay + 6.0 * (exact_mean - simpson_mean) * s * (1.0 - s)
        return [ca.if_else(pv.tau_motor_s > 0, cmd[i] + (x[self.lag0 + i] - cmd[i]) * decay, cmd[i])
                for i in range(N_MOTORS)]

    def derivatives(self, t: Any, x: Any, u: Any, p: Any) -> Any:
        """Body states under the thrust ``t`` into the step; the lag states do not move within a step."""
        xt = ca.vertcat(x[0:self.lag0], *self._lag_at(x, u, p, t, impulse=True))
        return ca.vertcat(self.body_derivatives(xt, u, p), *([0.0] * N_MOTORS))

    def post_step(self, x: Any, u: Any, p: Any) -> Any:
        """The lag states' exact value one ``sample_s`` on, then the model's own post-step."""
        return super().post_step(ca.vertcat(x[0:self.lag0], *self._lag_at(x, u, p, self.sample_s)), u, p)

"""Facts of the quadrotor written once: the DJI F450 of paper 000 (Table 1) and the quad's motor count.

``QuadrotorParams`` takes its defaults from here; identification, the HIL adapter, the demo and the FMU host
import these names instead of repeating the numbers.
"""

from __future__ import annotations

N_MOTORS = 4  #: motors of a quad (X or + frame)
#: the FMU parameters that set each motor's initial lag state [N] (negative: at the commanded thrust)
INIT_THRUST_NAMES = tuple(f"init_thrust_{i}_N" for i in range(1, N_MOTORS + 1))
#: a motor lag started in steady state at the commands of a moment (its thrust unknown there) is run over this
#: many time constants of logged commands before the thrust it gives is used: it keeps exp(-15) = 3e-7 of that
#: guess's error (with 6, 2.5e-3: right after a rate loop's saturated 3-2-1-1, 1.6e-4 N of differential thrust
#: that a noise-free replica's fit put into Jx). Identification's thrust histories and validation's restarts
#: both use it.
MOTOR_LAG_SETTLE_TAUS = 15.0
PWM_IDLE_US = 1100.0  #: per-motor PWM at and below which an ESC gives no thrust [us]
PWM_FULL_US = 2000.0  #: per-motor PWM of full command (normalised command u = 1) [us]
MASS_KG = 1.14  #: DJI F450 take-off mass, paper 000 Table 1 [kg]
CELL_FULL_V, CELL_EMPTY_V, CELL_NOMINAL_V = 4.2, 3.3, 3.7  #: LiPo cell voltages: full, empty, nominal [V]
#: FMU inputs, motor k = 1..4 in ArduPilot/PX4 order
MOTOR_PWM_INPUTS = tuple(f"pwm_{k}_us" for k in range(1, N_MOTORS + 1))

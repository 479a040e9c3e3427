"""Facts of the quadrotor written once: the DJI F450 of paper 000 (Table 1) and the quad's motor count.

``QuadrotorParams`` takes its defaults from here; identification, the HIL adapter, the demo and the FMU host
import these names instead of repeating the numbers.
"""

from __future__ import annotations

N_MOTORS = 4  #: motors of a quad (X or + frame)
#: the FMU parameters that set each motor's initial lag state [N] (negative: at the commanded thrust)
INIT_THRUST_NAMES = tuple(f"init_thrust_{i}_N" for i in range(1, N_MOTORS + 1))
PWM_IDLE_US = 1100.0  #: per-motor PWM at and below which an ESC gives no thrust [us]
PWM_FULL_US = 2000.0  #: per-motor PWM of full command (normalised command u = 1) [us]
MASS_KG = 1.14  #: DJI F450 take-off mass, paper 000 Table 1 [kg]
CELL_FULL_V, CELL_EMPTY_V, CELL_NOMINAL_V = 4.2, 3.3, 3.7  #: LiPo cell voltages: full, empty, nominal [V]
#: FMU inputs, motor k = 1..4 in ArduPilot/PX4 order
MOTOR_PWM_INPUTS = tuple(f"pwm_{k}_us" for k in range(1, N_MOTORS + 1))

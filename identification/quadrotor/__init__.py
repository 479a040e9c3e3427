"""The quadrotor's rate and force dynamics from logs by output error: roll/pitch inertia through the arm's moment
effectiveness, motor time constant, yaw torque over yaw inertia, linear drag (``identify``), airframe priors
(``priors``), excitation segments (``segments``) and motor commands rebuilt from ArduCopter's RATE mixer inputs
where the logged outputs are slow (``rate_commands``). Method: readme.md. Imports ``estimation``, ``logs``,
``common`` and ``fmu_models``; never ``thrust``, ``aero``, ``excite``, ``flights`` or ``validation`` (the thrust
map comes in through the parameter file ``identify thrust`` writes)."""

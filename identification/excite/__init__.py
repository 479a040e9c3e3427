"""Experiment design: for the fixed wing, the excitation plan (``design``), its closed-loop check on the model
(``check``), the files a flight needs (``writers``: Lua script, RC override, timeline), the Lua script's dry run
on stand-in ArduPilot bindings (``dry_run``), plots and the workflow; for the quadrotor, the stick plan from its
rate dynamics (``quadrotor``), its closed-loop check (``quadrotor_check``), MANUAL_CONTROL / RC-override steps and
ArduCopter SystemId parameters (``quadrotor_writers``) and the workflow (``quadrotor_workflow``). Imports
``estimation``, ``logs``, ``common``; never ``thrust``, ``aero``, ``flights`` or ``validation``."""

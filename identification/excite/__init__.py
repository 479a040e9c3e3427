"""Experiment design for the fixed wing: the excitation plan (``design``), its closed-loop check on the model
(``check``), the files a flight needs (``writers``: Lua script, RC override, timeline), the Lua script's dry run on
stand-in ArduPilot bindings (``dry_run``), plots and the workflow.
Imports ``estimation``, ``logs``, ``common``; never ``thrust``, ``aero``, ``flights`` or ``validation``."""

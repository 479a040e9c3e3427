"""Synthetic flights of our models, for the demo, tests and benches: closed-loop flights of the FMUs through FMPy
(``scenarios``) and logged flights with sensor noise written as CSV or DataFlash (``synthetic``). Imports
``estimation``, ``logs`` and ``fmu_models``; never ``thrust``, ``aero``, ``excite``, ``quadrotor`` or ``validation``."""

"""From flight logs to identified models and their validation. Subpackages, bottom to top (imports only point
down; the import-linter contracts in pyproject.toml enforce it):

- ``common``: what every room shares: the parallel executor, JSON output, fit metrics and skill intervals, plots.
- ``logs``: reading flight logs (``FlightLog``, readers per format, channel maps, log state, timelines) and
  writing DataFlash logs.
- ``estimation``: the output-error estimator and its identifiability analysis, shared by every model fitted.
- ``thrust``, ``aero``, ``excite``, ``flights``: side by side and independent of each other: the quadrotor's
  thrust map, the fixed wing's derivatives, experiment design, and synthetic flights of our models.
- ``validation``: replays of a log through an FMU, scored against baselines, with Monte Carlo bands and reports.
"""

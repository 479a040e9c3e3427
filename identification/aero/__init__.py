"""The fixed wing's stability and control derivatives from logs: segments and manoeuvres (``segments``,
``model``), the equation-error start (``equation_error``), priors from the geometry (``priors``) and the whole
output-error workflow (``identify``). Method: readme.md. Imports ``estimation``, ``logs``, ``common``; never
``thrust``, ``excite``, ``flights`` or ``validation``."""

#: the continuation's first spans accepted [s] (``AeroOptions.horizon_s`` and ``restart_horizons_s``, the CLI's
#: ``--horizon``); here, in a module without imports, so that the CLI can check the range without loading the fit
HORIZON_RANGE_S = (0.05, 600.0)

"""The fixed wing's stability and control derivatives from logs: segments and manoeuvres (``segments``,
``model``), the equation-error start (``equation_error``), priors from the geometry (``priors``) and the whole
output-error workflow (``identify``). Method: readme.md. Imports ``estimation``, ``logs``, ``common``; never
``thrust``, ``excite``, ``flights`` or ``validation``."""

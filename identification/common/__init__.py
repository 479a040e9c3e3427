"""Tools every identification room shares and that know nothing of logs or models: the Dask-or-local task
executor (``parallel``), JSON output (``jsonio``), fit metrics and skill intervals (``metrics``), figure helpers
(``plots``). Imports only ``fmu_models``."""

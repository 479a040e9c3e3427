"""Flight logs in and out: the ``FlightLog`` type and its quality checks (``flightlog``), one reader per format
(``readers``), channel maps, the state read off a log (``log_state``), excitation timelines (``timeline``), the
flown blocks found in a log itself (``flown_blocks``: the Lua script's EXCT marks, excitation-mode spans), and
the DataFlash writer (``dataflash_writer``) the synthetic flights and tests use. Imports ``common`` and
``fmu_models`` only."""

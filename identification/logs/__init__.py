"""Flight logs in and out: the ``FlightLog`` type and its quality checks (``flightlog``), one reader per format
(``readers``), channel maps, the state read off a log (``log_state``), excitation timelines (``timeline``), and
the DataFlash writer (``dataflash_writer``) the synthetic flights and tests use. Imports ``common`` and
``fmu_models`` only."""

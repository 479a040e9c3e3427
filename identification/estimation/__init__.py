"""The estimator machinery every identified model uses: output-error estimation with exact CasADi
sensitivities, Cramer-Rao and segment-bootstrap bounds (``oem``), least squares with a coloured residual
(``least_squares``), and identifiability and correlation analysis (``identifiability``). Imports ``logs``,
``common`` and ``fmu_models``."""

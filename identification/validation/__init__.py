"""Validation of an FMU against a log: replays and verdicts against baselines (``replay``), the output map
(``output_map``), the battery state fed to the replay (``replay_battery``), Monte Carlo bands (``mc_bands``),
jobs, batches and manifests (``job``, ``workflow``) and reports (``report``). The top of ``identification``: may
import every other room."""

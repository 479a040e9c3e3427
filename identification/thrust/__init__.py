"""The quadrotor's thrust map from logs: the thrust dataset (``dataset``), ANFIS training (``anfis_train``), the
physical per-motor model and its battery state (``model``, ``battery``), the yaw torque ratio (``yaw_torque``),
the leave-one-flight-out workflow (``workflow``) and the paper's reproduction (``paper``). Method: readme.md.
Imports ``estimation``, ``logs``, ``common``; never ``aero``, ``excite``, ``flights`` or ``validation``."""

"""uavfmu: flight logs in, identified UAV flight-dynamics FMUs out."""

__version__ = "0.1.0"

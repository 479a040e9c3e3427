"""uavfmu: flight logs in, identified UAV flight-dynamics FMUs out."""

from importlib.metadata import PackageNotFoundError, version

try:  # one source for the version: pyproject.toml, as installed (`make` installs the package editable)
    __version__ = version("uavfmu")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"

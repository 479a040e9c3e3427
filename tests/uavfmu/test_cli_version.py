"""`uavfmu --version` prints the installed package version, which is pyproject.toml's."""

from __future__ import annotations

import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest

from uavfmu.cli import main


def test_version_is_the_package_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    pyproject = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    expected = pyproject["project"]["version"]
    assert version("uavfmu") == expected
    assert capsys.readouterr().out.strip() == f"uavfmu {expected}"


def test_python_dash_m_uavfmu_runs_the_same_command_line() -> None:
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "uavfmu", "--version"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == f"uavfmu {version('uavfmu')}"

"""Shared fixtures: FMUs built once per test session, the shared data folder."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


def shared_data(*parts: str) -> Path:
    """Path into ``../shared/data``; skips the test with a reason when the file is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (tests on real logs need ../shared beside the repo)")
    return path


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``{"quadrotor": Path, "fixed_wing": Path}``: both FMUs (native backend) with default parameters, built once."""
    from build_fmus import MODELS, build

    out = tmp_path_factory.mktemp("fmus")
    available = [m for m in MODELS if importlib.util.find_spec(f"fmu_models.{m}.model") is not None]
    paths = build(None, out, available)
    return {p.stem: p for p in paths}


@pytest.fixture(scope="session")
def fmi3_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both vehicles as FMI 3.0 Co-Simulation + Model Exchange FMUs (this machine's platform), built once."""
    from build_fmus import BuildOptions, build
    from fmu_models.fmi import zigcc

    out = tmp_path_factory.mktemp("fmi3")
    opts = BuildOptions(fmi_version=3, kinds=("cs", "me"), platforms=(zigcc.host_platform().fmi_name,))
    return {p.stem: p for p in build(None, out, None, options=opts)}


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both FMUs built with the pythonfmu backend (``uavfmu build --backend python``), once."""
    from build_fmus import build

    out = tmp_path_factory.mktemp("python_fmus")
    return {p.stem: p for p in build(None, out, backend="python")}


@pytest.fixture(scope="session")
def quadrotor_fmu(built_fmus: dict[str, Path]) -> Path:
    return built_fmus["quadrotor"]


@pytest.fixture(scope="session")
def fixed_wing_fmu(built_fmus: dict[str, Path]) -> Path:
    if "fixed_wing" not in built_fmus:
        pytest.fail("fixed-wing model missing: fmu_models/fixed_wing/model.py")
    return built_fmus["fixed_wing"]

"""Shared fixtures: FMUs built once per test session, the shared data folder."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


#: where the wall-clock pacing tests (marker ``realtime``) live: ``make test`` runs every other test in parallel, then
#: collects this folder alone for them (the Makefile's ``REALTIME_TESTS``), so one elsewhere would never run
REALTIME_DIR = REPO / "tests" / "hil_adapter"


def realtime_outside(items: list[tuple[str, Path, bool]], folder: Path = REALTIME_DIR) -> list[str]:
    """Node ids of ``(node id, file, marked realtime)`` items marked ``realtime`` but not under ``folder``."""
    return [nodeid for nodeid, path, marked in items if marked and folder not in Path(path).resolve().parents]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    stray = realtime_outside([(i.nodeid, Path(i.path), i.get_closest_marker("realtime") is not None) for i in items])
    if stray:
        raise pytest.UsageError(f"tests marked realtime outside {REALTIME_DIR.relative_to(REPO)} (make test runs them "
                                f"from there alone, and leaves them out of the parallel run): {', '.join(stray)}")


@pytest.fixture(scope="session", autouse=True)
def _temporary_files_under_the_run() -> Iterator[Path]:
    """Temporary files of the code under test and of its subprocesses (``tempfile``, ``$TMPDIR``) go into one folder
    per test process, removed at its end: FMPy's ``simulate_fmu`` leaves its FMU extraction behind when the simulation
    raises, as the FMU error tests make it do (about 50 folders per run left in the system's temporary folder
    before). A short path beside the system's, not under pytest's folder: multiprocessing puts its sockets there,
    and a socket path is limited to 104-108 bytes."""
    folder = Path(tempfile.mkdtemp(prefix="uavfmu-test-"))
    before_env, before_dir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = str(folder), str(folder)
    try:
        yield folder
    finally:
        tempfile.tempdir = before_dir
        if before_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = before_env
        shutil.rmtree(folder, ignore_errors=True)


def shared_data(*parts: str) -> Path:
    """Path into ``../shared/data``; skips the test with a reason when the file is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (tests on real logs need ../shared beside the repo)")
    return path


@contextmanager
def _locked(path: Path):  # type: ignore[no-untyped-def]
    """An exclusive lock on ``path`` (POSIX ``flock``)."""
    import fcntl

    with path.open("a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _built_once(factory: pytest.TempPathFactory, name: str, build: Callable[[Path], list[Path]]) -> dict[str, Path]:
    """``build(folder)``'s FMUs by stem, built once per test run: under pytest-xdist the first worker builds into
    the run's shared temporary folder and the others use its files (read only, as every test uses them), instead of
    each worker compiling the same FMUs again. Without xdist, or without ``flock`` (not POSIX), each builds its own."""
    if "PYTEST_XDIST_WORKER" not in os.environ or importlib.util.find_spec("fcntl") is None:
        return {p.stem: p for p in build(factory.mktemp(name))}
    root = factory.getbasetemp().parent  # shared by the run's workers
    done = root / f"{name}.json"
    with _locked(root / f"{name}.lock"):
        if not done.exists():
            out = root / name
            out.mkdir(exist_ok=True)
            done.write_text(json.dumps([str(p) for p in build(out)]))
    return {Path(p).stem: Path(p) for p in json.loads(done.read_text())}


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``{"quadrotor": Path, "fixed_wing": Path}``: both FMUs (native backend) with default parameters, built once."""
    from build_fmus import MODELS, build

    available = [m for m in MODELS if importlib.util.find_spec(f"fmu_models.{m}.model") is not None]
    return _built_once(tmp_path_factory, "fmus", lambda out: build(None, out, available))


@pytest.fixture(scope="session")
def fmi3_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both vehicles as FMI 3.0 Co-Simulation + Model Exchange FMUs (this machine's platform), built once."""
    from build_fmus import BuildOptions, build
    from fmu_models.fmi import zigcc

    opts = BuildOptions(fmi_version=3, kinds=("cs", "me"), platforms=(zigcc.host_platform().fmi_name,))
    return _built_once(tmp_path_factory, "fmi3", lambda out: build(None, out, None, options=opts))


@pytest.fixture(scope="session")
def python_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both FMUs built with the pythonfmu backend (``uavfmu build --backend python``), once."""
    from build_fmus import build

    return _built_once(tmp_path_factory, "python_fmus", lambda out: build(None, out, backend="python"))


@pytest.fixture(scope="session")
def quadrotor_fmu(built_fmus: dict[str, Path]) -> Path:
    return built_fmus["quadrotor"]


@pytest.fixture(scope="session")
def fixed_wing_fmu(built_fmus: dict[str, Path]) -> Path:
    if "fixed_wing" not in built_fmus:
        pytest.fail("fixed-wing model missing: fmu_models/fixed_wing/model.py")
    return built_fmus["fixed_wing"]

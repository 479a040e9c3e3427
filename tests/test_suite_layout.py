"""The suite's layout: `make test`'s two runs between them run every test (the wall-clock pacing tests, marker
``realtime``, are left out of the parallel run and collected from one folder afterwards, so one elsewhere must stop
the collection), and the code under test leaves its temporary files in a folder of the test process, removed at
its end."""

from __future__ import annotations

import re
from pathlib import Path

from tests.conftest import REALTIME_DIR, REPO, realtime_outside


def test_a_realtime_test_outside_its_folder_is_named_and_the_rest_are_not() -> None:
    items = [("tests/hil_adapter/test_a.py::test_paced", REALTIME_DIR / "test_a.py", True),
             ("tests/hil_adapter/sub/test_b.py::test_paced", REALTIME_DIR / "sub" / "test_b.py", True),
             ("tests/uavfmu/test_c.py::test_paced", REPO / "tests" / "uavfmu" / "test_c.py", True),
             ("tests/uavfmu/test_c.py::test_plain", REPO / "tests" / "uavfmu" / "test_c.py", False),
             ("tests/hil_adapter_x/test_d.py::test_paced", REPO / "tests" / "hil_adapter_x" / "test_d.py", True)]
    assert realtime_outside(items) == ["tests/uavfmu/test_c.py::test_paced",
                                       "tests/hil_adapter_x/test_d.py::test_paced"]


def test_the_makefile_collects_the_realtime_tests_from_the_folder_the_guard_checks() -> None:
    make = (REPO / "Makefile").read_text()
    folder = re.search(r"^REALTIME_TESTS\s*:?=\s*(\S+)\s*$", make, re.MULTILINE)
    assert folder is not None, "Makefile: REALTIME_TESTS not set"
    assert (REPO / folder.group(1)).resolve() == REALTIME_DIR.resolve()
    assert re.search(r"-m realtime \$\(REALTIME_TESTS\)", make), "the realtime run does not use REALTIME_TESTS"
    assert Path(REALTIME_DIR).is_dir()


def test_temporary_files_of_the_code_under_test_stay_in_the_test_process_folder(
        _temporary_files_under_the_run: Path) -> None:
    import os
    import tempfile

    folder = Path(tempfile.mkdtemp())
    assert _temporary_files_under_the_run in folder.parents
    assert os.environ["TMPDIR"] == str(_temporary_files_under_the_run)

"""identification.common.parallel on a local cluster: results in task order from disk, files shipped by content and
paths
given back as the client's, a task failing twice listed with its error while the rest completes, seeds per
task, bounded input."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from identification.common.parallel import MAX_WORKERS, Executor, ParallelError, local_path, task_rng


def read_and_draw(task: dict) -> dict:
    """A task: the shipped file's size and cached location, a seeded draw; task 3 always fails."""
    if task["k"] == 3:
        raise ValueError(f"task 3 cannot read {task['path']}")
    here = local_path(task["path"])
    return {"k": task["k"], "size": len(here.read_bytes()), "where": str(here), "pid": os.getpid(),
            "x": task_rng(11, task["k"]).standard_normal(3)}


def test_results_in_order_files_shipped_and_failures_listed(tmp_path: Path) -> None:
    data = tmp_path / "flight.csv"
    data.write_bytes(b"time_s,x\n" + b"0,1\n" * 1000)
    tasks = [{"k": k, "path": str(data)} for k in range(8)]
    with Executor(workers=2) as ex:
        run = ex.map_tasks(read_and_draw, tasks, files=[data], out_dir=tmp_path / "out", progress=False)
        again = ex.map_tasks(read_and_draw, tasks[::-1], files=[data], progress=False, max_in_flight=1)
    assert set(run.failures) == {3} and set(run.retried) == {3}
    assert "ValueError: task 3 cannot read" in run.failures[3] and str(data) in run.failures[3]  # the client's path
    got = dict(run.results())
    assert got[3] is None and [got[k]["k"] for k in range(8) if k != 3] == [0, 1, 2, 4, 5, 6, 7]
    assert all(got[k]["size"] == data.stat().st_size and got[k]["where"] == str(data) for k in got if k != 3)
    assert {got[k]["pid"] for k in got if k != 3} != {os.getpid()}  # ran in worker processes
    # the same task gives the same draw whatever its position, worker or batch
    rev = dict(again.results())
    for k in (0, 5, 7):
        np.testing.assert_array_equal(got[k]["x"], rev[7 - k]["x"])
    assert (tmp_path / "out" / "000000.npz").is_file() and (tmp_path / "out" / "000000.json").is_file()


def test_bounded_and_unreachable() -> None:
    with pytest.raises(ValueError, match=f"allowed 1..{MAX_WORKERS}"):
        Executor(workers=0)
    with pytest.raises(ParallelError, match=r"cannot reach the dask scheduler at tcp://127\.0\.0\.1:9"):
        Executor(scheduler="tcp://127.0.0.1:9", connect_timeout_s=2.0)

"""identification.common.parallel on a local cluster: results in task order from disk, files shipped by content and
paths
given back as the client's, a task failing twice listed with its error while the rest completes, seeds per
task, bounded input."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from identification.common.parallel import (
    ATTEMPTS,
    MAX_WORKERS,
    Executor,
    ParallelError,
    local_path,
    retry_workers,
    run_inline,
    task_rng,
)


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


def logged_attempt(task: dict) -> dict:
    """A task that writes one line per attempt (its worker's name and process) to ``task["log"]`` before it
    fails: ``"raise"`` raises, ``"die"`` kills its own worker process with SIGKILL."""
    from distributed import get_worker

    with open(task["log"], "a", encoding="utf-8") as f:
        f.write(f"{task['k']} {get_worker().name} {os.getpid()}\n")
    time.sleep(0.1)  # long enough for the other worker to be busy when a retry is placed
    if task["how"] == "die":
        os.kill(os.getpid(), signal.SIGKILL)
    raise ValueError(f"task {task['k']} always fails")


def _attempts(log: Path) -> dict[int, list[tuple[str, int]]]:
    """Task -> the (worker name, process id) of each attempt, in order."""
    out: dict[int, list[tuple[str, int]]] = {}
    for line in log.read_text(encoding="utf-8").splitlines():
        k, name, pid = line.split()
        out.setdefault(int(k), []).append((name, int(pid)))
    return out


def test_a_task_that_always_raises_runs_exactly_twice_the_retry_on_the_other_worker(tmp_path: Path) -> None:
    """Counted attempts, not retried tasks: the first attempt and one retry (``ATTEMPTS``), and the retry is
    placed away from the worker the task failed on (six tasks in flight on two workers: a retry left free to go
    anywhere lands on the worker it failed on for some of them)."""
    log = tmp_path / "attempts.txt"
    tasks = [{"k": k, "log": str(log), "how": "raise"} for k in range(6)]
    with Executor(workers=2) as ex:
        run = ex.map_tasks(logged_attempt, tasks, progress=False)
    assert ATTEMPTS == 2 and set(run.failures) == set(run.retried) == set(range(6))
    attempts = _attempts(log)
    assert {k: len(a) for k, a in attempts.items()} == dict.fromkeys(range(6), ATTEMPTS)
    same = {k: a[0][0] for k, a in attempts.items() if a[0][0] == a[1][0]}
    assert not same, f"retried on the worker they failed on: {same}"


def test_a_task_that_always_kills_its_worker_runs_exactly_twice_on_two_workers(tmp_path: Path) -> None:
    log = tmp_path / "attempts.txt"
    with Executor(workers=2) as ex:
        run = ex.map_tasks(logged_attempt, [{"k": 0, "log": str(log), "how": "die"}], progress=False)
    assert "died during the task" in run.retried[0] and "died during the task" in run.failures[0]
    (first, pid_first), (second, pid_second) = _attempts(log)[0]  # exactly two attempts
    assert first != second and pid_first != pid_second  # not the dead worker, nor its restarted replacement


def test_inline_a_task_that_always_raises_runs_exactly_twice(tmp_path: Path) -> None:
    calls: list[int] = []

    def failing(task: dict) -> dict:
        calls.append(task["k"])
        raise ValueError("always")

    run = run_inline(failing, [{"k": 0}, {"k": 1}], progress=False)
    assert calls == [0, 0, 1, 1] and set(run.failures) == {0, 1}


def test_a_retry_avoids_the_failed_worker_and_its_restart_of_the_same_name() -> None:
    workers = {"tcp://127.0.0.1:1001": {"name": 0}, "tcp://127.0.0.1:1002": {"name": 1},
               "tcp://127.0.0.1:1003": {"name": 0}}  # 1003: the nanny's restart of worker 0, which died at 1001
    assert retry_workers(workers, ("tcp://127.0.0.1:1001", 0)) == ["tcp://127.0.0.1:1002"]
    assert retry_workers(workers, ("tcp://127.0.0.1:1002", 1)) == ["tcp://127.0.0.1:1001", "tcp://127.0.0.1:1003"]
    # workers without names (a remote cluster's): only the address is avoided
    unnamed = {"tcp://a:1": {"name": None}, "tcp://b:1": {"name": None}}
    assert retry_workers(unnamed, ("tcp://a:1", None)) == ["tcp://b:1"]


def sleep_then(task: dict) -> dict:
    """Log the attempt, sleep ``task["s"]`` seconds, then die (SIGKILL to the worker) or return."""
    from distributed import get_worker

    with open(task["log"], "a", encoding="utf-8") as f:
        f.write(f"{task['k']} {get_worker().name} {os.getpid()}\n")
    time.sleep(task["s"])
    if task["die"]:
        os.kill(os.getpid(), signal.SIGKILL)
    return {"k": task["k"]}


def test_a_task_waiting_behind_a_crashing_one_is_not_charged(tmp_path: Path) -> None:
    """Four tasks on two single-threaded workers, the first killing its worker: only it is retried. With two
    tasks in flight per worker thread the scheduler queued a second task on each worker, which died with the
    crashing one and was charged an attempt it never ran."""
    log = tmp_path / "attempts.txt"
    tasks = [{"k": k, "log": str(log), "s": 0.5 if k == 0 else 0.3, "die": k == 0} for k in range(4)]
    with Executor(workers=2) as ex:
        run = ex.map_tasks(sleep_then, tasks, progress=False)
    assert set(run.failures) == {0}
    assert set(run.retried) == {0}, f"charged without having failed: {sorted(set(run.retried) - {0})}"

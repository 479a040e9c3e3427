"""Batch validation on a real dask cluster (scheduler and two workers as separate processes on loopback, started
with the ``dask`` command line) gives byte-identical metrics.json to the default local run; a worker killed with
SIGKILL mid-batch costs a retry of the tasks it held (one, or two when the scheduler had queued a second one on
it) and the batch completes."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from identification.common.parallel import Executor
from identification.flights import synthetic
from identification.validation.replay import options
from identification.validation.workflow import ValidationJob, validate_batch, write_batch_report

REPO = Path(__file__).resolve().parents[3]
PAIRS = 40


@pytest.fixture(scope="module")
def batch(fixed_wing_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    """40 short noisy fixed-wing logs (one 3 s flight, 40 sensor-noise seeds) and the PWM mapping."""
    d = tmp_path_factory.mktemp("dask_batch")
    t, sig = synthetic.fixed_wing_flight(seconds=3.0, rate_hz=50.0)
    logs = []
    for k in range(PAIRS):
        logs.append(synthetic.write_csv_log(d / f"wing{k:02d}.csv", t, synthetic.with_noise(sig, k)))
    return synthetic.write_mapping_toml(d / "mapping.toml"), logs


def _jobs(fmu: Path, mapping: Path, logs: list[Path], root: Path) -> list[ValidationJob]:
    opts = options(window_s=1.0, rate_hz=50.0)
    return [ValidationJob(fmu, log, opts, mapping=mapping, report_dir=root / f"{k:03d}", report_html=False)
            for k, log in enumerate(logs)]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(*args: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO), "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0",
           "DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "1.0"}
    return subprocess.Popen([str(Path(sys.executable).parent / "dask"), *args], env=env, cwd=REPO,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


@pytest.fixture
def cluster() -> str:
    """``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1; stopped (by their pids) afterwards."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard")]
    try:
        for k in range(2):
            procs.append(_dask("worker", address, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                               "--no-dashboard", "--name", f"w{k}"))
        _wait_for_workers(address, 2, timeout_s=60.0)
        yield address
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=5)


def _wait_for_workers(address: str, n: int, timeout_s: float) -> None:
    from distributed import Client

    with Client(address, timeout="30s") as client:
        client.wait_for_workers(n, timeout=timeout_s)


def _metrics(root: Path) -> dict[str, bytes]:
    return {p.parent.name: p.read_bytes() for p in sorted(root.glob("*/metrics.json"))}


def test_real_cluster_gives_the_local_metrics_bit_for_bit(fixed_wing_fmu: Path, batch, cluster: str,
                                                          tmp_path: Path) -> None:
    mapping, logs = batch
    local = validate_batch(_jobs(fixed_wing_fmu, mapping, logs, tmp_path / "local"), workers=2)
    remote = validate_batch(_jobs(fixed_wing_fmu, mapping, logs, tmp_path / "remote"), scheduler=cluster)
    assert not [r.error for r in local if r.status == "error"]
    a, b = _metrics(tmp_path / "local"), _metrics(tmp_path / "remote")
    assert len(a) == PAIRS and a == b
    first = json.loads(a["000"])
    assert first["fmu"]["path"] == str(fixed_wing_fmu) and first["log"]["path"] == str(logs[0])  # client paths
    assert [r.as_dict() | {"report": None} for r in local] == [r.as_dict() | {"report": None} for r in remote]
    write_batch_report(remote, tmp_path / "remote")
    assert (tmp_path / "remote" / "results.json").is_file()


def test_worker_killed_mid_batch_costs_one_retry(fixed_wing_fmu: Path, batch, tmp_path: Path) -> None:
    """SIGKILL to the worker process running a task after 8 results: every pair still gets its result, only the
    tasks the killed worker held are retried (on the other worker or the restarted one: one task, as each worker
    runs one at a time), each once, and a retried one matches an undisturbed run. A kill that lands just after its
    task's result left the worker (the scheduler still lists the task for a moment) costs no retry, rightly: such a
    run is repeated, at most three times (it happened in about 1 of 14 runs)."""
    mapping, logs = batch
    retried: list = []
    for attempt in range(3):
        root = tmp_path / f"killed{attempt}"
        jobs = _jobs(fixed_wing_fmu, mapping, logs[:16], root)
        results, killed = _batch_with_a_worker_killed(jobs)
        assert killed, "no worker was busy to kill"
        assert all(r.status != "error" and (root / f"{k:03d}" / "metrics.json").is_file()
                   for k, r in enumerate(results))
        retried = [r for r in results if r.retried]
        assert len(retried) <= killed[1] and all("died" in r.retried for r in retried), (killed, retried)
        if retried:
            break
    assert retried, "in three runs no kill landed while its task was still running"
    again = validate_batch([jobs[logs.index(Path(retried[0].log))]], workers=1)
    assert again[0].signals == retried[0].signals


def _batch_with_a_worker_killed(jobs: list[ValidationJob]) -> tuple[list, list[int]]:
    """The batch's results on two local workers, one of them killed once 8 results are in; and [its pid, how many
    tasks it held] (empty when none was busy)."""
    with Executor(workers=2) as ex:
        pids = ex.client.run(os.getpid)
        killed: list[int] = []

        def kill_busy_worker(done: int, total: int) -> None:
            if done == 8 and not killed:
                threading.Thread(target=_kill_one, args=(ex, pids, killed), daemon=True).start()

        return validate_batch(jobs, progress=kill_busy_worker, executor=ex), killed


def _kill_one(ex: Executor, pids: dict[str, int], killed: list[int]) -> None:
    """SIGKILL the process of a worker that is executing a task (bounded wait for one)."""
    for _ in range(200):
        busy = [w for w, keys in ex.client.processing().items() if keys and w in pids]
        if busy:
            held = len(ex.client.processing()[busy[0]])  # what it loses: read before the kill and after
            os.kill(pids[busy[0]], signal.SIGKILL)
            held = max(held, len(ex.client.processing().get(busy[0], ())))
            killed += [pids[busy[0]], held]
            return
        time.sleep(0.01)

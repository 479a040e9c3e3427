"""One execution layer for embarrassingly parallel jobs, on ``dask.distributed``.

:func:`map_tasks` runs ``fn(task)`` for every task and streams each result to disk as it arrives::

    run = map_tasks(fn, tasks, files=[fmu_path, log_path], out_dir=Path("out"))
    for i, result in run.results():   # in task order, read back from disk
        ...
    run.failures                      # {task index: error} of tasks that failed twice

Where the work runs: in the calling process (``workers=0``, no ``scheduler``: for small jobs that would not repay a
cluster start-up; same seeding, result streaming and failure accounting, but a task that kills the process kills
the job), an in-process ``LocalCluster`` of ``workers`` single-threaded worker processes bound to
127.0.0.1 with no dashboard (the default), or the cluster whose scheduler is ``scheduler="tcp://HOST:PORT"``
(else the ``UAVFMU_SCHEDULER`` environment variable). Results are the same bit for bit either way: a task
carries its own seed (:func:`task_rng`), and results are reduced in task order, never completion order.

Files (FMUs, logs, mappings) travel as bytes with the tasks that read them and are written once per worker
machine into a content-hash cache; inside ``fn``, :func:`local_path` turns the client's path into the cached copy, and
every cached path in a result or error message is turned back into the client's path. No model object is
pickled: ``fn`` must be an importable module-level function whose tasks and results are plain data.

Faults: a task whose worker dies under it (a crashing FMU, SIGKILL, out of memory) or that raises is run once
more, on another worker when there is one (not the worker it failed on, nor a worker of the same name: the one
a nanny restarted in place of a worker that died); a task that fails twice is listed in
:attr:`TaskRun.failures` with its error, and the rest completes. At most ``max_in_flight`` tasks are submitted
at a time (default: one per worker thread), so memory on client and workers is bounded by the tasks in flight, not
by the number of tasks. One per thread: no task waits on a worker behind another, so a task that kills its worker
takes no queued task with it (with two per thread the scheduler queued a second task on each worker, and that task
died with the first and was charged an attempt it never ran; the scheduler's own queue holds back only task groups
larger than twice the threads).

Results are dicts: ``numpy`` array values go to ``NNNNNN.npz``, the rest to ``NNNNNN.json`` (no pickle on disk).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
import tempfile
import threading
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: environment variable naming the scheduler of a running cluster (``tcp://HOST:PORT``)
SCHEDULER_ENV = "UAVFMU_SCHEDULER"
MAX_WORKERS = 256
MAX_TASKS = 1_000_000
#: scheduler settings for exact fault accounting (a running cluster's scheduler needs them in its environment:
#: ``DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES=0 DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION=1.0``)
SCHEDULER_CONFIG = {"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}
#: times a task runs at most: the first attempt and one retry
ATTEMPTS = 2

_THREAD = threading.local()

#: files a job ships: the same for every task, or a function of the task (each task gets only its own)
#: a tqdm bar (True), none (False), or a function called with (tasks done, tasks) after each task
Progress = bool | Callable[[int, int], None]
Files = Iterable[str | Path] | Callable[[Any], Iterable[str | Path | None]]


class ParallelError(RuntimeError):
    """The cluster could not be reached or started; the message names the address and what to do."""


def task_rng(seed: int, index: int) -> np.random.Generator:
    """The random generator of task ``index`` of a job seeded ``seed``: independent of which worker runs the task
    and of the order tasks run in (``numpy.random.SeedSequence`` with the task index as spawn key)."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def local_path(path: str | Path) -> Path:
    """Inside a task: the worker's cached copy of a file the client shipped (``files=`` of :func:`map_tasks`);
    the path itself when it was not shipped (or outside a task)."""
    return Path(getattr(_THREAD, "files", {}).get(str(path), path))


def cache_root() -> Path:
    """Where workers keep shipped files, by content hash (one folder per user on each machine)."""
    return Path(os.environ.get("UAVFMU_CACHE", Path(tempfile.gettempdir()) / f"uavfmu-cache-{os.getuid()}"))


def _materialise(sha: str, name: str, data: bytes) -> Path:
    """The cached copy of a shipped file, written once (atomically) per content hash."""
    path = cache_root() / sha[:32] / name
    if not (path.is_file() and path.stat().st_size == len(data)):
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{name}.{os.getpid()}.{threading.get_ident()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, path)
    return path


def _restore(obj: Any, swap: Sequence[tuple[str, str]]) -> Any:
    """``obj`` with every cached path in its strings replaced by the client's path."""
    if isinstance(obj, str):
        for local, original in swap:
            obj = obj.replace(local, original)
        return obj
    if isinstance(obj, dict):
        return {k: _restore(v, swap) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return type(obj)(_restore(v, swap) for v in obj)
    return obj


def _run_task(fn: Callable[[Any], dict[str, Any]], task: Any, shipped: Mapping[str, tuple[str, str]],
              blobs: Mapping[str, bytes]) -> dict[str, Any]:
    """Worker side: files into the cache, ``fn(task)``, cached paths back to the client's; an exception becomes
    ``{"__error__": text}`` (a died worker never returns: the client sees it as the future's error)."""
    files = {orig: str(_materialise(sha, name, blobs[sha])) for orig, (sha, name) in shipped.items()}
    swap = sorted(((loc, orig) for orig, loc in files.items()), key=lambda p: -len(p[0]))
    _THREAD.files = files
    try:
        out = fn(task)
        if not isinstance(out, dict):
            raise TypeError(f"{getattr(fn, '__name__', fn)} returned {type(out).__name__}, expected a dict")
        return _restore(out, swap)
    except Exception as err:
        tail = traceback.extract_tb(err.__traceback__)[-1:]
        where = f" (at {Path(tail[0].filename).name}:{tail[0].lineno})" if tail else ""
        return {"__error__": _restore(f"{type(err).__name__}: {err}{where}", swap)}
    finally:
        _THREAD.files = {}


def _write(out_dir: Path, i: int, result: Mapping[str, Any]) -> None:
    arrays = {k: v for k, v in result.items() if isinstance(v, np.ndarray)}
    rest = {k: v for k, v in result.items() if k not in arrays}
    if arrays:
        np.savez(out_dir / f"{i:06d}.npz", **arrays)
    tmp = out_dir / f".{i:06d}.json.tmp"
    tmp.write_text(json.dumps(rest))
    os.replace(tmp, out_dir / f"{i:06d}.json")


@dataclass
class TaskRun:
    """Outcome of :func:`map_tasks`: results on disk in ``out_dir``, tasks that failed twice, tasks retried."""

    out_dir: Path
    n_tasks: int
    failures: dict[int, str] = field(default_factory=dict)
    retried: dict[int, str] = field(default_factory=dict)
    workers: int = 0
    _tmp: Any = None

    def result(self, i: int, arrays: Iterable[str] | None = None) -> dict[str, Any] | None:
        """Result of task ``i`` read back from disk (None when it failed twice); of its arrays only those named in
        ``arrays`` (all when None)."""
        path = self.out_dir / f"{i:06d}.json"
        if not path.is_file():
            return None
        out = json.loads(path.read_text())
        npz = path.with_suffix(".npz")
        if npz.is_file():
            with np.load(npz, allow_pickle=False) as data:
                keys = data.files if arrays is None else [k for k in arrays if k in data.files]
                out.update({k: data[k] for k in keys})
        return out

    def results(self, arrays: Iterable[str] | None = None) -> Iterator[tuple[int, dict[str, Any] | None]]:
        """``(index, result or None)`` of every task, in task order (one result in memory at a time)."""
        keep = None if arrays is None else list(arrays)
        for i in range(self.n_tasks):
            yield i, self.result(i, keep)

    def failure_lines(self) -> list[str]:
        return [f"task {i}: failed twice: {err}" for i, err in sorted(self.failures.items())]


class Executor(AbstractContextManager):
    """A dask client on a started ``LocalCluster`` or on a running cluster; reuse it for several jobs."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None,
                 memory_limit: str | float | None = "auto", connect_timeout_s: float = 20.0) -> None:
        import dask
        from distributed import Client, LocalCluster

        address = scheduler or os.environ.get(SCHEDULER_ENV) or None
        self.cluster = None
        if address:
            try:
                self.client = Client(address, timeout=f"{connect_timeout_s}s")
            except (OSError, TimeoutError) as err:
                raise ParallelError(f"cannot reach the dask scheduler at {address} ({err}); start it with "
                                    "`dask scheduler` or leave --scheduler/UAVFMU_SCHEDULER unset for local "
                                    "workers") from None
        else:
            n = workers if workers is not None else min(4, os.cpu_count() or 1)
            if not 1 <= n <= MAX_WORKERS:
                raise ValueError(f"workers = {n}: allowed 1..{MAX_WORKERS}")
            # the scheduler gives up on a task at the first worker lost under it (the retry is ours: ATTEMPTS) and
            # sends a worker one task per thread (else a task queued behind a crashing one dies with it)
            with dask.config.set(SCHEDULER_CONFIG):
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                            dashboard_address=None, memory_limit=memory_limit,
                                            silence_logs=logging.CRITICAL,
                                            # no dashboard; the scheduler's health routes on a free loopback port
                                            scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"})
            self.client = Client(self.cluster)
        self.address = address or self.cluster.scheduler_address

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def threads(self) -> int:
        """Worker threads of the cluster now (at least 1)."""
        return max(1, sum(self.client.nthreads().values()))

    def map_tasks(self, fn: Callable[[Any], dict[str, Any]], tasks: Sequence[Any], *, out_dir: Path | None = None,
                  files: Files = (), max_in_flight: int | None = None, progress: Progress = True,
                  desc: str = "tasks") -> TaskRun:
        """See the module docstring and :func:`map_tasks`."""
        from distributed import as_completed
        from tqdm import tqdm

        if len(tasks) > MAX_TASKS:
            raise ValueError(f"{len(tasks)} tasks: allowed at most {MAX_TASKS:,}")
        run = _new_run(out_dir, len(tasks), self.threads())
        per_task = files if callable(files) else (lambda _task, common=list(files): common)
        limit = max(1, max_in_flight or run.workers)
        attempt: dict[int, int] = {}

        def submit(i: int, avoid: tuple[str | None, Any] | None = None) -> None:
            """Submit task ``i``; a retry goes to a worker other than ``avoid`` (address, name) when there is one."""
            attempt[i] = attempt.get(i, 0) + 1
            others = retry_workers(self.client.scheduler_info()["workers"], avoid) if avoid else []
            where = {"workers": others, "allow_other_workers": True} if others else {}
            shipped, blobs = _ship(per_task(tasks[i]))
            fut = self.client.submit(_run_task, fn, tasks[i], shipped, blobs, pure=False, **where,
                                     key=f"{desc}-{i}-{attempt[i]}-{os.getpid()}-{id(run)}")
            index[fut.key] = i
            queue.add(fut)

        todo, queue, index, done = iter(range(len(tasks))), as_completed(), {}, 0
        for i in itertools.islice(todo, limit):
            submit(i)
        with tqdm(total=len(tasks), desc=desc, disable=progress is not True, unit="task") as bar:
            for fut in queue:
                i = index.pop(fut.key)
                error, worker = self._outcome(fut, run, i)
                fut.release()
                if error is not None and attempt[i] < ATTEMPTS:
                    run.retried[i] = error
                    submit(i, avoid=worker)
                    continue
                if error is not None:
                    run.failures[i] = error
                done += 1
                bar.update(1)
                if callable(progress):
                    progress(done, len(tasks))
                for j in itertools.islice(todo, 1):
                    submit(j)
        return run

    def _outcome(self, fut: Any, run: TaskRun, i: int) -> tuple[str | None, tuple[str | None, Any] | None]:
        """Write a finished task's result to disk; or (error text, (address, name) of the worker to avoid) when it
        failed."""
        try:
            out = fut.result()
        except Exception as err:  # KilledWorker (the worker died under the task), CancelledError, ...
            worker = getattr(err, "last_worker", None)
            last = getattr(worker, "address", None)
            what = f"the worker process ({last}) died during the task" if last else str(err)
            return f"{type(err).__name__}: {what}", (last, getattr(worker, "name", None))
        if "__error__" in out:
            who = self.client.who_has(fut).get(fut.key) or ()
            address = who[0] if who else None
            name = self.client.scheduler_info()["workers"].get(address, {}).get("name") if address else None
            return str(out["__error__"]), (address, name)
        _write(run.out_dir, i, out)
        return None, None


def retry_workers(workers: Mapping[str, Mapping[str, Any]], avoid: tuple[str | None, Any]) -> list[str]:
    """Addresses of the ``workers`` (the scheduler's ``{address: info}``) a retry may go to: not the ``avoid``
    (address, name) worker the task failed on, nor one of the same name (a nanny's restart of a dead worker)."""
    address, name = avoid
    return [w for w, info in workers.items() if w != address and (name is None or info.get("name") != name)]


def _ship(files: Iterable[str | Path | None]) -> tuple[dict[str, tuple[str, str]], dict[str, bytes]]:
    """A task's existing files as bytes: ``{client path: (sha256, name)}``, ``{sha256: bytes}``. They travel with
    the task, not as scattered data: a task that depends on data held by one worker is sent to that worker (no
    balancing, no queuing on the scheduler) and is lost with it. Read when the task is submitted, so the client
    holds the bytes of the tasks in flight only."""
    shipped: dict[str, tuple[str, str]] = {}
    blobs: dict[str, bytes] = {}
    for f in dict.fromkeys(str(p) for p in files if p is not None):
        path = Path(f)
        if not path.is_file():
            continue  # the task reports the missing file by its own path
        data = path.read_bytes()
        sha = hashlib.sha256(data).hexdigest()
        blobs.setdefault(sha, data)
        shipped[f] = (sha, path.name)
    return shipped, blobs


def _new_run(out_dir: Path | None, n: int, workers: int) -> TaskRun:
    tmp = None
    if out_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="uavfmu-tasks-")
        out_dir = Path(tmp.name)
    out_dir.mkdir(parents=True, exist_ok=True)
    for stale in out_dir.glob("[0-9]" * 6 + ".*"):
        stale.unlink()
    return TaskRun(out_dir, n, workers=workers, _tmp=tmp)


def run_inline(fn: Callable[[Any], dict[str, Any]], tasks: Sequence[Any], *, out_dir: Path | None = None,
               progress: Progress = True, desc: str = "tasks") -> TaskRun:
    """:func:`map_tasks` in the calling process, one task after another: results streamed to ``out_dir``, a task
    that raises run once more, a task that fails twice listed in ``failures`` (files are read in place)."""
    from tqdm import tqdm

    if len(tasks) > MAX_TASKS:
        raise ValueError(f"{len(tasks)} tasks: allowed at most {MAX_TASKS:,}")
    run = _new_run(out_dir, len(tasks), 0)
    with tqdm(total=len(tasks), desc=desc, disable=progress is not True, unit="task") as bar:
        for i, task in enumerate(tasks):
            for attempt in range(1, ATTEMPTS + 1):
                out = _run_task(fn, task, {}, {})
                if "__error__" not in out:
                    _write(run.out_dir, i, out)
                    break
                (run.retried if attempt < ATTEMPTS else run.failures)[i] = str(out["__error__"])
            bar.update(1)
            if callable(progress):
                progress(i + 1, len(tasks))
    return run


def map_tasks(fn: Callable[[Any], dict[str, Any]], tasks: Sequence[Any], *, out_dir: Path | None = None,
              files: Files = (), scheduler: str | None = None, workers: int | None = None,
              max_in_flight: int | None = None, progress: Progress = True, desc: str = "tasks") -> TaskRun:
    """Run ``fn(task)`` for every task on a fresh :class:`Executor` (in the calling process with ``workers=0``
    and no ``scheduler``) and stream the results to ``out_dir`` (a temporary folder, kept as long as the
    returned run, when None). See the module docstring."""
    if workers == 0 and not scheduler:
        return run_inline(fn, tasks, out_dir=out_dir, progress=progress, desc=desc)
    with Executor(scheduler, workers) as ex:
        return ex.map_tasks(fn, tasks, out_dir=out_dir, files=files, max_in_flight=max_in_flight,
                            progress=progress, desc=desc)

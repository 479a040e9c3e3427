"""Thrust cross-validation folds on ``identification.common.parallel``: in this process (the default,
no
cluster start-up) and on local dask workers, bit for bit the serial fold loop."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from identification.common.parallel import map_tasks
from identification.thrust.workflow import (
    FoldResult,
    ThrustConfig,
    base_spec,
    fold_results,
    load_flight,
    outer_folds,
    score_fold,
)
from tests.identification.thrust.test_thrust_workflow import VoltLog, _cfg, fake_logs  # noqa: F401  (fixture)


def _same(a: FoldResult, b: FoldResult) -> None:
    assert (a.held_out, a.n_samples, a.model, a.baselines, a.spec, a.period_s) == \
        (b.held_out, b.n_samples, b.model, b.baselines, b.spec, b.period_s)
    assert a.calibration_scale == b.calibration_scale
    assert list(a.series) == list(b.series)
    for k in a.series:
        np.testing.assert_array_equal(a.series[k], b.series[k])


def _setup(fake_logs: dict[str, VoltLog], **kw: object) -> tuple:  # noqa: F811
    fake_logs["a"] = VoltLog(1.3, 12.4, 10.8, seed=1, voltage=False, duration_s=40.0)
    fake_logs["b"] = VoltLog(1.0, 11.6, 10.2, seed=2, voltage=False, duration_s=40.0)
    cfg: ThrustConfig = _cfg([("a", 1.3), ("b", 1.0)], epochs=5, n_mfs=2, **kw)
    flights = [load_flight(s, cfg) for s in cfg.flights]
    base, _ = base_spec(flights, cfg)
    return cfg, base, [f.model_data(base.voltage) for f in flights]


def test_folds_in_process_equal_the_serial_loop_bit_for_bit(fake_logs: dict[str, VoltLog]) -> None:  # noqa: F811
    cfg, base, data = _setup(fake_logs)
    serial = [score_fold(n, tr, te, base, cfg, True) for n, tr, te in outer_folds(data, cfg.n_folds_single)]
    inline = fold_results(data, base, cfg, True)  # workers None, no scheduler: in this process
    assert [f.held_out for f in inline] == ["a", "b"]
    for a, b in zip(serial, inline, strict=True):
        _same(a, b)


def test_folds_on_two_dask_workers_equal_the_in_process_run(fake_logs: dict[str, VoltLog]) -> None:  # noqa: F811
    cfg, base, data = _setup(fake_logs)
    inline = fold_results(data, base, cfg, True)
    remote = fold_results(data, base, dataclasses.replace(cfg, workers=2), True)
    for a, b in zip(inline, remote, strict=True):
        _same(a, b)


def _flaky(task: dict) -> dict:
    if task["i"] == 1 and not Path(task["mark"]).exists():
        Path(task["mark"]).write_text("failed once")
        raise RuntimeError("first attempt fails")
    if task["i"] == 2:
        raise ValueError("always fails")
    return {"i": task["i"], "x": np.arange(task["i"] + 1.0)}


def test_in_process_mode_streams_results_retries_once_and_lists_failures(tmp_path: Path) -> None:
    mark = str(tmp_path / "mark")
    seen: list[tuple[int, int]] = []
    run = map_tasks(_flaky, [{"i": i, "mark": mark} for i in range(4)], workers=0, out_dir=tmp_path / "out",
                    progress=lambda d, n: seen.append((d, n)))
    assert run.workers == 0 and seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert set(run.retried) == {1, 2} and "first attempt fails" in run.retried[1]
    assert list(run.failures) == [2] and "ValueError: always fails" in run.failures[2]
    got = dict(run.results())
    assert got[2] is None and (tmp_path / "out" / "000003.npz").is_file()
    np.testing.assert_array_equal(got[3]["x"], [0.0, 1.0, 2.0, 3.0])


def test_a_failing_fold_names_the_held_out_flight(fake_logs: dict[str, VoltLog],  # noqa: F811
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    import identification.thrust.workflow as tw
    from identification.thrust.dataset import ThrustDataError

    cfg, base, data = _setup(fake_logs)
    monkeypatch.setattr(tw, "score_fold", lambda n, *a: (_ for _ in ()).throw(ValueError(f"bad {n}")))
    with pytest.raises(ThrustDataError, match="fold without a: ValueError: bad a"):
        fold_results(data, base, cfg, True)


def test_aero_bootstrap_repeats_are_the_same_bits_in_process_on_workers_and_serially() -> None:
    from identification.estimation.oem import BOOTSTRAP_CHUNK, bootstrap_repeats, bootstrap_task

    rng = np.random.default_rng(5)
    m, n = 7, 3
    J = rng.standard_normal((m, 20, n))
    A = np.einsum("sia,sib->sab", J, J)
    g = np.einsum("sia,si->sa", J, rng.standard_normal((m, 20)))
    P, gp = np.eye(n) * 1e-3, np.zeros(n)
    inline = bootstrap_repeats(A, g, P, gp, 120, seed=3)
    assert inline.shape == (120, n)
    serial = np.concatenate([bootstrap_task({"A": A, "g": g, "P": P, "gp": gp, "seed": 3, "index": i,
                                             "count": min(BOOTSTRAP_CHUNK, 120 - f)})["reps"]
                             for i, f in enumerate(range(0, 120, BOOTSTRAP_CHUNK))])
    np.testing.assert_array_equal(inline, serial)
    np.testing.assert_array_equal(inline, bootstrap_repeats(A, g, P, gp, 120, seed=3, workers=2))
    assert not np.array_equal(inline, bootstrap_repeats(A, g, P, gp, 120, seed=4))  # the seed matters

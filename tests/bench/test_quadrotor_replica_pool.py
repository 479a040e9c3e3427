"""The quadrotor replica bench judges widths in each draw's own interval units and pools saved runs."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))  # the bench imports its sibling scripts
import quadrotor_replica as bench


def _save(path: Path, rng: np.random.Generator, draws: int, width_factor: float) -> Path:
    """Draws with truths and interval scales spread like the replica's (a factor of 4), errors normal with the
    std the interval claims; the saved half-widths are ``width_factor`` times the right ones."""
    rows = {}
    for n in bench.CHECKED:
        truth = rng.uniform(0.6, 1.4, draws)
        sd = truth * np.exp(rng.uniform(np.log(0.0005), np.log(0.002), draws))
        est = truth + rng.normal(0.0, sd)
        rows[n] = np.column_stack([truth, est, width_factor * 1.96 * sd]).tolist()
    path.write_text(json.dumps({"rows": rows, "misses": []}))
    return path


def test_right_intervals_of_unlike_draws_are_not_called_wide(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(3)
    files = [_save(tmp_path / f"run{k}.json", rng, 40, 1.0) for k in range(2)]
    assert bench.main(["--pool", *map(str, files)]) == 0
    out = capsys.readouterr().out
    assert "80 draws of 2 runs pooled" in out and "MISSED" not in out


def test_too_narrow_intervals_are_a_shown_miss(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(4)
    files = [_save(tmp_path / f"run{k}.json", rng, 40, 0.5) for k in range(2)]
    assert bench.main(["--pool", *map(str, files)]) == 1
    assert "MISS" in capsys.readouterr().out


def test_a_file_that_is_not_a_saved_run_is_named(tmp_path: Path, capsys) -> None:
    import pytest

    bad = tmp_path / "bad.json"
    bad.write_text('{"rows": {}}')
    with pytest.raises(SystemExit) as stop:
        bench.main(["--pool", str(bad)])
    assert stop.value.code == 2 and f"--pool {bad}: not a --save file" in capsys.readouterr().err


def test_pooled_runs_count_the_thrust_slope_checks_shown(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(5)
    files = [_save(tmp_path / f"run{k}.json", rng, 40, 1.0) for k in range(2)]
    got = json.loads(files[0].read_text())
    files[0].write_text(json.dumps({**got, "slope_z": [0.5, -3.2, 1.1] + [0.0] * 37}))
    bench.main(["--pool", *map(str, files)])
    assert "shown in 1 of 40 draws with it recorded" in capsys.readouterr().out

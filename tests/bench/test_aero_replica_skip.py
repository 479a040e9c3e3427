"""The fixed-wing replica bench leaves out a drawn truth that cannot be flown instead of stopping the run, and judges
the draws of several saved runs together as one run would."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))  # the bench imports its sibling scripts
import aero_replica as bench


def test_a_truth_that_diverges_is_skipped_and_the_other_draws_are_judged(monkeypatch: pytest.MonkeyPatch,
                                                                        capsys: pytest.CaptureFixture[str],
                                                                        tmp_path: Path) -> None:
    def run_draw(seed: int, *args: object) -> tuple[bool, str, dict[str, tuple[float, float, bool, float, float]]]:
        """Draws whose every interval covers with a half-width of 1.96 errors: coverage and width met."""
        if seed == 2:
            raise bench.TruthDivergesError("the truth model diverges in segment 1:2")
        return True, f"draw {seed}", {n: ((-1.0) ** seed, 1.96, False, 1.96, 1.96) for n in bench.PRIMARY}

    log = tmp_path / "excitation.BIN"
    log.write_bytes(b"")
    monkeypatch.setattr(bench, "LOG", log)
    monkeypatch.setattr(bench, "run_draw", run_draw)
    monkeypatch.setattr(sys, "argv", ["aero_replica.py", "--draws", "6"])
    status = bench.main()
    out = capsys.readouterr().out
    assert "draw 2: skipped, the truth model diverges in segment 1:2" in out
    assert "over 5 draws (1 skipped: the truth diverges)" in out
    assert "5 of 5 draws: every primary derivative within 10 %" in out
    assert status == 0 and "-> PASS" in out  # the skipped draw fails nothing


def test_a_run_whose_every_truth_diverges_judges_nothing_and_fails(monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str],
                                                                  tmp_path: Path) -> None:
    def run_draw(seed: int, *args: object) -> None:
        raise bench.TruthDivergesError(f"the truth model diverges in segment {seed}:9")

    log = tmp_path / "excitation.BIN"
    log.write_bytes(b"")
    monkeypatch.setattr(bench, "LOG", log)
    monkeypatch.setattr(bench, "run_draw", run_draw)
    monkeypatch.setattr(sys, "argv", ["aero_replica.py", "--draws", "2"])
    assert bench.main() == 1
    assert "every drawn truth diverges (draws 0, 1): nothing judged" in capsys.readouterr().out


def _fake_draws(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, scale: float) -> None:
    """Draws whose errors are +-1 and half-widths ``scale`` (the log present, no identification run)."""
    def run_draw(seed: int, *args: object) -> tuple[bool, str, dict[str, tuple[float, float, bool, float, float]]]:
        return True, f"draw {seed}", {n: ((-1.0) ** seed, scale, False, scale, scale) for n in bench.PRIMARY}

    log = tmp_path / "excitation.BIN"
    log.write_bytes(b"")
    monkeypatch.setattr(bench, "LOG", log)
    monkeypatch.setattr(bench, "run_draw", run_draw)


def test_saved_runs_pool_into_one_verdict(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                          tmp_path: Path) -> None:
    _fake_draws(monkeypatch, tmp_path, 3.0)  # every interval 3 errors wide: covers, width past 2
    runs = [tmp_path / "a.json", tmp_path / "b.json"]
    assert bench.main(["--draws", "3", "--seed", "0", "--save", str(runs[0])]) == 0  # 3 draws cannot show it
    assert "unresolved" in capsys.readouterr().out
    assert bench.main(["--draws", "3", "--seed", "10", "--save", str(runs[1])]) == 0
    capsys.readouterr()
    assert bench.main(["--draws", "6", "--seed", "0"]) == 0
    single = capsys.readouterr().out.split("targets:")[1]
    monkeypatch.setattr(bench, "run_draw", None)  # pooling runs no draw
    assert bench.main(["--pool", *map(str, runs)]) == 0
    out = capsys.readouterr().out
    assert "over 6 draws of 2 runs pooled (truths factor" in out
    assert out.split("targets:")[1] == single  # the same figures as one run of those draws
    _fake_draws(monkeypatch, tmp_path, 3.0)
    assert bench.main(["--draws", "30", "--seed", "100"]) == 1  # more draws resolve it: a miss
    assert "MISS" in capsys.readouterr().out


def test_pooling_refuses_unlike_runs_and_a_draw_twice(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    _fake_draws(monkeypatch, tmp_path, 1.96)
    a, b, c = tmp_path / "a.json", tmp_path / "b.json", tmp_path / "c.json"
    assert bench.main(["--draws", "2", "--seed", "0", "--save", str(a)]) == 0
    assert bench.main(["--draws", "2", "--seed", "1", "--save", str(b)]) == 0
    assert bench.main(["--draws", "2", "--seed", "5", "--fixed-spread", "zeros", "--save", str(c)]) == 0
    capsys.readouterr()
    other = tmp_path / "other.json"
    other.write_text('{"rows": {}, "misses": []}')
    for files, message in (([a, b], f"--pool {b}: draw 1 is in {a} as well: a draw pooled twice"),
                           ([a, c], f"--pool {c}: settings fixed_spread='zeros' differ from {a}'s "
                                    "(fixed_spread='factor')"),
                           ([a, other], f"--pool {other}: field 'bench' is None, not 'aero_replica'")):
        with pytest.raises(SystemExit) as stop:
            bench.main(["--pool", *map(str, files)])
        assert stop.value.code == 2 and message in capsys.readouterr().err


def test_a_save_path_that_cannot_be_written_is_named_before_any_draw(monkeypatch: pytest.MonkeyPatch,
                                                                     capsys: pytest.CaptureFixture[str],
                                                                     tmp_path: Path) -> None:
    _fake_draws(monkeypatch, tmp_path, 1.96)
    monkeypatch.setattr(bench, "run_draw", None)  # no draw may run
    target = tmp_path / "no" / "such" / "folder" / "run.json"
    with pytest.raises(SystemExit) as stop:
        bench.main(["--draws", "2", "--save", str(target)])
    assert stop.value.code == 2 and f"--save {target}: cannot be written" in capsys.readouterr().err

"""The fixed-wing replica bench leaves out a drawn truth that cannot be flown instead of stopping the run."""

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

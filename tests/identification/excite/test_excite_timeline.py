"""The manoeuvre timeline schema: reads the flown excitation timeline and refuses bad ones with file and field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fmu_models.config import ConfigError
from identification.logs.timeline import load_timeline
from tests.conftest import shared_data


def _minimal(**block: object) -> dict:
    b = {"index": 1, "axis": "aileron", "start_s": 0.0, "excitation_start_s": 1.0, "end_s": 5.0}
    b.update(block)
    return {"time_base": "seconds since script start", "blocks": [b]}


def test_reads_the_flown_excitation_timeline() -> None:
    tl = load_timeline(shared_data("fixed_wing", "arduplane_sitl_fmu_excitation.timeline.json"))
    assert len(tl.blocks) == 10
    assert {b.axis for b in tl.blocks} == {"aileron", "elevator", "rudder", "throttle"}
    assert [b.index for b in tl.blocks_for("rudder")] == [3, 6, 9]
    first = tl.blocks[0]
    assert first.start_s <= first.excitation_start_s < first.end_s
    assert first.pulse_unit_s == pytest.approx(0.4)
    assert tl.log_first_sample_s == pytest.approx(31.364949)
    assert first.model_extra["rep"] == 1  # undeclared keys are kept, not dropped


def test_multi_block_lists_its_axes(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    path.write_text(json.dumps(_minimal(axis="multi", axes=["aileron", "rudder"])))
    tl = load_timeline(path)
    assert tl.blocks[0].excited_axes == ("aileron", "rudder")
    assert tl.blocks_for("rudder") == tl.blocks and tl.blocks_for("elevator") == []


@pytest.mark.parametrize("block, field", [({"axis": "roll"}, "blocks.0.axis"),
                                          ({"end_s": 0.5}, "excitation_start_s < end_s"),
                                          ({"start_s": "0"}, "blocks.0.start_s"),
                                          ({"pulse_unit_s": -1.0}, "blocks.0.pulse_unit_s")])
def test_bad_timeline_names_file_and_field(tmp_path: Path, block: dict, field: str) -> None:
    path = tmp_path / "bad.timeline.json"
    path.write_text(json.dumps(_minimal(**block)))
    with pytest.raises(ConfigError) as err:
        load_timeline(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_missing_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="file not found"):
        load_timeline(tmp_path / "none.json")


def test_shifted_moves_every_block(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    path.write_text(json.dumps(_minimal()))
    tl = load_timeline(path).shifted(100.0, "seconds since boot")
    b = tl.blocks[0]
    assert (b.start_s, b.excitation_start_s, b.end_s) == (100.0, 101.0, 105.0)
    assert tl.time_base == "seconds since boot"


def test_segment_chooser_reads_through_the_schema(tmp_path: Path) -> None:
    """``identify aero``'s segment chooser uses this schema only: a bad block is a SegmentError naming file and
    field; ``log_span_s`` stands in for a missing ``log_first_sample_s``."""
    from identification.aero.model import SegmentError
    from identification.aero.segments import load_timeline_blocks

    bad = tmp_path / "bad.timeline.json"
    bad.write_text(json.dumps(_minimal(end_s=0.5)))
    with pytest.raises(SegmentError, match=r"(?s)bad\.timeline\.json.*blocks\.0"):
        load_timeline_blocks(bad)
    good = tmp_path / "good.timeline.json"
    good.write_text(json.dumps({**_minimal(), "log_span_s": [12.5, 80.0]}))
    tl = load_timeline_blocks(good)
    assert tl.log_start_s == pytest.approx(12.5) and tl.blocks[0].end_s == pytest.approx(5.0)

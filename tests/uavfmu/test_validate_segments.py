"""``uavfmu validate --segments/--segments-from``: parsing and the range check of the spans."""

from __future__ import annotations

import argparse
import json

import pytest

from identification.validation.replay import ValidationInputError, check_options
from uavfmu.commands.validate import _segments


def test_segments_from_metrics_and_command_line(tmp_path):
    metrics = tmp_path / "q.metrics.json"
    metrics.write_text(json.dumps({"held_out_segments": ["10:10.5", "10.5:11"]}))
    args = argparse.Namespace(segments="1:2", segments_from=metrics)
    assert _segments(args) == [(1.0, 2.0), (10.0, 10.5), (10.5, 11.0)]
    assert _segments(argparse.Namespace(segments=None, segments_from=None)) is None
    metrics.write_text(json.dumps({"other": 1}))
    with pytest.raises(ValueError, match="held_out_segments"):
        _segments(args)
    with pytest.raises(ValueError, match="not t0:t1"):
        _segments(argparse.Namespace(segments="1-2", segments_from=None))


def test_segments_must_be_ordered_and_bounded():
    assert check_options(segments_s=[(1.0, 2.0)]).segments_s == [(1.0, 2.0)]
    with pytest.raises(ValidationInputError, match="t0 < t1"):
        check_options(segments_s=[(2.0, 1.0)])
    with pytest.raises(ValidationInputError, match="segments"):
        check_options(segments_s=[(-1.0, 1.0)])

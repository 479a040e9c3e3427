"""Time spans given as text (``--segments t0:t1,...``): one parser for every command that takes them."""

from __future__ import annotations

import pytest

from identification.logs.timeline import SpanError, parse_spans


def test_spans_parse_from_text_and_from_split_items() -> None:
    assert parse_spans("1:2, 3.5:4") == [(1.0, 2.0), (3.5, 4.0)]
    assert parse_spans(["1:2", "", " 3:5 "]) == [(1.0, 2.0), (3.0, 5.0)]
    assert parse_spans("") == []


@pytest.mark.parametrize("text, words", [("1-2", "is not t0:t1"), ("2:1", "needs 0 <= t0 < t1"),
                                         ("-1:2", "needs 0 <= t0 < t1"), ("1:nan", "needs 0 <= t0 < t1"),
                                         ("1:2:3", "is not t0:t1")])
def test_a_bad_span_is_refused_naming_the_option_and_the_item(text: str, words: str) -> None:
    with pytest.raises(SpanError) as err:
        parse_spans(f"0:1,{text}", "--held-out")
    assert "--held-out" in str(err.value) and repr(text) in str(err.value) and words in str(err.value)

"""The ingest body's JSON, read by jiter for speed, is read exactly as the standard library reads it: the same
document for every JSON text, a key given twice refused at any depth, and whatever either refuses refused with
the standard library's words (the API's refusals are unchanged)."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from segb_server.backend.services.errors import InvalidPayload
from segb_server.backend.services.ingest.payloads import json_document

SCALARS = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text()
VALUES = st.recursive(
    SCALARS, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
)


def standard(body: bytes) -> object:
    return json.loads(body)


@settings(max_examples=300, deadline=None)
@given(VALUES, st.booleans())
def test_every_json_text_is_read_as_the_standard_library_reads_it(value: object, ascii_only: bool) -> None:
    body = json.dumps(value, ensure_ascii=ascii_only).encode()
    assert json_document(body) == standard(body)


@pytest.mark.parametrize(
    "body",
    [
        b'{"ttl_content": "a", "ttl_content": "b"}',
        b'{"ttl_content": "a", "user": {"x": 1, "x": 2}}',
        b'[{"k": 1, "k": 1}]',
    ],
)
def test_a_key_given_twice_at_any_depth_is_refused_naming_it(body: bytes) -> None:
    with pytest.raises(InvalidPayload, match="more than once"):
        json_document(body)


@pytest.mark.parametrize(
    "body",
    [b"{nope", b'{"a": 1,}', b'{"a": 1} extra', b'{"a": "\x01"}', b'{"a": 01}', b"\xff\xfe", b'{"a": "\\x41"}'],
)
def test_what_is_not_json_is_refused_by_the_standard_library_s_words(body: bytes) -> None:
    with pytest.raises(ValueError) as refused:
        json_document(body)
    with pytest.raises(ValueError) as expected:
        standard(body)
    assert str(refused.value) == str(expected.value)


def test_what_jiter_refuses_but_json_reads_is_still_read() -> None:
    """A lone surrogate (refused later, naming its field), UTF-16, a byte order mark, NaN: as before."""
    assert json_document(b'{"user": "\\ud800"}') == {"user": "\ud800"}
    assert json_document('{"user": "é"}'.encode("utf-16")) == {"user": "é"}
    assert json_document(b'\xef\xbb\xbf{"user": "bom"}') == {"user": "bom"}
    assert math.isnan(json_document(b'{"a": NaN}')["a"])  # type: ignore[index]

"""The bench's re-publish section: its documents are the real client's whole graph, growing by one interaction a
re-publish, and its table shows each size's answer against the first size's."""

from __future__ import annotations

import json

from bench.measure import Latency
from bench.republish import Republish, documents, republish_section


def test_each_republish_is_the_whole_graph_one_interaction_larger() -> None:
    small, large = documents((2, 4), repeats=2)

    texts = [json.loads(body)["ttl_content"] for body in (small.history, *small.republished, large.history)]
    assert (small.interactions, large.interactions) == (2, 4)
    assert [len(text) for text in texts] == sorted(len(text) for text in texts)
    assert all(text.startswith("@prefix") for text in texts)
    assert texts[0].split("\n\n")[1] in texts[-1]  # a block sent before is sent again, byte for byte


def test_the_table_gives_each_size_its_ratio_to_the_first() -> None:
    def run(interactions: int, ms: float) -> Republish:
        return Republish(interactions, interactions * 130, 1.0, Latency.of([ms / 1000] * 3),
                         Latency.of([ms / 2000] * 3), ms * 10, 5.0, 1.0)  # fmt: skip

    lines = republish_section({"embedded": [run(100, 10), run(1000, 15)]})

    rows = [line for line in lines if line.startswith("| embedded")]
    assert [row.split(" | ")[5] for row in rows] == ["1.00", "1.50"]
    assert republish_section({}) == []

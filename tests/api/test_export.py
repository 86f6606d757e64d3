"""Exports of a graph larger than one batch, several at once, on the embedded store: each answer is whole.
The export reads the store a batch at a time while the server writes the answer, from whichever worker
thread is free; pyoxigraph's iterators must stay on the thread that made them."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest
from pyoxigraph import RdfFormat, parse

from segb_server.backend.api.app import create_app
from segb_server.backend.services.graph.export import BATCH_TRIPLES
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.in_process import InProcess
from tests.support.settle import settle

TRIPLES = BATCH_TRIPLES * 3 + 17


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[httpx.Client]:
    root: Path = tmp_path_factory.mktemp("export")
    store = OxigraphStore("http://amor-segb/events", root / "oxigraph")
    # An export streams the store: the audit rules (an empty folder of them), which would first check every one of
    # these 30,000 subjects, are not what is tested here.
    settings = make_settings(store="oxigraph", data_dir=root, rules_dir=root / "no-rules")
    with InProcess(create_app(settings, store=store)) as live:
        lines = "".join(f'<https://e.org/s{i}> <https://e.org/p> "v{i}" .\n' for i in range(TRIPLES))
        answer = live.post("/ttl", content=lines, headers={"Content-Type": "application/n-triples"})
        assert answer.status_code == 201, answer.text
        settle(live.client)
        yield live.client
    store.close()


@pytest.mark.parametrize("media", [pytest.param("application/n-triples", marks=pytest.mark.slow), "text/turtle"])
def test_concurrent_exports_of_several_batches_are_each_whole(server: httpx.Client, media: str) -> None:
    def export(_: int) -> tuple[int, int]:
        answer = server.get("/events", headers={"Accept": media})
        fmt = RdfFormat.N_TRIPLES if media == "application/n-triples" else RdfFormat.TURTLE
        return answer.status_code, sum(1 for _ in parse(answer.content, fmt)) if answer.status_code == 200 else -1

    with ThreadPoolExecutor(6) as pool:
        answers = list(pool.map(export, range(12)))
    assert answers == [(200, TRIPLES)] * 12
    assert export(0) == (200, TRIPLES)  # and the server still answers afterwards


@pytest.mark.parametrize("form", ["store", "received"])
def test_a_turtle_export_of_several_batches_declares_each_prefix_once(server: httpx.Client, form: str) -> None:
    answer = server.get("/events", params={"form": form}, headers={"Accept": "text/turtle"})
    assert answer.status_code == 200
    declared = [line.split()[1] for line in answer.text.splitlines() if line.startswith("@prefix")]
    assert "schema:" in declared and "prov:" in declared
    assert len(declared) == len(set(declared)), sorted(declared)
    assert sum(1 for _ in parse(answer.content, RdfFormat.TURTLE)) == TRIPLES

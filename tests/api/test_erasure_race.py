"""An erasure and the posts that arrive while it finds what to erase: a message of the person's recorded after
the rule ran (so the rule never saw it) is erased too, not left behind with its text; when such posts keep
arriving the erasure is refused with nothing recorded, rather than erase only part of what is theirs."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.services.people import erasure
from segb_server.backend.services.writing.journal import Journal, PostEntry, triple_digest
from segb_server.backend.state.sqlite import SqliteDatabase
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.people import INES_SAYS, care_home
from tests.support.settle import settle

SCHEMA = "http://schema.org/"
PROV = "http://www.w3.org/ns/prov#"


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[str, str]]:
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path / "data"))) as server:
        visit = care_home()
        visit.publish_steps(server.url)
        yield server.url, str(visit.iris["ines"])


def post_her_message(url: str, ines: str, number: int) -> str:
    """A message she sent, posted as a robot would: its text links to nothing but the message."""
    text = f"Said while being erased, number {number}"
    message = f"<https://example.org/race/message_{number}>"
    lines = [
        f"{message} <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <{SCHEMA}Message> .",
        f"{message} <{SCHEMA}sender> <{ines}> .",
        f"{message} <{PROV}wasAttributedTo> <{ines}> .",
        f'{message} <{SCHEMA}text> "{text}"@en .',
    ]
    answer = httpx.post(f"{url}/ttl", content="\n".join(lines), headers={"Content-Type": "application/n-triples"})
    assert answer.status_code == 201, answer.text
    return text


def race_the_rule(monkeypatch: pytest.MonkeyPatch, url: str, ines: str, races: int) -> list[str]:
    """After each of the rule's first `races` runs, before the erasure is recorded, she says something more."""
    said: list[str] = []
    found = erasure.ErasureService.resources

    def resources_then_a_post(self: erasure.ErasureService, human: str) -> list[str]:
        result = found(self, human)
        if len(said) < races:
            said.append(post_her_message(url, ines, len(said)))
        return result

    monkeypatch.setattr(erasure.ErasureService, "resources", resources_then_a_post)
    return said


def served_texts(url: str) -> str:
    events = httpx.get(f"{url}/events", headers={"Accept": "application/n-triples"}, timeout=60).text
    conversations = httpx.get(f"{url}/reports/conversations", params={"limit": 1000}, timeout=60).text
    return events + conversations


def test_a_message_recorded_while_the_rule_ran_is_erased_too(
    served: tuple[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    url, ines = served
    said = race_the_rule(monkeypatch, url, ines, races=1)
    answer = httpx.post(f"{url}/humans/erase", json={"iri": ines, "reason": "request 7"}, timeout=120)
    assert answer.status_code == 200, answer.text
    settle(url)
    assert len(said) == 1
    texts = served_texts(url)
    assert said[0] not in texts and INES_SAYS[0] not in texts
    assert httpx.get(f"{url}/ledger/verify", params={"deep": "true"}, timeout=60).json()["valid"] is True


def test_a_post_held_by_this_process_waits_for_the_erasure_instead_of_racing_it(
    served: tuple[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a first race, the rule runs with this process's posts held: a post sent then is recorded after the
    erasure (a new post, kept) instead of making the rule run again."""
    url, ines = served
    said: list[str] = []
    posting: list[threading.Thread] = []
    found = erasure.ErasureService.resources

    def resources_then_a_post(self: erasure.ErasureService, human: str) -> list[str]:
        result = found(self, human)
        if not said:  # the first run: raced
            said.append(post_her_message(url, ines, 0))
        elif len(posting) < 1:  # the second: a post sent now waits, so the erasure does not wait for it
            posting.append(threading.Thread(target=lambda: said.append(post_her_message(url, ines, 1))))
            posting[-1].start()
            time.sleep(0.5)  # long enough for it to reach the journal, were it not held
        return result

    monkeypatch.setattr(erasure.ErasureService, "resources", resources_then_a_post)
    answer = httpx.post(f"{url}/humans/erase", json={"iri": ines, "reason": "request 8"}, timeout=120)
    assert answer.status_code == 200, answer.text
    posting[0].join(timeout=60)
    erased_at = answer.json()["sequence"]
    settle(url)
    texts = served_texts(url)
    assert said[0] not in texts and said[1] in texts  # the second came after the erasure: a new post, kept
    sequences = {receipt["log_id"]: receipt["sequence"] for receipt in httpx.get(f"{url}/ledger").json()["receipts"]}
    assert max(sequences.values()) == erased_at + 1


def test_posts_of_another_process_on_every_run_of_the_rule_refuse_the_erasure_with_nothing_recorded(
    served: tuple[str, str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Another API worker's posts are not held: when one about her lands during every run, nothing is erased."""
    url, ines = served
    other_worker = Journal(SqliteDatabase(tmp_path / "data" / "journal.sqlite3"))
    said: list[str] = []
    found = erasure.ErasureService.resources

    def resources_then_another_workers_post(self: erasure.ErasureService, human: str) -> list[str]:
        result = found(self, human)
        text = f"Said to another worker, number {len(said)}"
        line = f"<https://example.org/race/other_{len(said)}> <{SCHEMA}sender> <{ines}> ."
        lines = [line[:-2], f'<https://example.org/race/other_{len(said)}> <{SCHEMA}text> "{text}"']
        entry = PostEntry(f"other-{len(said)}", "robot", None, "sha", lines, [triple_digest(x) for x in lines])
        [receipt] = other_worker.append_posts([entry])
        assert not isinstance(receipt, BaseException)
        said.append(text)
        return result

    monkeypatch.setattr(erasure.ErasureService, "resources", resources_then_another_workers_post)
    answer = httpx.post(f"{url}/humans/erase", json={"iri": ines, "reason": "request 9"}, timeout=120)
    assert answer.status_code == 409, answer.text
    assert "kept arriving" in answer.json()["detail"] and "nothing was erased" in answer.json()["detail"]
    assert len(said) == erasure.FIND_ATTEMPTS
    receipts = httpx.get(f"{url}/ledger", params={"limit": 1000}).json()["receipts"]
    assert all(receipt["action"] != "erase" for receipt in receipts)
    settle(url)
    assert INES_SAYS[0] in served_texts(url)  # nothing of hers was erased, not even in part

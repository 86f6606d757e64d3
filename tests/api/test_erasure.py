"""Erasing one person, through the API, on the embedded store on disk, with what the PyPI client publishes (two
robots, three people, shared events, cumulative re-publishes): afterwards no endpoint, export, SPARQL answer,
journal entry or file of the data directory holds her name, her sentences or her IRI; the others' reports are
unchanged; the ledger verifies with the erasure in it; her robot re-sending its whole graph does not bring her
back."""

from __future__ import annotations

import sqlite3
import threading
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import httpx
import pytest
from semantic_log_generator import ActivityKind

from segb_server.backend.api.app import create_app
from tests.conftest import make_settings, virtuoso_store
from tests.support.in_process import InProcess
from tests.support.live_server import LiveServer
from tests.support.people import INES_NAME, INES_SAYS, OTHERS_SAY, ROBOT_REPLIES, Visit, care_home, filler
from tests.support.scenarios import at
from tests.support.settle import settle
from tests.support.virtuoso import VirtuosoProcess

HUMAN_REPORTS = ("participants", "conversations", "emotion-timeline")


@dataclass
class Erased:
    url: str
    data_dir: Path
    visit: Visit
    before: dict[tuple[str, str], list[dict]]  # (report, human) → rows, for the people who stay
    answer: dict
    republished: list[dict]
    resolved_again: list[dict]

    @property
    def ines(self) -> str:
        return str(self.visit.iris["ines"])

    def needles(self) -> list[str]:
        return [INES_NAME, *INES_SAYS, *INES_SAYS_AS_COMPARED, self.ines]


# Her words as the shared contexts compare texts (lower case, no punctuation): how a context quotes them.
INES_SAYS_AS_COMPARED = ("my grandson visits on sunday", "thank you see you tomorrow")


def human_rows(url: str, visit: Visit) -> dict[tuple[str, str], list[dict]]:
    return {
        (report, who): httpx.get(f"{url}/reports/{report}", params={"human": str(visit.iris[who])}).json()["rows"]
        for report in HUMAN_REPORTS
        for who in ("juan", "carla")
    }


def overhear(visit: Visit, text: str) -> None:
    """TIAGo hears what she said without knowing who spoke: a shared event of no one, its observation and a
    message without a sender, each holding her words verbatim (as the demo's TIAGo logs what it overhears)."""
    tiago = visit.loggers["tiago"]
    event = tiago.get_shared_event_uri(event_kind="human_utterance", observed_at=at(31), text=text, modality="speech")
    listen = tiago.log_activity(
        activity_id="listen_overheard", activity_kind=ActivityKind.LISTENING, related_shared_events=[event],
        started_at=at(31),
    )  # fmt: skip
    tiago.log_message(text, message_id="overheard", language="en", generated_by_activity=listen)


@pytest.fixture(scope="module")
def erased(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Erased]:
    data_dir = tmp_path_factory.mktemp("erasure")
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=data_dir))) as server:
        visit = care_home()
        visit.publish_steps(server.url)
        overhear(visit, INES_SAYS[1])
        visit.publish(server.url, ("tiago",))
        settle(server.url)
        # A robot resolving a shared context through the server (what HTTPSharedContextResolver calls): the
        # server's own state then quotes her.
        observations = [
            {"event_kind": "human_utterance", "observed_at": "2026-03-10T09:00:05Z", "subject_uri":
             str(visit.iris["ines"]), "modality": "speech", "text": INES_SAYS[0]},
            # And one that overheard her without knowing who spoke: the context it makes quotes her, naming no one.
            {"event_kind": "human_utterance", "observed_at": "2026-03-10T09:00:21Z", "modality": "speech",
             "text": INES_SAYS[1]},
        ]  # fmt: skip
        for observation in observations:
            resolved = httpx.post(f"{server.url}/shared-context/resolve", json=observation)
            assert resolved.status_code == 200, resolved.text
        # An auditor's requests naming her IRI in their path (a receipt asked for by it, a mistyped route): the
        # server's log records each request's path.
        for path in (f"/ledger/{quote(str(visit.iris['ines']), safe='')}", f"/no-such-page/{visit.iris['ines']}"):
            assert httpx.get(f"{server.url}{path}").status_code == 404
        # An auditor's SPARQL query takes a copy of the store (users' queries run on copies).
        assert INES_NAME in httpx.post(f"{server.url}/sparql", data={"query": "SELECT * { ?s ?p ?o }"}).text
        before = human_rows(server.url, visit)
        answer = httpx.post(
            f"{server.url}/humans/erase",
            json={"iri": str(visit.iris["ines"]), "reason": "Request by the data subject, ticket 2026-117"},
            timeout=120,
        )
        assert answer.status_code == 200, answer.text
        settle(server.url)
        republished = visit.publish(server.url)  # her robots still hold everything and send it all again
        settle(server.url)
        # Their resolvers, run again over the same log, send the same observations again.
        resolved_again = [
            httpx.post(f"{server.url}/shared-context/resolve", json=observation).json() for observation in observations
        ]
        yield Erased(server.url, data_dir, visit, before, answer.json(), republished, resolved_again)


def texts_served(url: str, ines: str, visit: Visit) -> Iterator[tuple[str, str]]:
    """Every answer an auditor or an admin can get that could hold her: (what, body)."""
    get = lambda path, **params: httpx.get(f"{url}{path}", params=params, timeout=60)  # noqa: E731
    for fmt in ("turtle", "ntriples", "jsonld"):
        yield f"/events {fmt}", get("/events", format=fmt).text
        yield f"/events received {fmt}", get("/events", format=fmt, form="received").text
    for report in get("/reports").json()["reports"]:
        for fmt in ("json", "csv"):
            yield f"report {report['name']} {fmt}", get(f"/reports/{report['name']}", format=fmt).text
    yield "/findings", get("/findings", limit=1000).text
    yield "/rules", get("/rules").text
    yield "/graph", get("/graph", limit=5000).text
    yield "/graph search", get("/graph", q=INES_NAME).text
    # Asked about her IRI, the server names it back (the question); nothing more.
    yield "/resource", get("/resource", iri=ines).text.replace(ines, "")
    for item in ("a1_said", "a1_reply", "a1_read", "t1_detect"):  # what stays of her visits, explained
        yield f"/explain {item}", get("/explain", iri=str(visit.iris[item])).text
    yield "/sparql", httpx.post(f"{url}/sparql", data={"query": "SELECT * { ?s ?p ?o }"}).text
    yield "/sparql construct", httpx.post(f"{url}/sparql", data={"query": "CONSTRUCT WHERE { ?s ?p ?o }"}).text
    receipts = get("/ledger", limit=1000).json()["receipts"]
    yield "/ledger", str(receipts)
    for receipt in receipts:
        yield f"/ledger/{receipt['log_id']}", get(f"/ledger/{receipt['log_id']}").text
    yield "/logs/server", get("/logs/server", limit=2000).text
    yield "/shared-context/review/pending", get("/shared-context/review/pending").text
    export = get(f"/humans/{quote(ines, safe='')}/export", format="turtle")
    assert export.status_code == 404
    yield "export", export.text.replace(ines, "")


def test_nothing_served_holds_her_name_her_words_or_her_iri(erased: Erased) -> None:
    served = list(texts_served(erased.url, erased.ines, erased.visit))
    assert len(served) > 30
    found = [(what, needle) for what, body in served for needle in erased.needles() if needle in body]
    assert found == []
    # The robots' replies and the others' words are still there.
    events = dict(served)["/events ntriples"]
    assert all(text in events for text in (*OTHERS_SAY, *ROBOT_REPLIES))


def test_no_file_of_the_data_directory_holds_her(erased: Erased) -> None:
    for database in erased.data_dir.glob("*.sqlite3"):
        with sqlite3.connect(database) as connection:
            connection.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    files = [path for path in erased.data_dir.rglob("*") if path.is_file()]
    assert any(path.parent.name.startswith("oxigraph") for path in files) and any(
        path.name == "server.jsonl" for path in files
    )
    found = [
        (str(path), needle) for path in files for needle in erased.needles() if needle.encode() in path.read_bytes()
    ]
    assert found == []
    # The journal keeps posts compressed: what it holds is read back too.
    with sqlite3.connect(erased.data_dir / "journal.sqlite3") as journal:
        contents = [zlib.decompress(blob) for (blob,) in journal.execute("SELECT content FROM receipts") if blob]
    assert contents and not [needle for needle in erased.needles() for text in contents if needle.encode() in text]


def test_the_others_reports_are_unchanged(erased: Erased) -> None:
    assert human_rows(erased.url, erased.visit) == erased.before
    assert all(erased.before[(report, "juan")] for report in HUMAN_REPORTS)


def test_the_ledger_verifies_with_the_erasure_recorded(erased: Erased) -> None:
    verified = httpx.get(f"{erased.url}/ledger/verify", params={"deep": "true"}).json()
    assert verified["valid"] is True and verified["redactions"] == 1, verified
    entry = httpx.get(f"{erased.url}/ledger/{erased.answer['log_id']}").json()
    receipt, redaction = entry["receipt"], entry["redaction"]
    assert (receipt["action"], receipt["user"], receipt["triples_removed"]) == (
        "erase", "anonymous_user", erased.answer["triples_removed"],
    )  # fmt: skip
    assert redaction["kind"] == "human" and redaction["reason"] == "Request by the data subject, ticket 2026-117"
    assert len(redaction["receipts"]) == erased.answer["receipts_redacted"] > 1
    assert sum(item["triples_removed"] for item in redaction["receipts"]) == receipt["triples_removed"]


def test_a_cumulative_republish_does_not_bring_her_back(erased: Erased) -> None:
    withheld = [answer["triples_withheld"] for answer in erased.republished]
    assert all(count > 0 for count in withheld) and sum(withheld) == erased.answer["triples_removed"]
    assert all(answer["triples_new"] == 0 for answer in erased.republished)
    participants = httpx.get(f"{erased.url}/reports/participants").json()["rows"]
    assert {row["humanName"] for row in participants} == {"Juan", "Carla"}


def test_her_observations_sent_again_to_the_resolver_are_not_recorded(erased: Erased) -> None:
    assert [answer["withheld"] for answer in erased.resolved_again] == [True, True]
    assert all(answer["shared_context_uri"] and answer["candidate_count"] == 0 for answer in erased.resolved_again)
    stats = httpx.get(f"{erased.url}/shared-context/stats").json()
    assert stats["active_contexts"] + stats["ambiguous_contexts"] == 0, stats  # hers were the only ones


def test_an_observation_of_an_erased_person_is_withheld_only_when_it_is_one_erased(memory_api: InProcess) -> None:
    """As for triples: what an erasure removed is held back when sent again; what she says later is new data."""
    zoe = "https://example.org/h/zoe"
    posted = memory_api.client.post(
        "/ttl", content=f"<{zoe}> a <http://xmlns.com/foaf/0.1/Person> .", headers={"content-type": "text/turtle"}
    )
    assert posted.status_code == 201, posted.text
    said = {"event_kind": "human_utterance", "observed_at": "2026-03-10T09:00:05Z", "subject_uri": zoe,
            "modality": "speech", "text": "I live on Elm Street."}  # fmt: skip
    resolve = lambda body: memory_api.client.post("/shared-context/resolve", json=body).json()  # noqa: E731
    first = resolve(said)
    assert first["withheld"] is False
    erased = memory_api.client.post("/humans/erase", json={"iri": zoe, "reason": "request 7"})
    assert erased.status_code == 200, erased.text
    again = resolve(said)
    assert (again["withheld"], again["shared_context_uri"]) == (True, first["shared_context_uri"])
    later = resolve({**said, "observed_at": "2026-04-01T10:00:00Z", "text": "Good morning."})
    assert later["withheld"] is False
    stats = memory_api.client.get("/shared-context/stats").json()
    assert stats["active_contexts"] + stats["ambiguous_contexts"] == 1, stats  # the later one alone


def test_the_robots_reply_stays_without_its_link_to_her(erased: Erased) -> None:
    said = str(erased.visit.iris["a1_said"])
    about = httpx.get(f"{erased.url}/resource", params={"iri": said}).json()
    assert ROBOT_REPLIES[0] in str(about)
    assert str(erased.visit.iris["a1_heard"]) not in str(about)  # prov:wasDerivedFrom her message: gone


def test_erasing_asks_for_an_absolute_iri_and_a_reason_and_finds_someone(memory_api: InProcess) -> None:
    post = lambda body: memory_api.client.post("/humans/erase", json=body)  # noqa: E731
    assert post({"iri": "maria", "reason": "x"}).status_code == 422
    assert post({"iri": "https://example.org/h/maria", "reason": "  "}).json()["error"] == "invalid_parameter"
    missing = post({"iri": "https://example.org/h/nobody", "reason": "request 1"})
    assert (missing.status_code, missing.json()["error"]) == (404, "not_found")
    assert memory_api.client.get("/ledger").json()["total"] == 0  # nothing was recorded


def test_a_robot_or_a_message_is_not_erased_or_exported_as_a_person(memory_api: InProcess) -> None:
    robot, said, someone = "https://example.org/r/ari", "https://example.org/m/1", "https://example.org/h/zoe"
    turtle = f"""
        <{robot}> a <http://kb.openrobots.org#Robot> .
        <{said}> a <http://schema.org/Message> ; <http://schema.org/sender> <{someone}> .
    """
    posted = memory_api.client.post("/ttl", content=turtle, headers={"content-type": "text/turtle"})
    assert posted.status_code == 201, posted.text
    for iri in (robot, said):
        erased = memory_api.client.post("/humans/erase", json={"iri": iri, "reason": "a mistake"})
        assert (erased.status_code, erased.json()["error"]) == (422, "invalid_parameter"), erased.text
        assert "is not a person" in erased.json()["detail"] and iri in erased.json()["detail"]
        exported = memory_api.client.get(f"/humans/{quote(iri, safe='')}/export", params={"format": "turtle"})
        assert exported.status_code == 422, exported.text
    assert len(memory_api.client.get("/ledger").json()["receipts"]) == 1  # the post alone: nothing was erased
    # Someone a robot names without typing them may be read out (an export writes nothing), but an erasure, which
    # cannot be undone, asks for the log to type them as a person.
    exported = memory_api.client.get(f"/humans/{quote(someone, safe='')}/export", params={"format": "turtle"})
    assert exported.status_code == 200 and said in exported.text
    erased = memory_api.client.post("/humans/erase", json={"iri": someone, "reason": "request 8"})
    assert erased.status_code == 422 and "does not type" in erased.json()["detail"], erased.text


@pytest.mark.virtuoso
def test_an_erasure_on_virtuoso_removes_her_triples_in_their_received_spelling(
    virtuoso: VirtuosoProcess, tmp_path: Path
) -> None:
    """Virtuoso reads each literal of DELETE DATA as it read it on INSERT DATA ("0.8"^^xsd:float included), so the
    triples go; the journal, the reports and the re-publish behave as on the embedded store."""
    store = virtuoso_store(virtuoso)
    try:
        with LiveServer(create_app(make_settings(store="virtuoso", data_dir=tmp_path), store=store)) as server:
            visit = care_home()
            visit.publish_steps(server.url)
            overhear(visit, INES_SAYS[1])  # her words, verbatim, in a message and a shared event of no one
            visit.publish(server.url, ("tiago",))
            settle(server.url)
            before = human_rows(server.url, visit)
            ines = str(visit.iris["ines"])
            answer = httpx.post(f"{server.url}/humans/erase", json={"iri": ines, "reason": "request"}, timeout=120)
            assert answer.status_code == 200, answer.text
            settle(server.url)
            stored = httpx.get(f"{server.url}/events", params={"format": "ntriples"}).text
            assert [needle for needle in (INES_NAME, *INES_SAYS, ines) if needle in stored] == []
            assert store.count() == len(
                httpx.get(f"{server.url}/events", params={"format": "ntriples", "form": "received"}).text.splitlines()
            )
            assert human_rows(server.url, visit) == before
            assert all(answer["triples_withheld"] > 0 for answer in visit.publish(server.url))
            verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()
            assert verified["valid"] is True and verified["redactions"] == 1
    finally:
        store.clear()
        store.close()


@pytest.mark.slow  # a store big enough for the erasure to take seconds: the full tier
def test_a_post_during_an_erasure_is_answered_within_its_timeout_and_kept(tmp_path: Path) -> None:
    """While the embedded store is written anew without her (seconds at 150,000 triples), a robot's post is not
    held behind that step: it is journaled, answered within INGEST_APPLY_TIMEOUT_SECONDS (201, or 503 saying it is
    kept), and in the store once the erasure is done."""
    settings = make_settings(store="oxigraph", data_dir=tmp_path, ingest_apply_timeout_seconds=1)
    with LiveServer(create_app(settings)) as server:
        visit = care_home()
        visit.publish_steps(server.url)
        overhear(visit, INES_SAYS[1])
        visit.publish(server.url, ("tiago",))
        settle(server.url)
        others = filler(75_000)
        headers = {"Content-Type": "application/n-triples"}
        # Applying it takes longer than the 1 s this server gives a post: a 503 saying it is kept, then applied.
        assert httpx.post(f"{server.url}/ttl", content=others, headers=headers, timeout=300).status_code in (201, 503)
        settle(server.url, timeout=300)  # the audit rules check 75,000 more subjects
        erasing = threading.Thread(
            target=httpx.post,
            args=(f"{server.url}/humans/erase",),
            kwargs={"json": {"iri": str(visit.iris["ines"]), "reason": "request"}, "timeout": 300},
        )
        erasing.start()
        deadline = time.monotonic() + 60
        while httpx.get(f"{server.url}/ledger", params={"limit": 1}).json()["receipts"][0]["action"] != "erase":
            assert time.monotonic() < deadline
            time.sleep(0.01)
        began = time.monotonic()
        late = httpx.post(f"{server.url}/ttl", content=b'<https://example.org/late> <https://example.org/p> "x" .\n',
                          headers=headers, timeout=60)  # fmt: skip
        waited = time.monotonic() - began
        erasing.join(timeout=300)
        assert late.status_code in (201, 503) and waited < 5, (late.status_code, waited)
        if late.status_code == 503:
            assert "kept in the journal" in late.json()["detail"]
        settle(server.url, timeout=300)
        assert "https://example.org/late" in httpx.get(f"{server.url}/events", params={"format": "ntriples"}).text

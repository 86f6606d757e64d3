"""An erasure replaces the person's names in the texts it keeps that concern them: two robots (ARI, TIAGo) and
three people (Lucía, Carlos, Ana) logged by the PyPI client. ARI greets Lucía ("Hola Lucía, ¿qué tal?"), TIAGo
shouts her name, an activity's label and a goodbye name her (the last by her full name). After her erasure and a
checkpoint her name, in any case, is in no endpoint, page, export, SPARQL answer or file of the data directory;
each of those texts stays with the mark "[erased]" where her name was; the robots re-sending their whole graphs
bring no name back; the ledger verifies; what Carlos and Ana said is as they said it. Erasing store-wide also
redacts a text that concerns someone else."""

from __future__ import annotations

import io
import re
import sqlite3
import unicodedata
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

import httpx
import pytest
from rdflib import FOAF, Literal
from semantic_log_generator import ActivityKind

from segb_server.backend.api.app import create_app
from segb_server.ui.app import create_ui_app
from tests.cli.test_cli import segb
from tests.conftest import make_settings, virtuoso_store
from tests.support.live_server import LiveServer
from tests.support.net import free_port
from tests.support.people import Visit, conversation
from tests.support.scenarios import at, robot_logger
from tests.support.settle import settle
from tests.support.virtuoso import VirtuosoProcess

MARK = "[erased]"
GREETING = "Hola Lucía, ¿qué tal?"
SHOUT = "¡LUCÍA! Bienvenida. Luciano llegará pronto."  # Luciano is someone else: a name is matched as a word
GOODBYE = "Hasta mañana, Lucía Pérez."
LABEL = "Saludar a lucía"
REDACTED = ("Hola [erased], ¿qué tal?", "¡[erased]! Bienvenida. Luciano llegará pronto.", "Hasta mañana, [erased].",
            "Saludar a [erased]")  # fmt: skip
LUCIA_SAYS = ("Me duele la rodilla", "Buenos días a todos")
OTHERS_SAY = ("Soy Carlos, vengo los martes", "Hola, soy Ana")  # each about themselves
OTHER_REPLIES = ("En la primera planta, Carlos.", "Encantado, Ana.")
ABOUT_HER = "Vengo a ver a Lucía"  # Carlos's own words, naming her: his, so kept unless erased store-wide
# Her name as any text or file may hold it: any case, composed or not, JSON-, URL- or N-Triples-escaped.
_HER = re.compile(r"(?<!\w)(lucía|lucia\u0301|luc\\u00eda|luc%c3%ada|pérez|pe\u0301rez|p\\u00e9rez)", re.IGNORECASE)
_HER_BYTES = [form.encode() for form in ("lucía", "lucía".upper(), "pérez", "pérez".upper())] + [
    b"luc\\u00eda",
    b"luc\\u00cda",
    b"luci\xcc\x81a",
    b"luc%c3%ada",
    b"luc%c3%8da",
    b"p\\u00e9rez",
    b"p\\u00c9rez",
]


def holds_her(text: str) -> bool:
    return _HER.search(unicodedata.normalize("NFC", text)) is not None or _HER.search(text) is not None


def bytes_hold_her(data: bytes) -> bool:
    lowered = data.lower()  # ASCII only: the upper-case forms are looked for as they are
    return any(needle.lower() in lowered or needle in data for needle in _HER_BYTES)


def care_centre() -> Visit:
    """Lucía talks to ARI (greeted by name) and to TIAGo (her name shouted); ARI decides to greet her (its label
    names her) and says goodbye by her full name; Carlos talks to TIAGo and Ana to ARI, each about themselves."""
    ari, tiago = robot_logger("ari", "ARI"), robot_logger("tiago", "TIAGo")
    visit = Visit({"ari": ari, "tiago": tiago})
    iris = visit.iris
    lucia = ari.register_human("l1", first_name="Lucía")
    carlos = tiago.register_human("c1", first_name="Carlos")
    ana = ari.register_human("a1", first_name="Ana")
    iris.update(lucia=lucia, carlos=carlos, ana=ana, ari=ari.robot_uri, tiago=tiago.robot_uri)

    def models() -> None:
        iris["cnn"] = ari.register_ml_model("emotion_cnn", label="Emotion CNN", version="1.0")
        iris["tiago_cnn"] = tiago.register_ml_model("face_net", label="FaceNet", version="2.1")
        ari.graph.add((lucia, FOAF.name, Literal("Lucía Pérez")))  # her full name, as a robot may state it

    def lucia_talks_to_ari() -> None:
        said = conversation(ari, "l1", lucia, LUCIA_SAYS[0], GREETING, 5, iris["cnn"])
        iris.update({f"l1_{key}": value for key, value in said.items()})
        decide = ari.log_activity(
            activity_id="greet_l1", activity_kind=ActivityKind.DECISION, label=LABEL,
            triggered_by_entity=said["heard"], started_at=at(6),
        )  # fmt: skip
        iris["l1_decide"] = decide

    def lucia_talks_to_tiago() -> None:
        said = conversation(tiago, "l2", lucia, LUCIA_SAYS[1], SHOUT, 10, iris["tiago_cnn"])
        iris.update({f"l2_{key}": value for key, value in said.items()})

    def carlos_talks() -> None:
        said = conversation(tiago, "c1", carlos, OTHERS_SAY[0], OTHER_REPLIES[0], 15, iris["tiago_cnn"])
        iris.update({f"c1_{key}": value for key, value in said.items()})

    def ana_talks() -> None:
        said = conversation(ari, "a1", ana, OTHERS_SAY[1], OTHER_REPLIES[1], 20, iris["cnn"])
        iris.update({f"a1_{key}": value for key, value in said.items()})

    def lucia_leaves() -> None:
        said = conversation(ari, "l3", lucia, "Adiós", GOODBYE, 25, iris["cnn"])
        iris.update({f"l3_{key}": value for key, value in said.items()})

    visit.steps = [
        ("ari", models), ("ari", lucia_talks_to_ari), ("tiago", lucia_talks_to_tiago), ("tiago", carlos_talks),
        ("ari", ana_talks), ("ari", lucia_leaves),
    ]  # fmt: skip
    return visit


def carlos_names_her(visit: Visit) -> None:
    """Carlos tells TIAGo whom he comes to see: his own words, naming her."""
    said = conversation(
        visit.loggers["tiago"], "c2", visit.iris["carlos"], ABOUT_HER, "De acuerdo.", 30, visit.iris["tiago_cnn"]
    )
    visit.iris.update({f"c2_{key}": value for key, value in said.items()})


@dataclass
class Erased:
    url: str
    ui_url: str
    data_dir: Path
    visit: Visit
    preview: dict[str, Any]
    preview_page: str  # the People page's preview of her erasure
    answer: dict[str, Any]
    before: str  # /events as N-Triples before the erasure
    republished: list[dict[str, Any]]

    @property
    def lucia(self) -> str:
        return str(self.visit.iris["lucia"])


def events(url: str, **params: str) -> str:
    return httpx.get(f"{url}/events", params={"format": "ntriples", **params}, timeout=60).text


def others_lines(ntriples: str) -> set[str]:
    """The lines holding what Carlos and Ana said and what was replied to them."""
    return {line for line in ntriples.splitlines() if any(text in line for text in (*OTHERS_SAY, *OTHER_REPLIES))}


def people_page_preview(ui_url: str, iri: str) -> str:
    """*Preview erasure* on the People page, as a browser posts it (the form's CSRF token with its cookie)."""
    with httpx.Client(base_url=ui_url, timeout=60) as browser:
        form = browser.get("/people")
        token = re.search(r'name="csrf_token" value="([^"]+)"', form.text)
        assert form.status_code == 200 and token, form.text[:300]
        shown = browser.post("/people/preview", data={"csrf_token": token.group(1), "iri": iri})
        assert shown.status_code == 200, shown.text[:300]
        return shown.text


@pytest.fixture(scope="module")
def erased(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Erased]:
    data_dir = tmp_path_factory.mktemp("mentions")
    port = free_port()
    # The UI's server is made first: making one configures logging anew, which would close the API's log file.
    ui_server = LiveServer(create_ui_app(make_settings(backend_url=f"http://127.0.0.1:{port}")))
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=data_dir)), port) as server, ui_server as ui:
        visit = care_centre()
        visit.publish_steps(server.url)
        settle(server.url)
        before = events(server.url)
        assert GREETING in before and SHOUT in before and GOODBYE in before
        lucia = str(visit.iris["lucia"])
        preview = httpx.post(f"{server.url}/humans/erase", json={"iri": lucia, "dry_run": True}, timeout=60)
        assert preview.status_code == 200, preview.text
        page = people_page_preview(ui.url, lucia)
        answer = httpx.post(
            f"{server.url}/humans/erase", json={"iri": lucia, "reason": "Request by the data subject"}, timeout=120
        )
        assert answer.status_code == 200, answer.text
        settle(server.url)
        republished = visit.publish(server.url)  # each robot still holds everything and sends it all again
        settle(server.url)
        yield Erased(server.url, ui.url, data_dir, visit, preview.json(), page, answer.json(), before, republished)


def served_texts(erased: Erased) -> Iterator[tuple[str, str]]:
    """Every answer of the API an auditor or an admin can get that could hold her name: (what, body)."""
    url, iris = erased.url, erased.visit.iris

    def get(path: str, **params: str) -> httpx.Response:
        answer = httpx.get(f"{url}{path}", params=params, timeout=60)
        assert answer.status_code == 200 or path.endswith("/export"), (path, params, answer.status_code)
        return answer

    for fmt in ("turtle", "ntriples", "jsonld"):
        yield f"/events {fmt}", get("/events", format=fmt).text
        yield f"/events received {fmt}", get("/events", format=fmt, form="received").text
    for report in get("/reports").json()["reports"]:
        for fmt in ("json", "csv"):
            yield f"/reports/{report['name']} {fmt}", get(f"/reports/{report['name']}", format=fmt).text
    yield "/graph", get("/graph", limit=5000).text
    yield "/graph search", get("/graph", q="erased").text
    for robot in ("ari", "tiago"):
        for fmt in ("json", "csv", "html"):
            yield f"/timeline {robot} {fmt}", get("/timeline", robot=str(iris[robot]), format=fmt).text
    yield "/findings", get("/findings", limit=1000).text
    for item in ("l1_said", "l2_said", "l3_said", "l1_decide"):
        yield f"/explain {item}", get("/explain", iri=str(iris[item])).text
        yield f"/resource {item}", get("/resource", iri=str(iris[item])).text
    for query in ("SELECT * { ?s ?p ?o }", "CONSTRUCT WHERE { ?s ?p ?o }"):
        for accept in ("application/sparql-results+json", "text/csv", "text/turtle"):
            answer = httpx.post(f"{url}/sparql", data={"query": query}, headers={"Accept": accept}, timeout=60)
            if answer.status_code == 200:
                yield f"/sparql {query[:9]} {accept}", answer.text
    receipts = get("/ledger", limit=1000).json()["receipts"]
    yield "/ledger", str(receipts)
    for receipt in receipts:
        yield f"/ledger/{receipt['log_id']}", get(f"/ledger/{receipt['log_id']}").text
    yield "/logs/server", get("/logs/server", limit=2000).text
    for who in ("carlos", "ana"):
        for fmt in ("turtle", "html"):
            yield f"export {who} {fmt}", get(f"/humans/{quote(str(iris[who]), safe='')}/export", format=fmt).text
    export = get(f"/humans/{quote(erased.lucia, safe='')}/export", format="turtle")
    assert export.status_code == 404
    yield "export lucía", export.text
    bundle = get("/evidence", robot=str(iris["ari"]))
    assert bundle.status_code == 200, bundle.text
    with zipfile.ZipFile(io.BytesIO(bundle.content)) as archive:
        for name in archive.namelist():
            yield f"/evidence {name}", archive.read(name).decode("utf-8", "replace")


def pages(erased: Erased) -> Iterator[tuple[str, str]]:
    """The web UI's pages that could tell her name."""
    iris = erased.visit.iris

    def get(path: str, **params: str) -> httpx.Response:
        page = httpx.get(f"{erased.ui_url}{path}", params=params, timeout=60, follow_redirects=True)
        assert page.status_code == 200, (path, page.status_code)
        return page

    for path in ("/", "/reports", "/people", "/ledger", "/findings", "/kg-graph", "/kg-graph/data", "/logs"):
        yield path, get(path).text
    for report in httpx.get(f"{erased.url}/reports").json()["reports"]:
        yield f"/reports/{report['name']}", get(f"/reports/{report['name']}").text
    for robot in ("ari", "tiago"):
        yield f"/timeline {robot}", get("/timeline", robot=str(iris[robot])).text
        yield f"/timeline/data {robot}", get("/timeline/data", robot=str(iris[robot])).text
    for item in ("l1_said", "l3_said"):
        yield f"/explain {item}", get("/explain", iri=str(iris[item])).text
    yield "/query", get("/query", query="SELECT ?s ?p ?o WHERE { ?s ?p ?o }").text


def test_the_preview_counts_the_texts_whose_names_would_be_redacted(erased: Erased) -> None:
    assert erased.preview["dry_run"] is True and erased.preview["mentions"] == 4, erased.preview
    shown = re.search(r'<p id="erase-preview-mentions">([^<]*)</p>', erased.preview_page)
    assert shown and shown.group(1).startswith("4 texts that concern them"), erased.preview_page[-2000:]
    assert erased.answer["mentions_redacted"] == 4, erased.answer
    assert erased.answer["name_still_mentioned"] == 0


def test_her_name_is_in_no_endpoint_export_or_sparql_answer(erased: Erased) -> None:
    served = list(served_texts(erased))
    assert len(served) > 60
    assert [what for what, body in served if holds_her(body)] == []
    assert not holds_her("Luciano") and holds_her("LUCÍA") and holds_her("luc\\u00eda")  # the test's own reading


def test_her_name_is_in_no_page(erased: Erased) -> None:
    shown = list(pages(erased))
    assert [what for what, body in shown if not body] == []
    assert [what for what, body in shown if holds_her(body)] == []
    assert any(REDACTED[0] in body for _, body in shown)


def test_each_text_naming_her_stays_with_the_mark_where_her_name_was(erased: Erased) -> None:
    stored = events(erased.url)
    assert all(text in stored for text in REDACTED), stored
    assert all(text not in stored for text in (GREETING, SHOUT, GOODBYE, LABEL))
    said = str(erased.visit.iris["l1_said"])
    resource = httpx.get(f"{erased.url}/resource", params={"iri": said}).json()
    assert REDACTED[0] in str(resource)
    assert MARK in httpx.get(f"{erased.url}/reports/conversations", params={"format": "csv"}).text


def test_what_the_others_said_about_themselves_is_untouched(erased: Erased) -> None:
    after = others_lines(events(erased.url))
    assert after == others_lines(erased.before) and len(after) >= 4


def test_a_republish_of_the_old_texts_is_withheld(erased: Erased) -> None:
    assert all(answer["triples_withheld"] > 0 for answer in erased.republished)
    assert all(answer["triples_new"] == 0 for answer in erased.republished)
    stored = events(erased.url)
    assert not holds_her(stored) and all(text in stored for text in REDACTED)


def test_the_ledger_verifies_and_records_the_replacements_by_digest(erased: Erased) -> None:
    verified = httpx.get(f"{erased.url}/ledger/verify", params={"deep": "true"}).json()
    assert verified["valid"] is True and verified["redactions"] == 1, verified
    entry = httpx.get(f"{erased.url}/ledger/{erased.answer['log_id']}").json()
    receipts = entry["redaction"]["receipts"]
    pairs = [pair for item in receipts for pair in item.get("replaced", [])]
    assert len(pairs) == 4 and all(re.fullmatch(r"[0-9a-f]{64}", digest) for pair in pairs for digest in pair)
    assert not holds_her(str(entry)) and "[erased]" not in str(entry["redaction"])  # digests, never the text


def test_no_file_of_the_data_directory_holds_her_name_after_a_checkpoint(erased: Erased) -> None:
    for database in erased.data_dir.glob("*.sqlite3"):
        with sqlite3.connect(database) as connection:
            connection.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    files = [path for path in erased.data_dir.rglob("*") if path.is_file()]
    assert any(path.parent.name.startswith("oxigraph") for path in files)
    assert [str(path) for path in files if bytes_hold_her(path.read_bytes())] == []
    with sqlite3.connect(erased.data_dir / "journal.sqlite3") as journal:
        rows = journal.execute("SELECT content, replacements FROM receipts WHERE action = 'ingest'").fetchall()
    documents = [zlib.decompress(blob) for row in rows for blob in row if blob]
    assert documents and not [text for text in documents if bytes_hold_her(text)]
    assert any(REDACTED[0].encode() in text for text in documents)  # the greeting, kept beside its post


def test_erasing_store_wide_redacts_a_text_that_concerns_someone_else(tmp_path: Path) -> None:
    """Carlos's own words naming her stay by default (they are his), and go with the store-wide option."""
    for scope, expected in (("concerning", ABOUT_HER), ("store", "Vengo a ver a [erased]")):
        with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path / scope))) as server:
            visit = care_centre()
            visit.publish_steps(server.url)
            carlos_names_her(visit)
            visit.publish(server.url, ("tiago",))
            settle(server.url)
            body = {"iri": str(visit.iris["lucia"]), "mentions": scope}
            preview = httpx.post(f"{server.url}/humans/erase", json={**body, "dry_run": True}, timeout=60).json()
            answer = httpx.post(f"{server.url}/humans/erase", json={**body, "reason": "request"}, timeout=120)
            assert answer.status_code == 200, answer.text
            settle(server.url)
            stored = events(server.url)
            assert expected in stored and all(text in stored for text in REDACTED)
            done = answer.json()
            # His words are in his message, in the shared event of his utterance and in its observation.
            assert (preview["mentions"], done["mentions_redacted"]) == ((4, 4) if scope == "concerning" else (7, 7))
            assert done["name_still_mentioned"] == (3 if scope == "concerning" else 0)
            verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()
            assert verified["valid"] is True
    # The redacted texts are covered by the erasure's record: one put back as it was breaks the deep verification.
    with sqlite3.connect(tmp_path / "store" / "journal.sqlite3") as journal:
        sequence, blob = journal.execute(
            "SELECT sequence, replacements FROM receipts WHERE length(replacements) > 0"
        ).fetchone()
        restored = zlib.decompress(blob).replace(REDACTED[0].encode(), GREETING.encode())
        journal.execute("UPDATE receipts SET replacements = ? WHERE sequence = ?", (zlib.compress(restored), sequence))
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path / "store"))) as server:
        verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()
        assert verified["valid"] is False and verified["first_broken"]["reason"] == "redaction does not match", verified


def test_a_text_naming_two_erased_people_loses_both_names(tmp_path: Path) -> None:
    """ARI tells Lucía that Carlos waits for her: erasing her leaves "[erased], Carlos"; erasing him store-wide
    then redacts the text already redacted (kept beside its post), and the journal holds neither name."""
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        visit = care_centre()
        visit.publish_steps(server.url)
        ari, iris = visit.loggers["ari"], visit.iris
        conversation(ari, "l4", iris["lucia"], "¿Ha llegado?", "Sí Lucía, Carlos te espera.", 35, iris["cnn"])
        visit.publish(server.url, ("ari",))
        settle(server.url)
        for who, scope in (("lucia", "concerning"), ("carlos", "store")):
            body = {"iri": str(iris[who]), "reason": "request", "mentions": scope}
            assert httpx.post(f"{server.url}/humans/erase", json=body, timeout=120).status_code == 200
            settle(server.url)
        stored = events(server.url)
        assert "Sí [erased], [erased] te espera." in stored and not holds_her(stored) and "Carlos" not in stored
        verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()
        assert verified["valid"] is True and verified["redactions"] == 2, verified
    with sqlite3.connect(tmp_path / "journal.sqlite3") as journal:
        rows = journal.execute("SELECT content, replacements FROM receipts WHERE action = 'ingest'").fetchall()
    documents = b"".join(zlib.decompress(blob) for row in rows for blob in row if blob)
    assert b"[erased], [erased] te espera" in documents and b"Carlos" not in documents and not bytes_hold_her(documents)


def test_an_unknown_scope_for_mentions_is_refused(tmp_path: Path) -> None:
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        answer = httpx.post(
            f"{server.url}/humans/erase", json={"iri": "https://example.org/h/x", "dry_run": True, "mentions": "all"}
        )
        assert answer.status_code == 422 and "mentions" in answer.text


@pytest.mark.processes  # runs the segb command
def test_the_command_line_counts_the_mentions_then_redacts_them_and_a_rebuild_keeps_the_mark(tmp_path: Path) -> None:
    """`segb erase --dry-run` counts the texts whose names would be redacted (store-wide too); the erasure says how
    many it redacted and how many concerning someone else still name her; a store rebuilt from the journal holds
    the redacted texts, not the old ones."""
    with LiveServer(create_app(make_settings(store="oxigraph", data_dir=tmp_path))) as server:
        visit = care_centre()
        visit.publish_steps(server.url)
        carlos_names_her(visit)
        visit.publish(server.url, ("tiago",))
        settle(server.url)
    lucia, data_dir = str(visit.iris["lucia"]), str(tmp_path)
    for scope, texts in (("concerning", 4), ("store", 7)):
        dry = segb("erase", "--data-dir", data_dir, "--dry-run", "--mentions", scope, lucia)
        assert dry.returncode == 0 and f"redact the person's names in {texts} texts" in dry.stdout, dry.stdout
    erased = segb("erase", "--data-dir", data_dir, lucia, "--reason", "request 31")
    assert erased.returncode == 0, erased.stderr
    assert "names redacted in 4 texts" in erased.stdout and "note: 3 texts that concern someone else" in erased.stdout
    refused = segb("erase", "--data-dir", data_dir, "--dry-run", "--mentions", "everywhere", lucia)
    assert refused.returncode == 2 and "--mentions" in refused.stderr and "Traceback" not in refused.stderr
    assert segb("rebuild", "--data-dir", data_dir).returncode == 0
    stored = segb("export", "--data-dir", data_dir, "--format", "ntriples").stdout
    assert all(text in stored for text in REDACTED) and not any(text in stored for text in (GREETING, SHOUT, LABEL))
    assert ABOUT_HER in stored  # his words, erased only store-wide


@pytest.mark.virtuoso
@pytest.mark.parametrize("scope", ["concerning", "store"])
def test_on_virtuoso_her_name_is_replaced_by_the_mark_and_withheld(
    virtuoso: VirtuosoProcess, tmp_path: Path, scope: str
) -> None:
    """As on the embedded store: Virtuoso reads her name, non-ASCII, in the rule's answers and in the store-wide
    sieve; Carlos's words naming her are counted as still there, or redacted store-wide."""
    store = virtuoso_store(virtuoso)
    try:
        with LiveServer(create_app(make_settings(store="virtuoso", data_dir=tmp_path), store=store)) as server:
            visit = care_centre()
            visit.publish_steps(server.url)
            carlos_names_her(visit)
            visit.publish(server.url, ("tiago",))
            settle(server.url)
            body = {"iri": str(visit.iris["lucia"]), "mentions": scope}
            preview = httpx.post(f"{server.url}/humans/erase", json={**body, "dry_run": True}, timeout=60)
            expected = 4 if scope == "concerning" else 7
            assert preview.json()["mentions"] == expected, preview.text
            answer = httpx.post(f"{server.url}/humans/erase", json={**body, "reason": "request"}, timeout=120)
            assert answer.status_code == 200, answer.text
            assert answer.json()["mentions_redacted"] == expected
            assert answer.json()["name_still_mentioned"] == (3 if scope == "concerning" else 0)
            settle(server.url)
            assert all(answer["triples_withheld"] > 0 for answer in visit.publish(server.url))
            settle(server.url)
            for form in ("received", None):
                stored = events(server.url, **({"form": form} if form else {}))
                assert all(text in stored for text in REDACTED)
                assert holds_her(stored) == (scope == "concerning")  # his words, unless redacted store-wide
                assert (ABOUT_HER in stored) == (scope == "concerning")
            sparql = httpx.post(f"{server.url}/sparql", data={"query": "SELECT * { ?s ?p ?o }"}, timeout=60).text
            assert REDACTED[0] in sparql and all(text not in sparql for text in (GREETING, SHOUT, GOODBYE, LABEL))
            verified = httpx.get(f"{server.url}/ledger/verify", params={"deep": "true"}).json()
            assert verified["valid"] is True and verified["redactions"] == 1
    finally:
        store.clear()
        store.close()

"""What a report's plan takes from its `.rq`: the IRIs a variable is narrowed to (`VALUES`, `FILTER … IN`), so
finding the keys a post touches skips the triples that cannot match — on Virtuoso, the rdf:type triples of
every activity of a post made the emotion timeline's key-finding query take up to 1.7 s."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import NamedNode, Quad

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.kept_queries.keys import KeyFinder
from segb_server.backend.services.views.kept_queries.plan import ReportPlan, plan_report
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.vocabulary import PREFIXES

CATALOG = Catalog(PACKAGE_ROOT / "sparql")
PEOPLE = {f"<{PREFIXES['oro']}Human>", f"<{PREFIXES['foaf']}Person>", f"<{PREFIXES['prov']}Person>"}
RDF_TYPE = NamedNode(PREFIXES["rdf"] + "type")


class CountingStore(OxigraphStore):
    """The embedded store, counting the queries asked of it."""

    asked = 0

    def query(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        self.asked += 1
        return super().query(*args, **kwargs)


def test_values_inside_exists_and_filter_in_narrow_the_class_variable() -> None:
    for report in ("reports/emotion-timeline", "reports/participants"):
        narrowed = plan_report(CATALOG.get(report)).narrowed
        assert PEOPLE in narrowed.values(), (report, narrowed)


def test_types_that_are_not_people_touch_no_emotion_key_and_ask_the_store_nothing(tmp_path: Path) -> None:
    plan = plan_report(CATALOG.get("reports/emotion-timeline"))
    store = CountingStore("http://amor-segb/events", tmp_path / "store")
    activity = NamedNode("https://example.org/a/activity_1")
    other_types = [Quad(activity, RDF_TYPE, NamedNode(PREFIXES["oro"] + "EmotionRecognitionEvent"))]
    try:
        assert KeyFinder(plan, "emotion").units(Delta.of(other_types), store) == set()
        assert store.asked == 0
        person = [Quad(NamedNode("https://example.org/h/maria"), RDF_TYPE, NamedNode(PREFIXES["oro"] + "Human"))]
        KeyFinder(plan, "emotion").units(Delta.of(person), store)  # a person's type may change the target's kind
        assert store.asked == 1
    finally:
        store.close()


def test_a_filter_nested_in_an_exists_a_bind_holds_is_in_the_plan() -> None:
    """rdflib's translation drops `FILTER EXISTS { … }` inside the group of an EXISTS that a BIND holds; the plan
    reads that group as written, so a triple matching only the nested pattern still finds its rows."""
    query = CatalogQuery(
        "reports/nested",
        "Nested",
        "",
        "PREFIX schema: <http://schema.org/> PREFIX oro: <http://kb.openrobots.org#>\n# key: ?message\n"
        "SELECT ?message ?human WHERE { ?message a schema:Message "
        "BIND (EXISTS { ?message schema:sender ?sender FILTER EXISTS { ?sender a oro:Human } } AS ?human) }",
    )
    plan = plan_report(query)
    assert "?sender <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <http://kb.openrobots.org#Human> ." in {
        pattern.sparql() for pattern in plan.patterns
    }
    store = OxigraphStore("http://amor-segb/events")
    sender = NamedNode("https://example.org/h/maria")
    store.apply([Quad(NamedNode("https://example.org/m/1"), NamedNode("http://schema.org/sender"), sender)], 1)
    typed = [Quad(sender, RDF_TYPE, NamedNode(PREFIXES["oro"] + "Human"))]
    assert KeyFinder(plan, "message").units(Delta.of(typed), store) == {"<https://example.org/m/1>"}
    store.close()


def _plan_with(condition: str) -> ReportPlan:
    return plan_report(
        CatalogQuery(
            "reports/excluding",
            "Excluding",
            "",
            "PREFIX schema: <http://schema.org/> PREFIX oro: <http://kb.openrobots.org#>\n# key: ?message\n"
            f"SELECT ?message ?robot WHERE {{ ?message a schema:Message ; schema:sender ?robot . {condition} }}",
        )
    )


def test_only_a_not_exists_of_patterns_about_the_key_alone_excludes_a_key() -> None:
    """A top-level NOT EXISTS whose patterns match among a batch's triples from a key it introduced rules out that
    key's rows — only when the body is its patterns alone and shares nothing but the key with the query."""
    plain = _plan_with("FILTER NOT EXISTS { ?message a oro:InitialMessage }")
    assert [[pattern.sparql() for pattern in body] for body in plain.exclusions_of("?message")] == [
        ["?message <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <http://kb.openrobots.org#InitialMessage> ."]
    ]
    # A condition inside the body: its patterns may match where the body does not.
    conditioned = _plan_with("FILTER NOT EXISTS { ?message schema:recipient ?to FILTER (?to != <https://e.org/x>) }")
    assert conditioned.exclusions_of("?message") == []
    # A variable the row binds too: whether the body matches depends on the row, not on the key alone.
    shared = _plan_with("FILTER NOT EXISTS { ?message schema:recipient ?robot }")
    assert shared.exclusions_of("?message") == []

"""What a report's plan takes from its `.rq`: the IRIs a variable is narrowed to (`VALUES`, `FILTER … IN`), so
finding the keys a post touches skips the triples that cannot match — on Virtuoso, the rdf:type triples of
every activity of a post made the emotion timeline's key-finding query take up to 1.7 s."""

from __future__ import annotations

from pathlib import Path

from pyoxigraph import NamedNode, Quad

from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.upkeep.delta import Delta
from segb_server.backend.services.upkeep.kept_queries.keys import KeyFinder
from segb_server.backend.services.upkeep.kept_queries.plan import plan_report
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

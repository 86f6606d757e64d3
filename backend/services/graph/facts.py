"""The graph index's facts (links, each node's list of types, the literals it keeps) and each node's derived row
(kind, time, label).

What is drawn: every link between two resources (`rdf:type` gives node types instead) and the literals that name
and place nodes (`DRAWN_LITERALS`); other literals the index keeps whole for resource summaries
(`detail_literals`); the rest stay in the store. A node's row is computed again whenever a fact about it, or
about the activity it borrows its time from, arrives.
"""

from __future__ import annotations

import json
import sqlite3
from collections import defaultdict
from collections.abc import Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from pyoxigraph import Literal, NamedNode, Quad

from segb_server.backend.reading import NAME_PREDICATES, TIME_PREDICATES, display_name, own_time
from segb_server.backend.services.values import iso_time
from segb_server.backend.services.views.terms import CHUNK, TermIds, iri_hash, texts_of
from segb_server.backend.vocabulary import KINDS, PREFIXES, Kind, kind_of

RDF_TYPE = PREFIXES["rdf"] + "type"
# Display name predicates, best first: the rule of reading (backend/reading.py).
LABELS = list(NAME_PREDICATES)
TEXT = PREFIXES["schema"] + "text"
DESCRIPTION = PREFIXES["schema"] + "description"
INTENSITY = PREFIXES["onyx"] + "hasEmotionIntensity"
CATEGORY = PREFIXES["onyx"] + "hasEmotionCategory"
# Own time of a node, best first (the rule of reading). Messages and emotions borrow the time of the activity behind
# them.
TIMES = list(TIME_PREDICATES)
GENERATED_AT = PREFIXES["prov"] + "generatedAtTime"
WAS_GENERATED_BY = PREFIXES["prov"] + "wasGeneratedBy"
PRODUCED = PREFIXES["segb"] + "producedEntityResult"
HAS_EMOTION = PREFIXES["onyx"] + "hasEmotion"
PROV = PREFIXES["prov"]
TERMS = "graph_terms"  # the index's table of IRIs (views/terms.py)
DRAWN_LITERALS = frozenset([*LABELS, TEXT, DESCRIPTION, *TIMES, INTENSITY])
MAX_LABEL = 60
UNTIMED = 1 << 62  # the instant of a node without a time: after every real one
RANK = {kind: index for index, kind in enumerate(KINDS)}
TYPESETS_REMEMBERED = 1_000  # lists of types the writer remembers with their ids (a few dozen in a real log)
EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


@dataclass
class _Derived:
    kind: Kind
    time: str | None
    label: str


class Facts:
    """The writer's side of the index's tables: ids, and the few classes, datatypes and type lists it meets."""

    def __init__(self, kept_literals: frozenset[str]) -> None:
        self.kept_literals = kept_literals
        self.terms = TermIds(TERMS)
        self._typesets: dict[str, int] = {}  # a list of types as stored → its id
        self._listed: dict[int, frozenset[str]] = {}  # and back

    def forget(self) -> None:
        """The tables were emptied (a build, a clearing): every id made before is gone."""
        self.terms.forget()
        self._typesets.clear()
        self._listed.clear()

    def store(self, connection: sqlite3.Connection, quads: Iterable[Quad]) -> tuple[set[int], list[tuple[int, int]]]:
        """Store the drawable facts among `quads` and the kept literals; the ids of the nodes they are about, and
        the links among them ((source, target) pairs)."""
        types: dict[str, set[str]] = defaultdict(set)
        literals: list[tuple[str, str, str, str | None, str | None]] = []
        links: list[tuple[str, str, str]] = []
        nodes: set[str] = set()
        for quad in quads:
            subject, predicate, value = quad.subject, quad.predicate.value, quad.object
            if not isinstance(subject, NamedNode):
                continue
            if isinstance(value, Literal):
                if predicate in self.kept_literals:
                    language = value.language
                    literals.append(
                        (subject.value, predicate, value.value, None if language else value.datatype.value, language)
                    )
                    if predicate in DRAWN_LITERALS:
                        nodes.add(subject.value)
            elif isinstance(value, NamedNode):
                nodes.add(subject.value)
                if predicate == RDF_TYPE:
                    types[subject.value].add(value.value)
                else:
                    links.append((subject.value, predicate, value.value))
                    nodes.add(value.value)
        named = [*nodes, *(p for _, p, _ in links), *(p for _, p, _, _, _ in literals)]
        named += [datatype for *_, datatype, _ in literals if datatype is not None]
        ids = self.terms.ids(connection, named)
        if literals:
            # Numbered in the order they came (a node's name is its first, its time its last), from a count
            # of every literal the index was given: each node's literals lie together, in that order.
            (before,) = connection.execute(
                "UPDATE graph_state SET literals = literals + ? RETURNING literals - ?", (len(literals), len(literals))
            ).fetchone()
            connection.executemany(
                "INSERT INTO graph_literals VALUES (?, ?, ?, ?, ?, ?)",
                [(ids[n], before + seq, ids[p], v, None if d is None else ids[d], lang)
                 for seq, (n, p, v, d, lang) in enumerate(literals)],
            )  # fmt: skip
        linked = [(ids[s], ids[p], ids[o]) for s, p, o in links]
        connection.executemany("INSERT OR IGNORE INTO graph_links VALUES (?, ?, ?)", linked)
        empty = self._typeset(connection, frozenset())
        added = connection.executemany(
            "INSERT OR IGNORE INTO graph_nodes VALUES (?, ?, ?, ?, NULL, '', NULL, ?)",
            [(ids[iri], RANK["other"], UNTIMED, tie_of(iri), empty) for iri in nodes],
        ).rowcount
        connection.execute("UPDATE graph_state SET nodes = nodes + ?", (added,))
        if types:
            self._add_types(connection, {ids[node]: found for node, found in types.items()})
        return {ids[iri] for iri in nodes}, [(source, target) for source, _, target in linked]

    def borrowers(self, connection: sqlite3.Connection, touched: set[int]) -> set[int]:
        """Nodes whose time may come from a touched one: what a touched activity produced or generated, and the
        emotions of what it produced."""
        produced, has_emotion, generated_by = self._known(connection, [PRODUCED, HAS_EMOTION, WAS_GENERATED_BY])
        first: set[int] = set()
        for chunk in chunks(sorted(touched)):
            marks = ", ".join("?" * len(chunk))
            first.update(
                row[0]
                for row in connection.execute(
                    f"SELECT target FROM graph_links WHERE source IN ({marks}) AND predicate IN (?, ?) "
                    f"UNION SELECT source FROM graph_links WHERE target IN ({marks}) AND predicate = ?",
                    [*chunk, produced, has_emotion, *chunk, generated_by],
                )
            )
        second: set[int] = set()
        for chunk in chunks(sorted(first - touched)):
            marks = ", ".join("?" * len(chunk))
            second.update(
                row[0]
                for row in connection.execute(
                    f"SELECT target FROM graph_links WHERE source IN ({marks}) AND predicate = ?",
                    [*chunk, has_emotion],
                )
            )
        return first | second

    def derive(self, connection: sqlite3.Connection, nodes: Sequence[int]) -> None:
        """Compute each node's kind, time and label again from its facts."""
        drawn = self._known(connection, sorted(DRAWN_LITERALS))
        predicates = dict(zip(sorted(DRAWN_LITERALS), drawn, strict=True))
        by_id = {term_id: iri for iri, term_id in predicates.items() if term_id}
        (category,) = self._known(connection, [CATEGORY])
        for chunk in chunks(nodes):
            marks = ", ".join("?" * len(chunk))
            typesets = dict(connection.execute(f"SELECT id, typeset FROM graph_nodes WHERE id IN ({marks})", chunk))
            literals: dict[int, dict[str, str]] = defaultdict(dict)
            # A name or text: the first one written; a time: the last one.
            for node, predicate, value in connection.execute(
                f"SELECT node, predicate, value FROM graph_literals WHERE node IN ({marks}) ORDER BY node, seq", chunk
            ):
                name = by_id.get(predicate)
                if name is not None and (name in TIMES or name not in literals[node]):
                    literals[node][name] = value
            categories = dict(
                connection.execute(
                    f"SELECT l.source, MIN(t.text) FROM graph_links l JOIN graph_terms t ON t.id = l.target "
                    f"WHERE l.source IN ({marks}) AND l.predicate = ? GROUP BY l.source",
                    [*chunk, category],
                )
            )
            iris = texts_of(connection, TERMS, chunk)
            derived: dict[int, _Derived] = {}
            for node in chunk:
                values = literals.get(node, {})
                types = self._types_of(connection, typesets[node]) if node in typesets else frozenset()
                kind = kind_of(types, timestamped=GENERATED_AT in values)
                own = own_time(values)
                label = display_label(iris[node], kind, values, categories.get(node))
                derived[node] = _Derived(kind, normal_time(own), label)
            borrowing = [node for node, d in derived.items() if d.time is None and d.kind in ("message", "emotion")]
            for node, time in self._borrowed_times(connection, borrowing).items():
                derived[node].time = time
            instants = {node: instant_of(d.time) if d.time else UNTIMED for node, d in derived.items()}
            connection.executemany(
                "INSERT OR REPLACE INTO graph_nodes VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [
                    (node, RANK[d.kind], instants[node], tie_of(iris[node], timed=bool(d.time)),
                     kept_time(d.time, instants[node]), d.label, _folded(d.label),
                     typesets.get(node) or self._typeset(connection, frozenset()))
                    for node, d in derived.items()
                ],
            )  # fmt: skip

    def _borrowed_times(self, connection: sqlite3.Connection, nodes: list[int]) -> dict[int, str]:
        """The time of the activity behind each message or emotion: the activity that generated it, else what
        produced it (an activity, or an annotation and the activity that produced that)."""
        generated_by, produced, has_emotion = self._known(connection, [WAS_GENERATED_BY, PRODUCED, HAS_EMOTION])
        times = self._known(connection, TIMES)
        preference = {term_id: index for index, term_id in enumerate(times) if term_id}
        found: dict[int, str] = {}
        routes = [
            # the message -wasGeneratedBy-> activity
            "SELECT l.source, t.predicate, t.value, t.seq FROM graph_links l "
            "JOIN graph_literals t ON t.node = l.target WHERE l.predicate = ? AND l.source IN ({marks}) "
            "AND t.predicate IN (?, ?, ?)",
            # activity -producedEntityResult|hasEmotion-> it
            "SELECT l.target, t.predicate, t.value, t.seq FROM graph_links l "
            "JOIN graph_literals t ON t.node = l.source WHERE l.predicate IN (?, ?) AND l.target IN ({marks}) "
            "AND t.predicate IN (?, ?, ?)",
            # activity -producedEntityResult-> annotation -hasEmotion-> it
            "SELECT l2.target, t.predicate, t.value, t.seq FROM graph_links l2 JOIN graph_links l1 "
            "ON l1.target = l2.source AND l1.predicate IN (?, ?) JOIN graph_literals t ON t.node = l1.source "
            "WHERE l2.predicate IN (?, ?) AND l2.target IN ({marks}) AND t.predicate IN (?, ?, ?)",
        ]
        for chunk in chunks(nodes):
            marks = ", ".join("?" * len(chunk))
            arguments = [
                [generated_by, *chunk, *times],
                [produced, has_emotion, *chunk, *times],
                [produced, has_emotion, produced, has_emotion, *chunk, *times],
            ]
            for route, route_arguments in zip(routes, arguments, strict=True):
                # Per node and time predicate the last value written (as the node's own time), then the best
                # predicate; between activities, the earliest time.
                latest: dict[tuple[int, int], tuple[int, str]] = {}
                for node, predicate, value, order in connection.execute(route.format(marks=marks), route_arguments):
                    if node not in found and ((node, predicate) not in latest or order > latest[node, predicate][0]):
                        latest[node, predicate] = (order, value)
                best: dict[int, tuple[int, str]] = {}
                for (node, predicate), (_, value) in latest.items():
                    time = normal_time(value)
                    if time and (node not in best or (preference[predicate], time) < best[node]):
                        best[node] = (preference[predicate], time)
                found.update({node: time for node, (_, time) in best.items()})
        return found

    def _known(self, connection: sqlite3.Connection, iris: Sequence[str]) -> list[int]:
        """The ids of vocabulary IRIs (made when missing: the writer's transaction is under way)."""
        ids = self.terms.ids(connection, iris)
        return [ids[iri] for iri in iris]

    def _add_types(self, connection: sqlite3.Connection, added: dict[int, set[str]]) -> None:
        """Add types to nodes (rows of graph_nodes already): each node's list of types is kept once for all the
        nodes with that list (`graph_typesets`), so a node's types take the few bytes of its list's id."""
        typesets: dict[int, int] = {}
        for chunk in chunks(sorted(added)):
            marks = ", ".join("?" * len(chunk))
            typesets.update(connection.execute(f"SELECT id, typeset FROM graph_nodes WHERE id IN ({marks})", chunk))
        grown = []
        for node, new in added.items():
            types = self._types_of(connection, typesets[node])
            if not new <= types:
                grown.append((self._typeset(connection, types | new), node))
        connection.executemany("UPDATE graph_nodes SET typeset = ? WHERE id = ?", grown)
        self._drop_unheld(connection, {typesets[node] for _, node in grown})

    def _drop_unheld(self, connection: sqlite3.Connection, typesets: set[int]) -> None:
        """Drop the lists no node holds any more (a node's list grew): a robot typing one node again and again
        leaves one list of its types, not one for every step (which would grow as the square of its types)."""
        empty = self._typeset(connection, frozenset())  # held by every node until its types come
        for typeset in sorted(typesets - {empty}):
            if connection.execute("SELECT 1 FROM graph_nodes WHERE typeset = ? LIMIT 1", (typeset,)).fetchone():
                continue
            connection.execute("DELETE FROM graph_typesets WHERE id = ?", (typeset,))
            types = self._listed.pop(typeset, None)
            if types is not None:
                self._typesets.pop(json.dumps(sorted(types)), None)

    def _typeset(self, connection: sqlite3.Connection, types: frozenset[str]) -> int:
        """The id of a list of types (IRIs): a few dozen distinct lists cover thousands of nodes."""
        listed = json.dumps(sorted(types))
        known = self._typesets.get(listed)
        if known is None:
            connection.execute("INSERT OR IGNORE INTO graph_typesets (types) VALUES (?)", (listed,))
            known = connection.execute("SELECT id FROM graph_typesets WHERE types = ?", (listed,)).fetchone()[0]
            self._remember(listed, known, types)
        return known

    def _types_of(self, connection: sqlite3.Connection, typeset: int) -> frozenset[str]:
        """The types of a list's id."""
        types = self._listed.get(typeset)
        if types is None:
            (listed,) = connection.execute("SELECT types FROM graph_typesets WHERE id = ?", (typeset,)).fetchone()
            types = frozenset(json.loads(listed))
            self._remember(listed, typeset, types)
        return types

    def _remember(self, listed: str, typeset: int, types: frozenset[str]) -> None:
        if len(self._listed) >= TYPESETS_REMEMBERED:  # a robot typing every node its own way: start again
            self._typesets.clear()
            self._listed.clear()
        self._typesets[listed] = typeset
        self._listed[typeset] = types


def display_label(iri: str, kind: Kind, literals: dict[str, str], category: str | None) -> str:
    """A name for a node: its own name, an emotion's category and intensity, its text, or its IRI's end."""
    if (name := display_name(literals)) is not None:
        return name
    if kind == "emotion" and INTENSITY in literals:
        name = local_name(category).removeprefix("big6_") if category else ""
        return f"{name} {literals[INTENSITY]}".strip()
    for predicate in (TEXT, DESCRIPTION):
        if predicate in literals:
            text = literals[predicate]
            return text if len(text) <= MAX_LABEL else text[: MAX_LABEL - 1] + "…"
    return local_name(iri)


def _folded(label: str) -> str | None:
    """The label as a search compares it (any case), when SQLite's `lower`, which folds ASCII letters only,
    would not give it (a search reads `COALESCE(folded, lower(label))`): a few labels, not three in four."""
    folded = label.casefold()
    return folded if folded != label.translate(_ASCII_LOWER) else None


_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")


def kept_time(time: str | None, instant: int) -> str | None:
    """A node's time as its row keeps it: None when its instant spells it (a time with a zone, written in UTC as
    `normal_time` writes it), so only a time without a zone is kept as text (its instant takes it as UTC)."""
    if time is None or time_at(instant) == time:
        return None
    return time


def node_time(kept: str | None, instant: int) -> str | None:
    """A node's time from its row (`kept_time`)."""
    if kept is not None:
        return kept
    return None if instant == UNTIMED else time_at(instant)


def time_at(instant: int) -> str:
    return iso_time((EPOCH + timedelta(microseconds=instant)).isoformat())


def tie_of(iri: str, *, timed: bool = False) -> str | int:
    """What orders nodes of one kind and one instant: for untimed nodes (the robots, the people, listed by
    name) their IRIs' ends (`robot_ari` before `robot_tiago`), then a hash of the whole IRI (the same end in
    two namespaces); for timed nodes, which rarely share an instant, the hash alone, as an integer (8 bytes
    where the text took about 36, in the table and in its order's index). Either way an index built afresh
    and one kept current draw the same nodes in the same order; nodes of one instant are all timed or all
    untimed, so a text and a number are never compared."""
    hashed = iri_hash(iri)
    if timed:
        return hashed
    return f"{local_name(iri)[:40]}\x00{hashed & 0xFFFFFFFFFFFFFFFF:016x}"


def local_name(iri: str) -> str:
    return iri.rstrip("/#").replace("#", "/").rsplit("/", 1)[-1] or iri


def normal_time(value: str | None) -> str | None:
    if value is None:
        return None
    try:
        return iso_time(value)
    except ValueError:
        return None


def instant_of(iso: str) -> int:
    """A time as microseconds since 1970 in UTC, which sort as the instants do (a time without a zone is
    taken as UTC)."""
    moment = datetime.fromisoformat(iso.replace("Z", "+00:00"))
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    delta = moment - EPOCH
    return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds


def chunks(items: Sequence[int]) -> Iterator[Sequence[int]]:
    for start in range(0, len(items), CHUNK):
        yield items[start : start + CHUNK]


def typed_literal(value: str, datatype: str | None, language: str | None) -> Literal:
    return Literal(value, language=language) if language else Literal(value, datatype=NamedNode(datatype or ""))


def kept(predicates: Collection[str]) -> frozenset[str]:
    """The literals an index keeps: those that name and place nodes, and `predicates`."""
    return DRAWN_LITERALS | frozenset(predicates)

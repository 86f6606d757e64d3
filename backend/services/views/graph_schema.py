"""The graph index's tables: its state, the table of terms, the literals it keeps, the links, the lists of types
and the nodes' derived rows in drawing order, and the change log kept neighbourhoods are checked against."""

from __future__ import annotations

import hashlib

from segb_server.backend.services.graph.facts import TERMS
from segb_server.backend.services.views import terms

TABLES = (
    "graph_state",
    "graph_terms",
    "graph_literals",
    "graph_links",
    "graph_typesets",
    "graph_nodes",
    "graph_changes",
)
SCHEMA = [
    # nodes: how many rows graph_nodes holds (nodes are only ever added, until a clearing), for the first view's
    # total without counting them; changed: the entry of the last change to what is drawn (for live viewers of
    # every API process)
    # first_view: changes whenever the first view (`FIRST_VIEW`) would draw something else, so every process may
    # keep that view, the one each visit opens with, until it does
    # changes_from: the entry after which `graph_changes` holds every node each step wrote (`neighbourhoods`)
    # literals: how many literals the index was given (their numbers in `graph_literals`)
    "CREATE TABLE IF NOT EXISTS graph_state (id INTEGER PRIMARY KEY CHECK (id = 1), version TEXT, through INTEGER, "
    "nodes INTEGER NOT NULL DEFAULT 0, changed INTEGER NOT NULL DEFAULT 0, first_view INTEGER NOT NULL DEFAULT 0, "
    "changes_from INTEGER NOT NULL DEFAULT 0, literals INTEGER NOT NULL DEFAULT 0)",
    # every IRI once: nodes, predicates, datatypes (views/terms.py; classes are in the lists of types)
    *terms.schema(TERMS),
    "CREATE TABLE IF NOT EXISTS graph_changes (seq INTEGER NOT NULL, node INTEGER NOT NULL)",
    "CREATE INDEX IF NOT EXISTS graph_changes_by_seq ON graph_changes (seq)",
    # the literals kept (those that name and place nodes, and `detail_literals`) whole, each node's together in
    # the order they came (seq: graph_state.literals when it came; a node's name is its first, its time its
    # last); datatype is NULL for a language-tagged string
    "CREATE TABLE IF NOT EXISTS graph_literals (node INTEGER NOT NULL, seq INTEGER NOT NULL, "
    "predicate INTEGER NOT NULL, value TEXT NOT NULL, datatype INTEGER, language TEXT, PRIMARY KEY (node, seq)) "
    "WITHOUT ROWID",
    "CREATE TABLE IF NOT EXISTS graph_links (source INTEGER, predicate INTEGER, target INTEGER, "
    "PRIMARY KEY (source, predicate, target)) WITHOUT ROWID",
    "CREATE INDEX IF NOT EXISTS graph_links_by_target ON graph_links (target, predicate, source)",
    # the distinct lists of a node's types (IRIs, sorted, as JSON): a few dozen lists for thousands of nodes, each
    # node holding its list's id (`typeset`)
    "CREATE TABLE IF NOT EXISTS graph_typesets (id INTEGER PRIMARY KEY, types TEXT NOT NULL UNIQUE)",
    # rank: the kind's place in KINDS; instant: the time in microseconds (UNTIMED when none); tie: what orders
    # nodes of one kind and instant (the robots, the people), the same however they arrived (`facts.tie_of`: a
    # text or a number, so the column has no type that would turn one into the other);
    # time: only a time its instant does not spell (`facts.kept_time`); folded: the label as a search compares
    # it, when SQLite's lower() would not give it (`facts._folded`)
    "CREATE TABLE IF NOT EXISTS graph_nodes (id INTEGER PRIMARY KEY, rank INTEGER NOT NULL, "
    "instant INTEGER NOT NULL, tie NOT NULL, time TEXT, label TEXT NOT NULL, folded TEXT, "
    "typeset INTEGER NOT NULL)",
    "CREATE INDEX IF NOT EXISTS graph_nodes_order ON graph_nodes (rank, instant, tie, id)",
    "CREATE INDEX IF NOT EXISTS graph_nodes_typeset ON graph_nodes (typeset)",  # the nodes of a class
]
# A change to the tables is a new version of the index (`graph_index.STORED_VERSION`): an index written before
# it is built again instead of failing on a column it lacks.
SCHEMA_DIGEST = hashlib.sha256("\n".join(SCHEMA).encode()).hexdigest()[:12]

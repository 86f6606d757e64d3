"""The SHACL rules checked on nodes: every target of each rule among the nodes a batch names (or all of them), their
statements read once for all the rules, and each finding as a kept row with its sort key, time and robot."""

from __future__ import annotations

from dataclasses import replace

from pyoxigraph import Literal, NamedNode

from segb_server.backend.services.rules.shapes import (
    Context,
    NodeStatements,
    ShapeResult,
    ShapeRule,
    read_predicates,
    robots_of_generating,
    statements,
)
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.kept_queries.encoding import instant, sort_key
from segb_server.backend.store.base import Store, Term

Found = tuple[str, str | None, str | None, dict[str, JsonValue]]  # sort key, time, robot, the finding


def check_shapes(rule: ShapeRule, store: Store, named: set[str] | None) -> tuple[set[str], dict[str, list[Found]]]:
    """Check a SHACL rule on the targets among `named` (None: every target): the nodes checked, and each one's
    findings as (sort key, time, robot, row)."""
    return check_rules([rule], store, named)[rule.rule.id]


def check_rules(
    rules: list[ShapeRule], store: Store, named: set[str] | None, delta: Delta | None = None
) -> dict[str, tuple[set[str], dict[str, list[Found]]]]:
    """`check_shapes` for several rules, their targets' statements read once for all: every candidate's (the
    targets most shapes declare — a type, a predicate the node is the subject of — are read off them), or, for a
    full check (`named` None), the targets the store answers for. `delta`: the batch naming the candidates,
    whose triples are all there is about its fresh ones."""
    if named is not None:
        candidates = sorted(node for node in named if node.startswith("<"))
        predicates = _union([rule.statement_predicates() for rule in rules])
        data, contexts = statements(store, candidates, predicates, delta) if candidates else (NodeStatements(), {})
        targets = {rule.rule.id: rule.targets_among(store, candidates, data, delta) for rule in rules}
    else:
        targets = {rule.rule.id: rule.targets(store, None) for rule in rules}
        nodes = sorted({node for found in targets.values() for nodes in found.values() for node in nodes})
        data, contexts = statements(store, nodes, read_predicates(rules)) if nodes else (NodeStatements(), {})
    validated: dict[str, tuple[set[str], list[ShapeResult]]] = {}
    for rule in rules:
        units = set().union(*targets[rule.rule.id].values()) if targets[rule.rule.id] else set()
        validated[rule.rule.id] = (units, rule.validate(data, targets[rule.rule.id]) if units else [])
    # A finding about what an activity generated, saying no robot of its own, is the robot's of that activity:
    # looked up for the nodes found at fault only.
    generating = {
        context.generated_by
        for _, results in validated.values()
        for result in results
        if (context := contexts.get(result.focus)) is not None and context.robot is None and context.generated_by
    }
    robots = robots_of_generating(store, generating, delta) if generating else {}
    checked: dict[str, tuple[set[str], dict[str, list[Found]]]] = {}
    for rule in rules:
        units, results = validated[rule.rule.id]
        found: dict[str, list[Found]] = {}
        for result in results:
            context = contexts.get(result.focus, Context())
            if context.robot is None and context.generated_by in robots:
                context = replace(context, robot=robots[context.generated_by])
            found.setdefault(result.focus, []).append(_record(result, context))
        checked[rule.rule.id] = (units, found)
    return checked


def _union(sets: list[frozenset[str] | None]) -> frozenset[str] | None:
    """Every predicate any of them reads (None: one of them reads every statement)."""
    if any(found is None for found in sets):
        return None
    return frozenset().union(*(found for found in sets if found is not None))


def _record(result: ShapeResult, context: Context) -> Found:
    """One finding: sorted by its focus node's time, then the node; its time and robot as filters compare them."""
    time, robot = context.time, context.robot
    row: dict[str, JsonValue] = {
        "time": json_value(time),  # type: ignore[arg-type]
        "focus": result.focus[1:-1],
        "robot": json_value(robot),  # type: ignore[arg-type]
        "human": None,
        "message": result.message,
        "path": result.path,
        "value": result.value,
    }
    order = sort_key([time, _iri(result.focus)])  # type: ignore[list-item]
    moment = instant(time) if isinstance(time, Literal) else None
    robot_text = robot.value if isinstance(robot, NamedNode) else None
    return order, moment, robot_text, row


def _iri(text: str) -> Term:
    return NamedNode(text[1:-1])

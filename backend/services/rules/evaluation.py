"""Every rule evaluated in full on one store: what a log holds by itself (`segb check`, `POST /ttl/validate`)
and what the kept findings must equal (the differential tests)."""

from __future__ import annotations

from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.findings import Finding, finding, order_key
from segb_server.backend.services.rules.service import FindingsService
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.services.views.shape_checks import check_shapes
from segb_server.backend.store.base import Store


def check_store(catalog: RuleCatalog, store: Store, shape_rules: dict[str, ShapeRule] | None = None) -> list[Finding]:
    """Every rule's findings on `store`, parameters at their defaults, in time order (then by rule)."""
    shapes = shape_rules if shape_rules is not None else {rule.id: ShapeRule(rule) for rule in catalog.shapes()}
    evaluator = FindingsService(catalog, store, None, None, shapes)
    rows = []
    for rule in catalog:
        if rule.query is not None:
            rows += [(order_key(row), rule.id, row) for row in evaluator.evaluate_rule(rule, {})]
        else:
            _, found = check_shapes(shapes[rule.id], store, None)
            rows += [(order_key(row), rule.id, row) for records in found.values() for *_, row in records]
    rows.sort(key=lambda entry: (entry[0], entry[1]))
    return [finding(catalog.get(rule_id), row) for _, rule_id, row in rows]

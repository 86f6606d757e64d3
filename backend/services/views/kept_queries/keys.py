"""Which rows of a kept query new triples can change: for each triple pattern of the query that a new triple
matches, the patterns sure to hold with it lead back to the row keys (units) it can change — a chain of steps
found once when the query is planned, asked of the store with the triple's terms bound (one small query).

A chain starts from the matched triple's subject when it can: a triple's object is often a hub (a robot, a
model, a human), and a chain from it would reach every unit of that hub, where one from the subject reaches
the units of this one triple.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
from functools import cached_property

from segb_server.backend.services.views.delta import Delta, Fact
from segb_server.backend.services.views.kept_queries.delta_joins import Alias, DeltaJoin, Step
from segb_server.backend.services.views.kept_queries.plan import ReportPlan
from segb_server.backend.services.views.kept_queries.plan_parts import Pattern, Unsupported
from segb_server.backend.store.base import Store, select
from segb_server.backend.store.terms import term_text

VALUES_PER_QUERY = 300
BRANCHES_PER_QUERY = 12  # key-finding chains asked in one query


class PatternMatch:
    """The new triples one pattern matches: those whose predicate is one of its own, whose terms equal its
    constants, and whose terms are among the values its group allows a variable (e.g. `?target a ?class` where
    `VALUES ?class { … }` lists the classes of people: the types of every other resource a post describes
    match nothing)."""

    def __init__(self, plan: ReportPlan, pattern: Pattern) -> None:
        self.pattern = pattern
        self._predicates = sorted(pattern.predicates)
        self._subject = None if pattern.subject.startswith("?") else pattern.subject
        self._object = None if pattern.object.startswith("?") else pattern.object
        self._subjects = plan.narrowed.get((pattern.group, pattern.subject)) if self._subject is None else None
        self._objects = plan.narrowed.get((pattern.group, pattern.object)) if self._object is None else None

    def facts(self, delta: Delta) -> list[Fact]:
        if self._subject is None and self._subjects is None and self._objects is None and len(self._predicates) == 1:
            return delta.with_predicate(self._predicates[0], self._object)  # most patterns: nothing to sift
        found = []
        for predicate in self._predicates:
            for fact in delta.with_predicate(predicate, self._object):
                if self._subject is not None and fact.subject_text != self._subject:
                    continue
                if self._subjects is not None and fact.subject_text not in self._subjects:
                    continue
                if self._objects is not None and fact.object_text not in self._objects:
                    continue
                found.append(fact)
        return found

    def texts(self, delta: Delta, variable: str) -> AbstractSet[str]:
        """The texts `variable` takes in the new triples this pattern matches: for most patterns a set the batch
        makes once for every view that asks (`Delta.ends`)."""
        subject = variable == self.pattern.subject
        plain = self._subject is None and self._subjects is None and self._objects is None
        if plain and self.pattern.subject != self.pattern.object:
            return delta.ends(self._predicates, subject=subject, other=self._object)
        return {self.text(fact, variable) for fact in self.facts(delta)}

    def text(self, fact: Fact, variable: str) -> str:
        """The N-Triples text `variable` takes when this pattern matches `fact`."""
        return fact.subject_text if variable == self.pattern.subject else fact.object_text

    def binds_literal(self, fact: Fact, variables: tuple[str, ...]) -> bool:
        return fact.literal_object and self.pattern.object in variables


class KeyFinder:
    """The units (values of `?unit`, as N-Triples text) that new triples may change, for one plan. The chains from
    each of the plan's patterns to the unit are found once, when the query is planned (Unsupported when a
    pattern has none): a batch then costs only the matching and the queries. Triples matching only `ignored`
    patterns change no unit."""

    def __init__(self, plan: ReportPlan, unit: str, ignored: frozenset[Pattern] = frozenset()) -> None:
        self.plan = plan
        self.unit = unit
        self.target = f"?{unit}"
        self._leads = [
            _Lead(PatternMatch(plan, pattern),
                  [] if self.target in pattern.variables() else chains(plan, pattern, self.target))
            for pattern in plan.patterns
            if pattern not in ignored
        ]  # fmt: skip
        for lead in self._leads:  # compiled now, in one thread, rather than by the first batch's views at once
            for chain, _, _ in lead.routes:
                chain.join  # noqa: B018
        # The chains whose every unit, when the chain goes from the batch's own resources only, is found by another
        # lead anyway: such a chain ends with a triple that names the unit, a triple the batch holds (it is about a
        # fresh term) and which the pattern naming the unit matches. Followed or asked, it would add nothing.
        naming = {lead.match.pattern for lead in self._leads if not lead.chains}  # the leads that name the unit
        self._covered = {
            chain
            for lead in self._leads
            for chain in lead.chains
            if chain.join.hop_binds_out and any(link in naming for link in chain.links if isinstance(link, Pattern))
        }

    def units(self, delta: Delta, store: Store) -> set[str]:
        units: set[str] = set()
        # The VALUES rows of each chain, gathered over every pattern leading to it: the patterns of one resource
        # (an activity's type, robot, time, …) share their chains, and each row is asked once for all of them.
        rows_by_chain: dict[_Chain, dict[tuple[str, ...], bool]] = {}  # a chain's start → whether it binds a literal
        for lead in self._leads:
            if not lead.chains:
                units |= lead.match.texts(delta, self.target)
                continue
            facts = lead.match.facts(delta)
            if not facts:
                continue
            for chain, picks, object_named in lead.routes:
                rows = rows_by_chain.setdefault(chain, {})
                for fact in facts:
                    origin = tuple([fact.subject_text if subject else fact.object_text for subject in picks])
                    literal = object_named and fact.literal_object
                    if literal or origin not in rows:
                        rows[origin] = rows.get(origin, False) or literal
        asked: dict[_Chain, list[tuple[str, bool]]] = {}  # the VALUES rows of each chain the store is asked
        for chain, rows in rows_by_chain.items():
            covered = chain in self._covered
            for origin, literal in rows.items():
                if covered and chain.join.stays_fresh(delta, origin):
                    continue  # every unit it reaches is named by one of the batch's triples, found above
                # A chain from the batch's own resources is followed among its triples (`delta_joins.py`).
                found = chain.join.run(delta, origin)
                if found is None:
                    asked.setdefault(chain, []).append(("(" + " ".join(origin) + ")", literal))
                else:
                    units.update(unit for (unit,) in found)
        branches: list[str] = []  # asked together
        alone: list[str] = []  # asked one by one
        for chain, listed in asked.items():
            # One branch per chain, each opening with its own VALUES: they must bind the chain's own group (a BIND
            # in a UNION branch would not see VALUES outside it, and the branch would reach every unit of the store).
            for start in range(0, len(listed), VALUES_PER_QUERY):
                chunk = listed[start : start + VALUES_PER_QUERY]
                values = " ".join(row for row, _ in chunk)
                branch = f"{{ VALUES ({' '.join(chain.names)}) {{ {values} }} {chain.steps} }}"
                # Virtuoso 7 fails a UNION whose branch binds a literal ("Unknown language in
                # RDF_LANGUAGE_OF_OBJ"): such a branch is asked alone.
                (alone if any(literal for _, literal in chunk) else branches).append(branch)
        # The others together: a remote store costs a round trip per query, and a batch touches a handful of them.
        queries = [[branch] for branch in alone]
        queries += [branches[at : at + BRANCHES_PER_QUERY] for at in range(0, len(branches), BRANCHES_PER_QUERY)]
        for group in queries:
            union = " UNION ".join(group)
            answer = select(store, f"SELECT DISTINCT {self.target} WHERE {{ {union} }}")
            units.update(term_text(row[self.unit]) for row in answer.rows if self.unit in row)
        return units


@dataclass(frozen=True)
class _Chain:
    links: tuple[Step, ...]  # the steps from the pattern's variables to the unit
    names: tuple[str, ...]  # the pattern's variables the steps go on from (bound by VALUES)
    target: str

    @cached_property
    def _hash(self) -> int:
        return hash((self.links, self.names, self.target))

    def __hash__(self) -> int:
        # Each batch gathers its VALUES rows by chain: the fields' hash, made once (a chain's steps are many).
        return self._hash

    @cached_property
    def join(self) -> DeltaJoin:
        """The chain as followed among a batch's triples."""
        return DeltaJoin(self.links, self.names, [self.target])

    @property
    def steps(self) -> str:
        """The steps as SPARQL."""
        return " ".join(_sparql(link) for link in self.links)


def _sparql(step: Step) -> str:
    return f"BIND ({step.source} AS {step.target})" if isinstance(step, Alias) else step.sparql()


@dataclass(frozen=True, eq=False)
class _Lead:
    """A pattern, and the chains from its variables to the unit (none: the pattern holds the unit itself)."""

    match: PatternMatch
    chains: list[_Chain]

    @cached_property
    def routes(self) -> list[tuple[_Chain, tuple[bool, ...], bool]]:
        """Each chain, which of the matched triple's terms its start takes (True: the subject, else the object),
        and whether it takes the object (a literal there makes its branch be asked alone)."""
        pattern = self.match.pattern
        return [
            (chain, tuple(name == pattern.subject for name in chain.names), pattern.object in chain.names)
            for chain in self.chains
        ]


def chains(plan: ReportPlan, pattern: Pattern, target: str) -> list[_Chain]:
    chains = []
    for path in paths(plan, pattern, target):
        # Only the variables the chain goes on from: a chain from a triple's subject needs no VALUES of its
        # object, and leaving a literal object out lets the branch join the others' UNION.
        names = sorted(name for name in pattern.variables() if _mentions(path, name)) or sorted(pattern.variables())
        chains.append(_Chain(tuple(path), tuple(names), target))
    return chains


def _mentions(path: list[Step], variable: str) -> bool:
    """Whether a chain's steps use `variable`."""
    return any(
        variable in ((step.source, step.target) if isinstance(step, Alias) else step.variables()) for step in path
    )


def paths(plan: ReportPlan, start: Pattern, target: str) -> list[list[Step]]:
    """Chains of SPARQL steps from `start`'s variables to `target`, each made of patterns that hold whenever
    `start` is matched (one chain per UNION branch it may have come through) and of BIND aliases. Unsupported
    when there is none."""
    base = [pattern for pattern in plan.guaranteed_patterns(start) if pattern is not start]
    # From the subject first: a triple's object is often a hub (a robot, a model, a human), and a chain from it
    # reaches every unit of that hub, where a chain from the subject reaches the units of this one triple.
    for sources in _sources(start):
        found = _shortest(sources, base, plan.aliases, target)
        if found is not None:
            return [found]
    chains = [
        chain
        for branch in plan.branch_choices(start)
        for sources in _sources(start)[-1:]
        if (chain := _shortest(sources, base + branch, plan.aliases, target))
    ]
    if not chains:
        raise Unsupported(f"no path from {start.sparql()} to {target}")
    return chains


def _sources(start: Pattern) -> list[set[str]]:
    """The variables a chain may start from, tried in turn: the subject alone, then any of them."""
    subject_only = [{start.subject}] if start.subject.startswith("?") and len(start.variables()) > 1 else []
    return [*subject_only, start.variables()]


def _shortest(
    sources: set[str], usable: list[Pattern], aliases: list[tuple[str, str]], target: str
) -> list[Step] | None:
    """Breadth first over variables from `sources`: a pattern joins its variables; an alias binds one from the
    other."""
    frontier: deque[tuple[str, list[Step]]] = deque((variable, []) for variable in sorted(sources))
    seen = set(sources)
    while frontier:
        variable, path = frontier.popleft()
        if variable == target:
            return path
        steps: list[tuple[str, Step]] = [(other, pattern) for pattern in usable if variable in pattern.variables()
                                         for other in pattern.variables() - {variable}]  # fmt: skip
        steps += [(b if a == variable else a, Alias(variable, b if a == variable else a))
                  for a, b in aliases if variable in (a, b)]  # fmt: skip
        for other, step in steps:
            if other not in seen:
                seen.add(other)
                frontier.append((other, [*path, step]))
    return None


def narrowing(plan: ReportPlan, body: tuple[Pattern, ...]) -> str:
    """The VALUES an EXISTS body narrows its variables with (`VALUES ?kind { foaf:Person }`), which its patterns
    alone do not say."""
    groups = {pattern.group for pattern in body}
    return "".join(
        f"VALUES {variable} {{ {' '.join(sorted(allowed))} }} "
        for (group, variable), allowed in sorted(plan.narrowed.items())
        if group in groups
    )

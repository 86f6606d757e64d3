"""The rule catalog: every file of the rules folder, one rule each, read once at start-up.

A rule is a SPARQL SELECT (`.rq`) whose rows are findings, or a SHACL shapes graph (`.ttl`) whose
validation results are. Either opens with a header of comment lines:

    # id: late-answer                  (the file's name without its extension)
    # title: Message answered late
    # severity: warning                (violation, warning or info: SHACL's three)
    # description: A human's message whose reply came `delay` seconds or more after it.
    # key: ?focus                      (SPARQL: what one finding is about; its rows are kept by it)
    # param delay: decimal = 10 — the longest wait in seconds that is not a finding

A SPARQL rule projects `?focus` (what the finding is about) and `?message` (what it says), and may project
`?time`, `?robot` and `?human` (what the findings page lists and filters by) and any other value; it is
ordered `ORDER BY ?time ?focus`. Its parameters are declared as a report's are (`sparql/catalog.py`): bound
as typed values, never written into the text. A shapes graph takes no parameters: its constraints are its
own. Adding a rule is adding a file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal as TypingLiteral

from pyoxigraph import RdfFormat, parse

from segb_server.backend.reading import ReadingError
from segb_server.backend.services.errors import NotFound, ServiceError
from segb_server.backend.services.sparql.catalog import CatalogQuery, Parameter, read_header, read_header_only
from segb_server.backend.services.sparql.parser import translate_query

Severity = TypingLiteral["violation", "warning", "info"]
SEVERITIES: tuple[Severity, ...] = ("violation", "warning", "info")  # most serious first
FOLDER = "rules"  # catalog names of SPARQL rules: `rules/<id>`
REQUIRED_COLUMNS = ("focus", "message")
LISTED_COLUMNS = ("time", "robot", "human")  # what every finding may carry besides its values
_ORDER = re.compile(r"ORDER\s+BY\s+\?time\s+\?focus\s*$", re.IGNORECASE)
_ID = re.compile(r"[a-z0-9][a-z0-9-]*")


class RuleError(ServiceError):
    """A rule file the server cannot use: the message names the file and what is wrong. The server does not
    start with it (a rule silently left out would pass for a clean log)."""

    code = "rule_error"


@dataclass(frozen=True)
class Rule:
    """One rule file. `query` is the SPARQL rule as a catalog query (None for a shapes graph); `shapes` the
    Turtle of a shapes graph (None for a SPARQL rule)."""

    id: str
    title: str
    severity: Severity
    description: str
    path: Path
    query: CatalogQuery | None = None
    shapes: str | None = None

    @property
    def kind(self) -> str:
        return "sparql" if self.query is not None else "shacl"

    @property
    def parameters(self) -> dict[str, Parameter]:
        return self.query.parameters if self.query is not None else {}

    def describe(self) -> dict[str, object]:
        """The rule as `GET /rules` lists it."""
        return {
            "id": self.id,
            "title": self.title,
            "severity": self.severity,
            "description": self.description,
            "kind": self.kind,
            "file": self.path.name,
            "parameters": [
                {"name": p.name, "type": p.type, "default": p.default, "description": p.help}
                for p in self.parameters.values()
            ],
        }


class RuleCatalog:
    """The rules of one folder, in file-name order. An empty or missing folder is no rule at all (a server may
    run without rules); a file that is not a rule stops start-up, naming it."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        paths = sorted(directory.glob("*.rq")) + sorted(directory.glob("*.ttl")) if directory.is_dir() else []
        rules = [_load(path) for path in sorted(paths, key=lambda path: path.name)]
        seen: set[str] = set()
        for rule in rules:
            if rule.id in seen:
                raise RuleError(f"{rule.path}: another rule already has the id '{rule.id}'")
            seen.add(rule.id)
        self.rules = rules
        self._by_id = {rule.id: rule for rule in rules}

    def get(self, rule_id: str) -> Rule:
        try:
            return self._by_id[rule_id]
        except KeyError:
            raise NotFound(f"No rule '{rule_id}'. Rules: {', '.join(self._by_id) or 'none'}.") from None

    def sparql(self) -> list[Rule]:
        return [rule for rule in self.rules if rule.query is not None]

    def shapes(self) -> list[Rule]:
        return [rule for rule in self.rules if rule.shapes is not None]

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self.rules)

    def __len__(self) -> int:
        return len(self.rules)


def _load(path: Path) -> Rule:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RuleError(f"{path}: cannot be read ({error})") from None
    try:
        header = read_header(text) if path.suffix == ".rq" else read_header_only(text)
    except ReadingError as error:
        raise RuleError(f"{path}: {error}") from None
    meta = header.meta
    rule_id = meta.get("id", path.stem)
    if rule_id != path.stem or not _ID.fullmatch(rule_id):
        raise RuleError(f"{path}: its `# id:` must be its file name without the extension, in a-z, 0-9 and -")
    severity = meta.get("severity", "")
    if severity not in SEVERITIES:
        raise RuleError(f"{path}: `# severity:` must be one of {', '.join(SEVERITIES)}, not '{severity}'")
    title, description = meta.get("title") or rule_id, meta.get("description", "")
    if path.suffix == ".rq":
        query = CatalogQuery(f"{FOLDER}/{rule_id}", title, description, header.text, header.parameters)
        _check_query(path, query)
        return Rule(rule_id, title, severity, description, path, query=query)
    if header.parameters:
        raise RuleError(f"{path}: a shapes graph takes no `# param` (its constraints are its own)")
    try:
        list(parse(text.encode("utf-8"), RdfFormat.TURTLE))
    except SyntaxError as error:
        raise RuleError(f"{path}: not Turtle ({error})") from None
    return Rule(rule_id, title, severity, description, path, shapes=text)


def _check_query(path: Path, query: CatalogQuery) -> None:
    try:
        algebra = translate_query(query.text)
    except Exception as error:  # pyparsing's and rdflib's errors alike: the file is not SPARQL
        raise RuleError(f"{path}: not a SPARQL query ({error})") from None
    if algebra.name != "SelectQuery":
        raise RuleError(f"{path}: a rule is a SELECT query")
    columns = {str(variable) for variable in algebra["PV"]}
    missing = [f"?{name}" for name in REQUIRED_COLUMNS if name not in columns]
    if missing:
        raise RuleError(f"{path}: a rule's SELECT must project {' and '.join(missing)}")
    if not _ORDER.search(query.text.strip()):
        raise RuleError(f"{path}: a rule ends with `ORDER BY ?time ?focus` (findings are listed in time order)")

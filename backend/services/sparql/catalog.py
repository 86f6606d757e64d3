"""The query catalog: every `.rq` file under `sparql/`, its title, description and typed parameters.

A query file opens with a header of comment lines, then the query:

    # title: Emotion timeline
    # description: Every emotion reading with its time, target and robot.
    # param robot: iri — only activities performed by this robot
    # param since: dateTime — readings at or after this time
    # param threshold: decimal = 0.75 — lowest intensity shown
    PREFIX ...
    SELECT ... WHERE { ... FILTER (!BOUND(?param_robot) || ?robot = ?param_robot) ... }

Parameters reach the query as bound values (`segb_server.backend.store.terms.bind_values`), never as text. Parameter
`robot` is the variable `?param_robot`, so a filter's value never collides with the column it filters; a
parameter that is not given is UNDEF (so `!BOUND(?param_x)` switches its filter off) unless it declares a
default. Paging (`LIMIT`/`OFFSET`) is appended by `paged()`, so catalog queries carry no LIMIT of their own.

A file whose header says `# same-as: reports/emotion-timeline` has no query of its own: it runs that
query with its own title, description and parameter defaults (a preset, not a copy).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Literal as TypingLiteral
from typing import cast

from pyoxigraph import Literal, NamedNode

from segb_server.backend.reading import ReadingError, expand
from segb_server.backend.services.errors import InvalidParameter, NotFound, ServiceError
from segb_server.backend.store.base import Bindings, Term

ParameterType = TypingLiteral["iri", "dateTime", "decimal", "integer", "string"]
XSD = "http://www.w3.org/2001/XMLSchema#"

_HEADER = re.compile(r"#\s*([a-z][a-z-]*):\s*(.*)")  # title, description, same-as; rules add their own
PARAMETER_VARIABLE_PREFIX = "param_"
_PARAM = re.compile(
    r"#\s*param\s+(?P<name>[A-Za-z_]\w*)\s*:\s*(?P<type>iri|dateTime|decimal|integer|string)"
    r"(?:\s*=\s*(?P<default>\S+))?\s*(?:[—-]+\s*(?P<help>.*))?"
)


@dataclass(frozen=True)
class Parameter:
    name: str
    type: ParameterType
    help: str = ""
    default: str | None = None


@dataclass(frozen=True)
class CatalogQuery:
    """One `.rq` file. `name` is its path under `sparql/` without the extension, e.g. `reports/participants`."""

    name: str
    title: str
    description: str
    text: str
    parameters: dict[str, Parameter] = field(default_factory=dict)
    same_as: str | None = None  # a preset's base: the query whose text and parameters it has

    def bindings(self, values: Mapping[str, str | None]) -> Bindings:
        """Typed terms for the given values (strings from a query string); 422 naming a bad parameter."""
        unknown = sorted(set(values) - set(self.parameters))
        if unknown:
            raise InvalidParameter(unknown[0], f"not a parameter of {self.name}")
        bound: dict[str, Term | None] = {}
        for name, parameter in self.parameters.items():
            raw = values.get(name)
            if raw is None or raw == "":
                raw = parameter.default
            bound[PARAMETER_VARIABLE_PREFIX + name] = None if raw is None else to_term(parameter, raw)
        if "since" in self.parameters and "until" in self.parameters:
            check_window(values.get("since"), values.get("until"))
        return bound


IRI_SCHEMES = ("http://", "https://", "urn:")  # what a parameter naming a resource of the log may start with


def is_absolute_iri(text: str) -> bool:
    """Whether `text` is an IRI a parameter may name (`to_term`'s rule, for validators that cannot raise its 422)."""
    try:
        to_term(Parameter("iri", "iri"), text)
    except InvalidParameter:
        return False
    return True


def check_window(since: str | None, until: str | None) -> None:
    """A time window may not end before it starts: 422 naming `until` (both already valid, see `to_term`)."""
    if since and until and _moment(until) < _moment(since):
        raise InvalidParameter("until", "is before `since`")


def _moment(raw: str) -> datetime:
    return datetime.fromisoformat(raw.replace("Z", "+00:00"))


class _BadValue(ValueError):
    """A value of the right syntax that breaks a rule; its message is shown as is."""


def to_term(parameter: Parameter, raw: str) -> Term:
    """Parse one parameter value into the RDF term its declared type calls for."""
    kind = parameter.type
    try:
        if kind == "iri":
            if not raw.startswith(IRI_SCHEMES):
                raise _BadValue("must be an absolute IRI (http://, https:// or urn:)")
            return NamedNode(raw)
        if kind == "dateTime":
            moment = _moment(raw)
            if moment.tzinfo is None:
                raise _BadValue("needs a time of day and a time zone, e.g. 2026-03-10T09:00:00Z")
            return Literal(moment.isoformat(), datatype=NamedNode(XSD + "dateTime"))
        if kind == "decimal":
            number = Decimal(raw)
            if not number.is_finite():
                raise _BadValue("must be a finite number")
            return Literal(str(number), datatype=NamedNode(XSD + "decimal"))
        if kind == "integer":
            return Literal(str(int(raw)), datatype=NamedNode(XSD + "integer"))
        return Literal(raw)
    except _BadValue as error:
        raise InvalidParameter(parameter.name, str(error)) from None
    except (ValueError, InvalidOperation):
        raise InvalidParameter(parameter.name, f"'{raw}' is not a valid {kind}") from None


def paged(text: str, limit: int | None, offset: int | None) -> str:
    """The query with LIMIT/OFFSET appended (integers only, so nothing user-written enters the text)."""
    suffix = ""
    if limit is not None:
        suffix += f"\nLIMIT {int(limit)}"
    if offset:
        suffix += f"\nOFFSET {int(offset)}"
    return text + suffix


@dataclass(frozen=True)
class Header:
    """A query file's header: its `# name: value` lines, its parameters, and the whole text."""

    meta: dict[str, str]
    parameters: dict[str, Parameter]
    text: str


def read_header(text: str) -> Header:
    """A query file's header and its text, each `%rule(…)` of reading expanded (backend/reading.py)."""
    header = read_header_only(text)
    return Header(header.meta, header.parameters, expand(text))


def read_header_only(text: str) -> Header:
    """A file's header, its text as it is (a shapes graph's, which has no rules of reading)."""
    meta: dict[str, str] = {}
    parameters: dict[str, Parameter] = {}
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        if match := _PARAM.match(line):
            kind = cast(ParameterType, match["type"])  # the pattern admits only the five types
            parameters[match["name"]] = Parameter(match["name"], kind, (match["help"] or "").strip(), match["default"])
        elif match := _HEADER.match(line):
            meta[match.group(1)] = match.group(2).strip()
    return Header(meta, parameters, text)


def _resolve(name: str, headers: dict[str, Header]) -> CatalogQuery:
    """The query of one file; a `same-as` preset takes its base's text and parameters, then its own overrides."""
    header = headers[name]
    text, parameters = header.text, header.parameters
    if base_name := header.meta.get("same-as"):
        base = headers.get(base_name)
        if base is None or "same-as" in base.meta:
            raise ValueError(f"{name}.rq: same-as names '{base_name}', which is not a query of its own")
        text, parameters = base.text, {**base.parameters, **header.parameters}
    title, description = header.meta.get("title", name), header.meta.get("description", "")
    return CatalogQuery(name, title, description, text, parameters, header.meta.get("same-as"))


class CatalogError(ServiceError):
    """The query directory is missing, empty, or lacks a query the server needs: the server cannot start."""

    code = "catalog_error"


def _read(path: Path) -> Header:
    try:
        return read_header(path.read_text(encoding="utf-8"))
    except ReadingError as error:
        raise CatalogError(f"{path}: {error}") from None


class Catalog:
    """All queries of a `sparql/` directory, loaded once at start-up.

    `required` names queries the server cannot work without; a missing one (or an empty directory, as a
    packaging mistake would leave) stops start-up with a CatalogError naming the directory."""

    def __init__(self, directory: Path, required: tuple[str, ...] = ()) -> None:
        self.directory = directory
        headers = {
            path.relative_to(directory).with_suffix("").as_posix(): _read(path)
            for path in sorted(directory.rglob("*.rq"))
        }
        if not headers:
            raise CatalogError(f"No SPARQL queries (.rq files) in {directory}: set SPARQL_DIR to the sparql/ folder.")
        self._queries = {name: _resolve(name, headers) for name in headers}
        missing = [name for name in required if not self._has(name)]
        if missing:
            raise CatalogError(f"The SPARQL folder {directory} lacks {', '.join(missing)}.")

    def _has(self, name: str) -> bool:
        """A query of that name, or with a trailing `/`, any query in that folder."""
        if name.endswith("/"):
            return any(query.startswith(name) for query in self._queries)
        return name in self._queries

    def get(self, name: str) -> CatalogQuery:
        try:
            return self._queries[name]
        except KeyError:
            raise NotFound(f"No query named '{name}'.") from None

    def under(self, folder: str) -> list[CatalogQuery]:
        """Queries in one folder of the catalog (e.g. `reports`), in file-name order."""
        prefix = folder.rstrip("/") + "/"
        return [query for name, query in self._queries.items() if name.startswith(prefix)]

    def __iter__(self) -> Iterator[CatalogQuery]:
        return iter(self._queries.values())

"""Checking a document the way POST /ttl would take it, writing nothing (POST /ttl/validate).

The report has the reference backend's shape (`valid`, `syntax_ok`, `semantic_ok`, `triple_count`, `issues`)
and two kinds of findings:

* what the ingest refuses: the body goes through the ingest's own steps (payloads.py, parsing.py, the write
  scopes of service.py), so this verdict cannot drift from POST /ttl: syntax errors with line and column
  (relative IRIs among them), RDF 1.2 triple terms, the triple and token limits, an empty document, subjects
  outside the caller's write scopes. `ingest_ok` says whether POST /ttl would store the document for the
  same caller.
* the reference's rules on the PyPI client's vocabulary (a literal where a resource belongs, timestamps that
  are not xsd:dateTime, intensities outside [0, 1], subjects without a type). The ingest does not enforce
  them, but the reference's web UI inserts only what validates, so their errors make `valid` false.

Body-level limits (MAX_BODY_BYTES, MAX_DECOMPRESSED_BYTES) and malformed requests are not findings: they are
refused with the same 413/415/422 as POST /ttl.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime
from decimal import Decimal, InvalidOperation

from pyoxigraph import BlankNode, Literal, NamedNode, Quad, Triple

from segb_server.backend.auth import PermissionDenied
from segb_server.backend.reading import TIME_PREDICATES
from segb_server.backend.services.errors import EmptyPayload, InvalidRdf, PayloadTooLarge
from segb_server.backend.services.ingest.parsing import parse_quads
from segb_server.backend.services.ingest.payloads import decode_ingest_body
from segb_server.backend.services.ingest.service import check_scopes
from segb_server.backend.store.terms import term_text
from segb_server.backend.vocabulary import PREFIXES

MAX_ISSUES = 1000  # a report stays small whatever the document; the counts stay exact

RDF_TYPE = PREFIXES["rdf"] + "type"
XSD_DATETIME = PREFIXES["xsd"] + "dateTime"
PROV, SEGB, ONYX = PREFIXES["prov"], PREFIXES["segb"], PREFIXES["onyx"]
# The reference validator's predicates: these must point at resources...
OBJECT_PROPERTIES = frozenset(
    [PROV + name for name in ("wasAssociatedWith", "used", "wasInfluencedBy", "wasGeneratedBy", "generated")]
    + [PROV + "specializationOf", SEGB + "triggeredByActivity", SEGB + "producedEntityResult"]
)
# ...these must be xsd:dateTime literals...
TIME_PROPERTIES = frozenset(TIME_PREDICATES)
# ...and these are an emotion's intensity (a number in [0, 1]) and category (a resource).
INTENSITY = ONYX + "hasEmotionIntensity"
CATEGORY = ONYX + "hasEmotionCategory"
CHECKED = OBJECT_PROPERTIES | TIME_PROPERTIES | {INTENSITY, CATEGORY}

# The shape of an xsd:dateTime lexical form (years 0001 to 9999); datetime.fromisoformat then checks the
# ranges (alone it would also take forms XSD does not, such as a date without a time).
_DATETIME_SHAPE = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:\d\d)?")


@dataclass(frozen=True)
class Issue:
    severity: str  # "error" or "warning"
    code: str
    message: str
    focus_node: str | None = None
    predicate: str | None = None
    value: str | None = None
    line: int | None = None
    column: int | None = None


@dataclass
class ValidationReport:
    """`valid` and `semantic_ok`: no finding of severity error (warnings do not count), as the reference
    reports them; `triple_count`: the triples POST /ttl would receive (0 when it would refuse the document)."""

    syntax_ok: bool = True
    ingest_ok: bool = True
    triple_count: int = 0
    issues: list[Issue] = field(default_factory=list)
    findings: list[dict[str, object]] = field(default_factory=list)  # the audit rules' (services/rules/offline.py)
    error_count: int = 0
    warning_count: int = 0

    @property
    def valid(self) -> bool:
        return self.error_count == 0

    @property
    def issues_truncated(self) -> bool:
        return self.error_count + self.warning_count > len(self.issues)

    def add(self, issue: Issue) -> None:
        if issue.severity == "error":
            self.error_count += 1
        else:
            self.warning_count += 1
        if len(self.issues) < MAX_ISSUES:
            self.issues.append(issue)

    def refused(self, issue: Issue) -> ValidationReport:
        """The report on a document POST /ttl would refuse, for the reason `issue` gives."""
        self.ingest_ok = False
        self.add(issue)
        return self


def validate_body(
    body: bytes,
    *,
    content_type: str | None,
    content_encoding: str | None,
    max_decompressed_bytes: int,
    max_triples: int,
    scopes: tuple[str, ...] = (),
    rules: Callable[[list[Quad], bytes], list[dict[str, object]]] | None = None,
) -> ValidationReport:
    """The report on a POST /ttl body from a caller with write `scopes`, with what the audit `rules` find in the
    document when given (the rules' service runs them: this module hands them what it parsed). Raises the ingest's
    own errors for a request it would refuse before reading any RDF (unsupported type or encoding, bad JSON, too
    large once decompressed). Blank nodes are checked as they came: skolemising them refuses nothing."""
    report = ValidationReport()
    try:
        payload = decode_ingest_body(
            body,
            content_type=content_type,
            content_encoding=content_encoding,
            claimed_user=None,
            max_decompressed_bytes=max_decompressed_bytes,
        )
    except EmptyPayload as error:
        return report.refused(Issue("error", "SEM_EMPTY_GRAPH", f"The document holds no triples. {error.message}"))
    try:
        quads = parse_quads(payload.data, payload.rdf_format, max_triples=max_triples)
    except InvalidRdf as error:
        line, column = error.details.get("line"), error.details.get("column")
        # The parser always gives a position; a refusal without one is about content that parsed.
        report.syntax_ok = line is None
        code = "INGEST_REFUSED" if line is None else "TTL_SYNTAX_ERROR"
        return report.refused(Issue("error", code, error.message, line=line, column=column))
    except PayloadTooLarge as error:
        return report.refused(Issue("error", "INGEST_TOO_LARGE", error.message))
    try:
        check_scopes(quads, scopes)
    except PermissionDenied as error:
        return report.refused(Issue("error", "INGEST_OUT_OF_SCOPE", str(error)))
    report.triple_count = len(quads)
    if not quads:
        report.add(Issue("error", "SEM_EMPTY_GRAPH", "The document holds no triples."))
        return report
    for issue in semantic_issues(quads):
        report.add(issue)
    if rules is not None:
        report.findings = rules(quads, payload.data)
    return report


def semantic_issues(quads: list[Quad]) -> Iterator[Issue]:
    """The reference validator's rules: errors in document order, then one warning per untyped subject."""
    typed: set[str] = set()
    checked_subjects: set[str] = set()
    for quad in quads:
        subject, predicate, value = _text(quad.subject), quad.predicate.value, quad.object
        if predicate == RDF_TYPE:
            typed.add(subject)
            if isinstance(value, Literal):
                yield _finding("SEM_RDF_TYPE_LITERAL", "rdf:type must point at a class, not a literal.", quad)
            continue
        if predicate not in CHECKED:
            continue
        checked_subjects.add(subject)
        if predicate in OBJECT_PROPERTIES and isinstance(value, Literal):
            message = "This property links resources; its object is a literal."
            yield _finding("SEM_OBJECT_PROPERTY_LITERAL", message, quad)
        elif predicate == CATEGORY and isinstance(value, Literal):
            yield _finding("SEM_EMOTION_CATEGORY_LITERAL", "An emotion category is a resource, not a literal.", quad)
        elif predicate in TIME_PROPERTIES:
            yield from _time_issues(quad)
        elif predicate == INTENSITY:
            yield from _intensity_issues(quad)
    for subject in sorted(checked_subjects - typed):
        yield Issue(
            "warning",
            "SEM_SUBJECT_WITHOUT_TYPE",
            "This resource has provenance, time or emotion properties but no rdf:type.",
            focus_node=subject,
        )


def _time_issues(quad: Quad) -> Iterator[Issue]:
    value = quad.object
    if not isinstance(value, Literal):
        yield _finding("SEM_DATETIME_NOT_LITERAL", "A timestamp must be a literal.", quad)
    elif value.datatype != NamedNode(XSD_DATETIME):
        message = f"A timestamp must be typed xsd:dateTime, not <{value.datatype.value}>."
        yield _finding("SEM_DATETIME_WRONG_DATATYPE", message, quad)
    elif not is_xsd_datetime(value.value):
        yield _finding("SEM_DATETIME_INVALID_LEXICAL", "The value is not a valid xsd:dateTime.", quad)


def _intensity_issues(quad: Quad) -> Iterator[Issue]:
    value = quad.object
    if not isinstance(value, Literal):
        yield _finding("SEM_INTENSITY_NOT_LITERAL", "An emotion intensity must be a literal number.", quad)
        return
    try:
        number = Decimal(value.value)
    except InvalidOperation:
        number = None
    if number is None or not number.is_finite():  # NaN and infinities are not intensities (the reference crashed)
        yield _finding("SEM_INTENSITY_NOT_NUMERIC", "An emotion intensity must be a finite number.", quad)
    elif not 0 <= number <= 1:
        yield _finding("SEM_INTENSITY_OUT_OF_RANGE", "An emotion intensity must be between 0 and 1.", quad)


def is_xsd_datetime(text: str) -> bool:
    if not _DATETIME_SHAPE.fullmatch(text):
        return False
    try:
        datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return False
    return True


def _finding(code: str, message: str, quad: Quad) -> Issue:
    return Issue("error", code, message, _text(quad.subject), quad.predicate.value, _text(quad.object))


def _text(term: NamedNode | BlankNode | Literal | Triple) -> str:
    """An IRI or a literal's lexical form; a blank node as `_:id` (triple terms are refused before)."""
    return term.value if isinstance(term, NamedNode | Literal) else term_text(term)

"""What robots did as OpenTelemetry spans: one trace per interaction (the shared event the activities were about),
a span per activity under it (listening, recognition, response, …), a span per model it invoked (`gen_ai.*`) and
per state it produced under that, and a link from each activity to what triggered it.

The rows come from `sparql/traces/activities.rq`, which reads the log by backend/reading.py's rules (who spoke,
whose a message is, an event's time). A person appears only as the IRI the log gives them (their pseudonymous id),
never by name, and a message by its length unless TRACE_MESSAGE_TEXT is on. Ids are derived from the IRIs, so the
spans of one interaction sent from several posts (or exported again) share their trace and parents.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime

from opentelemetry.sdk.resources import Resource
from opentelemetry.sdk.trace import ReadableSpan
from opentelemetry.sdk.util.instrumentation import InstrumentationScope
from opentelemetry.trace import Link, SpanContext, SpanKind, TraceFlags

from segb_server.backend import __version__
from segb_server.backend.reading import activity_kind
from segb_server.backend.store.base import Term

SCOPE = InstrumentationScope("segb.robots", __version__)
# Phoenix files spans under this project (OpenInference's resource attribute); other tools read service.name.
# OpenTelemetry's own OTEL_RESOURCE_ATTRIBUTES (and OTEL_SERVICE_NAME) may name others: theirs win.
PROJECT = "segb"
_DETECTED = Resource.create().attributes  # the SDK's own, and the environment's (its default service name aside)
RESOURCE = Resource({"service.name": "segb", "openinference.project.name": PROJECT}).merge(
    Resource(
        {
            key: value
            for key, value in _DETECTED.items()
            if not (key == "service.name" and str(value).startswith("unknown_service"))
        }
    )
)
SAMPLED = TraceFlags(TraceFlags.SAMPLED)

Row = dict[str, Term]


def trace_id(iri: str) -> int:
    return int.from_bytes(hashlib.sha256(iri.encode()).digest()[:16], "big") or 1


def span_id(*iris: str) -> int:
    return int.from_bytes(hashlib.sha256(" ".join(iris).encode()).digest()[:8], "big") or 1


def nanoseconds(term: Term | None) -> int | None:
    if term is None:
        return None
    try:
        return int(datetime.fromisoformat(term.value.replace("Z", "+00:00")).timestamp() * 1e9)
    except (ValueError, AttributeError):
        return None


@dataclass
class Activity:
    """One activity's rows, gathered: what its span and its children's spans are made of."""

    iri: str
    robot: str
    start: int
    end: int
    types: set[str] = field(default_factory=set)
    label: str | None = None
    event: str | None = None
    event_time: int | None = None
    human: str | None = None
    triggers: dict[str, str | None] = field(default_factory=dict)  # triggering activity → its shared event
    models: dict[str, dict[str, str]] = field(default_factory=dict)
    messages: dict[str, dict[str, str]] = field(default_factory=dict)
    states: dict[str, int] = field(default_factory=dict)

    @property
    def trace(self) -> int:
        return trace_id(self.event or self.iri)

    @property
    def kind(self) -> str:
        return activity_kind(self.types)


def activities(rows: Iterable[Row]) -> list[Activity]:
    """The query's rows (several an activity: its types, models, messages, states, triggers) as activities."""
    found: dict[str, Activity] = {}
    for row in rows:
        start = nanoseconds(row.get("time"))
        if start is None:
            continue
        iri = row["activity"].value
        activity = found.get(iri)
        if activity is None:
            end = nanoseconds(row.get("ended"))
            activity = found[iri] = Activity(iri, row["robot"].value, start, max(end or start, start))
        activity.types.add(row["type"].value)
        activity.label = _text(row, "label") or activity.label
        activity.event = _text(row, "event") or activity.event
        activity.event_time = nanoseconds(row.get("eventTime")) or activity.event_time
        activity.human = _text(row, "activityHuman") or activity.human
        if trigger := _text(row, "trigger"):
            activity.triggers[trigger] = _text(row, "triggerEvent")
        if model := _text(row, "model"):
            activity.models[model] = {
                name: value for name in ("modelName", "version", "providerName") if (value := _text(row, name))
            }
        if message := _text(row, "message"):
            activity.messages[message] = {
                name: value for name in ("speaker", "human", "text") if (value := _text(row, name)) is not None
            }
        if (state := _text(row, "state")) and (moment := nanoseconds(row.get("stateTime"))):
            activity.states[state] = moment
    return list(found.values())


def _text(row: Row, column: str) -> str | None:
    term = row.get(column)
    return None if term is None else term.value


def interaction_span(activity: Activity) -> ReadableSpan:
    """The interaction's own span, the root of its trace: the shared event, at its time."""
    key = activity.event or activity.iri
    start = activity.event_time or activity.start
    attributes: dict[str, str] = {"openinference.span.kind": "AGENT", "segb.shared_event": key}
    if activity.human:
        attributes["segb.human"] = activity.human
    return ReadableSpan(
        "interaction",
        _context(activity.trace, span_id(key)),
        None,
        RESOURCE,
        attributes,
        kind=SpanKind.INTERNAL,
        start_time=start,
        end_time=max(start, activity.end),
        instrumentation_scope=SCOPE,
    )


def activity_spans(activity: Activity, *, with_text: bool) -> list[ReadableSpan]:
    """The activity's span under its interaction's, and its models' and states' spans under it."""
    root = _context(activity.trace, span_id(activity.event or activity.iri))
    own = _context(activity.trace, span_id(activity.iri))
    attributes: dict[str, str | int] = {
        "openinference.span.kind": "CHAIN",
        "segb.robot": activity.robot,
        "segb.activity": activity.iri,
        "segb.activity.kind": activity.kind,
    }
    if activity.label:
        attributes["segb.activity.label"] = activity.label
    if activity.event:
        attributes["segb.shared_event"] = activity.event
    humans = {told["human"] for told in activity.messages.values() if "human" in told} or (
        {activity.human} if activity.human else set()
    )
    if humans:
        attributes["segb.human"] = sorted(humans)[0]
    for index, (message, told) in enumerate(sorted(activity.messages.items())):
        prefix = f"segb.message.{index}"
        attributes[f"{prefix}.iri"] = message
        attributes[f"{prefix}.speaker"] = told.get("speaker", "unidentified")
        attributes[f"{prefix}.length"] = len(told.get("text", ""))
        if with_text and "text" in told:
            attributes[f"{prefix}.text"] = told["text"]
            attributes["output.value" if told.get("speaker") == "robot" else "input.value"] = told["text"]
    links = [
        Link(_context(trace_id(event or trigger), span_id(trigger)), {"segb.link": "triggered-by"})
        for trigger, event in sorted(activity.triggers.items())
    ]
    spans = [
        ReadableSpan(
            activity.kind,
            own,
            root,
            RESOURCE,
            attributes,
            links=links,
            start_time=activity.start,
            end_time=activity.end,
            instrumentation_scope=SCOPE,
        )
    ]
    for model, described in sorted(activity.models.items()):
        spans.append(_model_span(activity, own, model, described))
    for state, moment in sorted(activity.states.items()):
        spans.append(
            ReadableSpan(
                "state",
                _context(activity.trace, span_id(activity.iri, state)),
                own,
                RESOURCE,
                {"openinference.span.kind": "CHAIN", "segb.robot": activity.robot, "segb.state": state},
                start_time=moment,
                end_time=moment,
                instrumentation_scope=SCOPE,
            )
        )
    return spans


def _model_span(activity: Activity, parent: SpanContext, model: str, described: dict[str, str]) -> ReadableSpan:
    """A model invocation under the GenAI conventions (and OpenInference's, which Phoenix shows)."""
    name = described.get("modelName", model)
    attributes: dict[str, str] = {
        "openinference.span.kind": "LLM",
        "gen_ai.system": described.get("providerName", "unknown"),
        "gen_ai.request.model": name,
        "gen_ai.operation.name": "chat" if activity.kind == "response" else "inference",
        "llm.model_name": name,
        "segb.model": model,
        "segb.model.label": name,
        "segb.robot": activity.robot,
    }
    if "providerName" in described:
        attributes["llm.provider"] = described["providerName"]
    if "version" in described:
        attributes["segb.model.version"] = described["version"]
    return ReadableSpan(
        f"{attributes['gen_ai.operation.name']} {name}",
        _context(activity.trace, span_id(activity.iri, model)),
        parent,
        RESOURCE,
        attributes,
        kind=SpanKind.CLIENT,
        start_time=activity.start,
        end_time=activity.end,
        instrumentation_scope=SCOPE,
    )


def _context(trace: int, span: int) -> SpanContext:
    return SpanContext(trace, span, is_remote=False, trace_flags=SAMPLED)


def spans_of(rows: Iterable[Row], *, with_text: bool, roots_sent: set[str] | None = None) -> list[ReadableSpan]:
    """Every span the rows make. `roots_sent`: interactions whose root span went already (live traces send it once
    a process); each root sent now is added."""
    spans: list[ReadableSpan] = []
    for activity in activities(rows):
        key = activity.event or activity.iri
        if roots_sent is None or key not in roots_sent:
            spans.append(interaction_span(activity))
            if roots_sent is not None:
                roots_sent.add(key)
        spans += activity_spans(activity, with_text=with_text)
    return _unique(spans)


def _unique(spans: list[ReadableSpan]) -> list[ReadableSpan]:
    """One span an id (an interaction's root comes once per activity of it in a window)."""
    seen: dict[int, ReadableSpan] = {}
    for span in spans:
        assert span.context is not None
        kept = seen.get(span.context.span_id)
        if kept is None or (span.end_time or 0) > (kept.end_time or 0):
            seen[span.context.span_id] = span
    return list(seen.values())

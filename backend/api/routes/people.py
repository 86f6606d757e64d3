"""People's data (admin): erase one person everywhere (POST /humans/erase), and give them what is held about them
(GET /humans/{iri}/export, as RDF or as a page to read)."""

from __future__ import annotations

from fastapi import APIRouter, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from pydantic import BaseModel, Field
from pyoxigraph import NamedNode

from segb_server.backend.api.deps import Admin, ServicesDep
from segb_server.backend.services.formats import PERSON_EXPORTS, names, negotiate
from segb_server.backend.services.graph.export import write_graph
from segb_server.backend.services.people.erasure import MAX_REASON, ErasurePreview
from segb_server.backend.services.people.mentions import Scope
from segb_server.backend.services.people.story_page import PAGE_POLICY, story_page
from segb_server.backend.services.sparql.catalog import Parameter, to_term

router = APIRouter(tags=["people"])


class ErasureRequest(BaseModel):
    iri: str = Field(description="The person's IRI, as the robots logged it (e.g. …/human_maria).", max_length=2000)
    reason: str = Field(
        "",
        description="Why (kept in the ledger for good, in the erasure's record: do not name the person). Required "
        "unless `dry_run`.",
        max_length=MAX_REASON,
    )
    dry_run: bool = Field(False, description="Only say what the erasure would take; nothing is written.")
    mentions: Scope = Field(
        "concerning",
        description='Where the person\'s names are replaced by the mark "[erased]" in the texts kept: '
        "`concerning` (a reply to them, an event about them, a message of their conversations, by the rules of "
        "reading) or `store` (every text of the store, someone else's included).",
    )


class ErasurePreviewAnswer(BaseModel):
    dry_run: bool = Field(True, description="Always true: nothing was written.")
    message: str
    iri: str
    resources: int = Field(description="Resources the erasure would take, the person included.")
    kinds: dict[str, int] = Field(
        description="Those resources by kind: human, message, emotion (annotations and emotions), shared-event, "
        "observation, procedure, property, state, …"
    )
    triples: int = Field(description="Triples of the store naming one of them (as subject or object).")
    left_out: int = Field(
        description="Resources the rule reached but would leave alone: an agent (a person, a robot), a class or a "
        "predicate linked to the person's resources, or what was reached only through one of them."
    )
    mentions: int = Field(description='Texts kept that would have the person\'s names replaced by "[erased]".')

    @classmethod
    def of(cls, preview: ErasurePreview) -> ErasurePreviewAnswer:
        return cls(
            message=f"Would erase {preview.resources} resources ({preview.triples} triples) and redact the "
            f"person's names in {preview.mentions} texts; nothing was written.",
            iri=preview.human, resources=preview.resources, kinds=preview.kinds, triples=preview.triples,
            left_out=preview.left_out, mentions=preview.mentions,
        )  # fmt: skip


class ErasureAnswer(BaseModel):
    message: str
    log_id: str = Field(description="The erasure's entry in the ledger.")
    sequence: int
    triples_removed: int = Field(description="Triples removed from the posts' content (and from the store).")
    receipts_redacted: int = Field(description="Posts whose content lost triples.")
    resources: int = Field(description="Resources erased with the person (their messages, emotions read, …).")
    mentions_redacted: int = Field(
        description="Texts kept with the person's names replaced by \"[erased]\" (a robot's greeting, an "
        "activity's label): the old text left with the rest, the redacted one took its place."
    )
    name_still_mentioned: int = Field(
        description="Texts left in the store that still contain one of the person's names: ones that concern "
        "someone else (with `mentions: store`, none). Look for them with /sparql."
    )
    seconds: dict[str, float] = Field(
        description="How long each step took: found (the rule run on the store), journaled (the posts redacted and "
        "the entry appended), applied (the store without the triples), forgotten (shared contexts, server log, "
        "copies for SPARQL), viewed (the views built again), views_compacted, checked."
    )
    views_rebuilt: bool = Field(
        description="Whether the reports' rows and the graph index were built again before answering; until they "
        "are, reports are evaluated by their queries and the graph answers 503."
    )


@router.post(
    "/humans/erase",
    response_model=ErasureAnswer | ErasurePreviewAnswer,
    summary="Erase one person everywhere",
    description=(
        "Erases a person (GDPR Art. 17) from the store, every view, the journal's posts, the shared contexts, the "
        "copies users' SPARQL runs on and the server log: the person, the messages they sent, the emotions read on "
        "them, the shared events about them alone and their observations (the rule: `sparql/people/erase.rq`). "
        "What others said stays; a robot's reply stays and loses its links to what was erased. The person's names "
        '(first, full, given names and labels the log states for them) are replaced by "[erased]" in the texts '
        "kept that concern them (`sparql/people/mentions.rq`), or in every text with `mentions: store`. The "
        "erasure is "
        "one entry of the ledger (who, when, why, which posts, how many triples), which keeps verifying. "
        "A robot re-sending the erased triples later has them held back (counted as `triples_withheld`). "
        "It takes only what concerns that person: each link the rule follows must lead to a resource of the "
        "expected kind, and never to another agent (a person, a robot), a class or a predicate. "
        "With `dry_run: true` it answers what the erasure would take, counted by kind, and writes nothing. "
        "404 when nothing about the IRI is held; 422 for an IRI the log does not type as a person (oro:Human, "
        "foaf:Person, prov:Person), a class or a predicate, an IRI that is not absolute or an empty reason."
    ),
)
def erase_human(body: ErasureRequest, services: ServicesDep, principal: Admin) -> ErasureAnswer | ErasurePreviewAnswer:
    # A plain `def` route runs in the thread pool: the erasure reads and writes the journal and the store.
    iri = to_term(Parameter("iri", "iri"), body.iri.strip()).value
    if body.dry_run:
        return ErasurePreviewAnswer.of(services.erasure.preview(iri, body.mentions))
    done = services.erasure.erase_human(iri, body.reason, principal.username, body.mentions)
    record = done.receipt
    return ErasureAnswer(
        message=f"Erased: {record.triples_removed} triples removed.",
        log_id=record.log_id,
        sequence=record.sequence,
        triples_removed=record.triples_removed,
        receipts_redacted=done.receipts_redacted,
        resources=done.resources,
        views_rebuilt=done.views_rebuilt,
        mentions_redacted=done.mentions_redacted,
        name_still_mentioned=done.name_still_mentioned,
        seconds=done.seconds,
    )


@router.get(
    "/humans/{iri:path}/export",
    summary="Everything held about one person",
    description=(
        "A person's data (GDPR Art. 15): every triple the store holds about them — exactly what erasing them "
        "would remove — as Turtle, N-Triples or JSON-LD, or (`text/html`, the default for a browser; "
        "`?format=html`) a self-contained page telling it in time order: what they said and to which robot, what "
        "a robot replied, which emotions were read on them with which model, when they were seen. The IRI is "
        "percent-encoded in the path; the server log writes the path without it. 404 when nothing is held."
    ),
    responses={200: {"content": {fmt.media_type: {} for fmt in PERSON_EXPORTS}}, 404: {}, 406: {}},
)
async def export_human(
    iri: str,
    request: Request,
    services: ServicesDep,
    principal: Admin,
    format: str | None = Query(None, description=f"{', '.join(names(PERSON_EXPORTS))}; overrides Accept."),
) -> Response:
    fmt = negotiate(PERSON_EXPORTS, request.headers.get("accept"), format, what="a person's data")
    human = to_term(Parameter("iri", "iri"), iri).value
    data = await run_in_threadpool(services.people_export.export, human)
    disposition = {"Content-Disposition": f'attachment; filename="person.{fmt.extension}"'}
    if fmt.rdf is None:
        headers = {**disposition, "Content-Security-Policy": PAGE_POLICY}
        return Response(story_page(data), media_type=fmt.content_type, headers=headers)
    body = b"".join(write_graph([data.triples], fmt, NamedNode(services.store.graph_uri)))
    return Response(body, media_type=fmt.content_type, headers=disposition)

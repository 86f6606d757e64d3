"""Which findings are about the messages, activities and emotions a page shows (the marks on the explain page
and the conversations report): asked of the API by the nodes' IRIs, `GET /findings?focus=…`."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable
from typing import Any

from fastapi import Request

from segb_server.ui.api_client import BackendError
from segb_server.ui.pages import backend, token

FOCUS_PER_REQUEST = 200  # the API's limit on `focus` values in one request


async def findings_about(request: Request, iris: Iterable[object]) -> dict[str, list[dict[str, Any]]]:
    """Each IRI's findings (IRIs with none are left out). A viewer the API refuses the findings gets no marks."""
    wanted = sorted({str(iri) for iri in iris if iri})
    chunks = [wanted[start : start + FOCUS_PER_REQUEST] for start in range(0, len(wanted), FOCUS_PER_REQUEST)]

    async def ask(chunk: list[str]) -> list[dict[str, Any]]:
        answer = await backend(request).get_json("/findings", token=token(request), params={"focus": chunk})
        findings: list[dict[str, Any]] = answer["findings"]
        return findings

    try:
        answers = await asyncio.gather(*(ask(chunk) for chunk in chunks))
    except BackendError:
        return {}
    marks: dict[str, list[dict[str, Any]]] = {}
    for findings in answers:
        for found in findings:
            marks.setdefault(str(found["focus"]), []).append(found)
    return marks

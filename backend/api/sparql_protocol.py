"""Reading a SPARQL 1.1 Protocol request, however it arrives: GET parameters, a POST form, a POST query body."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import parse_qs

from fastapi import Request

from segb_server.backend.services.errors import UnsupportedMediaType
from segb_server.backend.services.sparql.guard import query_rejected

# rdflib's name for "the default graph" (DATASET_DEFAULT_GRAPH_ID): its SPARQLStore sends it as
# `default-graph-uri` for queries through a Dataset, meaning the endpoint's default graph, which is ours.
RDFLIB_DEFAULT_GRAPH = "urn:x-rdflib:default"


@dataclass(frozen=True)
class ProtocolRequest:
    """One query request: the query, the `format` asked for, and the dataset parameters."""

    query: str
    formats: list[str]  # every `format` value given; a hint (services.formats.format_hint)
    default_graphs: list[str]
    named_graphs: list[str]

    def check_dataset(self, graph_uri: str) -> None:
        """The dataset parameters may only restate the fixed dataset (the events graph as default graph)."""
        if self.named_graphs or any(graph not in (graph_uri, RDFLIB_DEFAULT_GRAPH) for graph in self.default_graphs):
            raise query_rejected(
                "dataset",
                f"The dataset is fixed: the events graph <{graph_uri}> is the default graph and there are no "
                "named graphs, so 'default-graph-uri' may only name it and 'named-graph-uri' is not supported.",
            )


def from_get(request: Request) -> ProtocolRequest:
    return _from_fields({key: request.query_params.getlist(key) for key in request.query_params})


def from_post(request: Request, body: bytes) -> ProtocolRequest:
    """A POST body: the query itself (`application/sparql-query`, other parameters in the query string) or a
    form (`application/x-www-form-urlencoded`); anything else is a 415."""
    media_type = (request.headers.get("content-type") or "").split(";")[0].strip().lower()
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as error:
        raise query_rejected("syntax", f"The body is not UTF-8: {error}.") from None
    fields = {key: request.query_params.getlist(key) for key in request.query_params}
    if media_type == "application/sparql-query":
        # A `query` in the query string as well is a second query (the protocol's bad_multiple_queries).
        fields["query"] = [*fields.get("query", []), text]
    elif media_type == "application/x-www-form-urlencoded":
        for key, values in parse_qs(text, keep_blank_values=True).items():
            fields[key] = fields.get(key, []) + values
    else:
        raise UnsupportedMediaType(
            f"Send the query as application/sparql-query or application/x-www-form-urlencoded, not "
            f"'{media_type or 'no Content-Type'}'."
        )
    return _from_fields(fields)


def _from_fields(fields: dict[str, list[str]]) -> ProtocolRequest:
    if "update" in fields:
        raise query_rejected("update", "SPARQL Update is not allowed: this endpoint is read-only.", query_kind="update")
    queries = fields.get("query", [])
    if not queries:
        raise query_rejected("empty", "The 'query' parameter is missing.")
    if len(queries) > 1:
        raise query_rejected("multiple_queries", f"The 'query' parameter is given {len(queries)} times; send one.")
    return ProtocolRequest(
        query=queries[0],
        formats=fields.get("format", []),
        default_graphs=fields.get("default-graph-uri", []),
        named_graphs=fields.get("named-graph-uri", []),
    )

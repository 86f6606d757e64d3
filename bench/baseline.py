"""The in-run baseline: the reference backend's ingest, minimally (rdflib parse + one INSERT DATA per post).

Like the reference it is one uvicorn worker whose `async def` handler makes blocking `requests` calls to
Virtuoso with digest auth, so requests are served one at a time. Only POST /ttl, /ttl/delete_all and
/healthz/live exist: enough to replay the same workloads against it.
"""

from __future__ import annotations

import argparse
import uuid

import requests
import uvicorn
from fastapi import FastAPI
from pydantic import BaseModel
from rdflib import Graph
from requests.auth import HTTPDigestAuth


class TtlBody(BaseModel):
    ttl_content: str
    user: str | None = None


def build(endpoint: str, user: str, password: str, graph_uri: str) -> FastAPI:
    app = FastAPI()
    session = requests.Session()
    session.auth = HTTPDigestAuth(user, password)

    def update(sparql: str) -> None:
        response = session.post(
            endpoint, data=sparql.encode(), headers={"Content-Type": "application/sparql-update"}, timeout=30
        )
        response.raise_for_status()

    @app.get("/healthz/live")
    async def live() -> dict[str, bool]:
        return {"live": True}

    @app.post("/ttl", status_code=201)
    async def insert(body: TtlBody) -> dict[str, str]:
        graph = Graph()
        graph.parse(data=body.ttl_content, format="turtle")
        triples = graph.serialize(format="nt")
        update(f"INSERT DATA {{ GRAPH <{graph_uri}> {{ {triples} }} }}")
        return {"message": "TTL inserted into Virtuoso", "log_id": str(uuid.uuid4())}

    @app.post("/ttl/delete_all")
    async def delete_all() -> dict[str, str]:
        update(f"CLEAR GRAPH <{graph_uri}>")
        return {"message": "Graph cleared."}

    return app


def main() -> None:
    parser = argparse.ArgumentParser()
    for name in ("--endpoint", "--user", "--password", "--graph"):
        parser.add_argument(name, required=True)
    parser.add_argument("--port", type=int, required=True)
    args = parser.parse_args()
    uvicorn.run(build(args.endpoint, args.user, args.password, args.graph), port=args.port, log_level="warning")


if __name__ == "__main__":
    main()

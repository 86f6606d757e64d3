"""`segb erase` and `segb export --human`: a person's data from the command line, on the server's data directory
(the embedded store must not be in use: stop the server, or use the API)."""

from __future__ import annotations

import argparse
import contextlib
import getpass
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from segb_server.backend.config import Settings

if TYPE_CHECKING:
    from segb_server.backend.services.container import Services

ServicesOf = Callable[[Settings], contextlib.AbstractContextManager["Services"]]


def add_erase(commands: argparse._SubParsersAction, store_options: Callable[[argparse.ArgumentParser], None]) -> None:
    erase = commands.add_parser(
        "erase", help="erase one person everywhere the server keeps data (their words, emotions read on them, …)"
    )
    store_options(erase)
    erase.add_argument("iri", nargs="?", metavar="IRI", help="the person's IRI, as the robots logged it")
    erase.add_argument("--human", metavar="IRI", help="the same, as an option")
    erase.add_argument(
        "--reason", help="why (kept in the ledger for good with the erasure: do not name the person); required "
        "unless --dry-run"
    )  # fmt: skip
    erase.add_argument("--by", help="who erases, as the ledger records it (default: the system user)")
    erase.add_argument(
        "--dry-run", action="store_true", help="only list what would be erased, counted by kind; nothing is written"
    )
    erase.add_argument(
        "--mentions", choices=("concerning", "store"), default="concerning",
        help='where the person\'s names are replaced by "[erased]" in the texts kept: those that concern them '
        "(default: replies to them, events about them, their conversations) or every text of the store",
    )  # fmt: skip


def add_retention(
    commands: argparse._SubParsersAction, store_options: Callable[[argparse.ArgumentParser], None]
) -> None:
    retention = commands.add_parser(
        "retention", help="erase now what RETENTION_DAYS says is past keeping (the server does it on schedule)"
    )
    store_options(retention)
    retention.add_argument("--days", dest="retention_days", type=int, help="days kept (RETENTION_DAYS)")
    retention.add_argument("--as-of", metavar="TIME", help="count from this time instead of now (ISO 8601 with a zone)")


def retention(args: argparse.Namespace, settings: Settings, services_of: ServicesOf) -> int:
    from datetime import datetime

    from segb_server.backend.services.people.retention import Retention

    if settings.retention_days is None:
        print("segb: error: no retention is set: RETENTION_DAYS (or --days) is empty, posts are kept forever",
              file=sys.stderr)  # fmt: skip
        return 2
    try:
        now = datetime.fromisoformat(args.as_of.replace("Z", "+00:00")) if args.as_of else None
    except ValueError:
        now = datetime.min  # not a time: refused below, as a time without a zone is
    if now is not None and now.tzinfo is None:
        print(f"segb: error: --as-of must be an ISO 8601 time with a zone, e.g. 2027-01-01T00:00:00Z (got "
              f"{args.as_of!r})", file=sys.stderr)  # fmt: skip
        return 2
    with services_of(settings) as services:
        services.start()
        keeper = Retention(services.erasure, settings.retention_days, 0, lambda: True)
        done = keeper.run_once(now)
    if done is None:
        print("nothing is past retention")
    else:
        print(f"erased {done.receipt.triples_removed} triples from {done.receipts_redacted} posts past retention; "
              f"ledger entry {done.receipt.sequence}")  # fmt: skip
    return 0


def erase(args: argparse.Namespace, settings: Settings, services_of: ServicesOf) -> int:
    from segb_server.backend.services.sparql.catalog import Parameter, to_term

    given = [iri for iri in (args.iri, args.human) if iri]
    if len(given) != 1 or (args.reason is None and not args.dry_run):
        print("segb: error: give the person's IRI once (IRI or --human IRI), and --reason unless --dry-run",
              file=sys.stderr)  # fmt: skip
        return 2
    human = to_term(Parameter("human", "iri"), given[0]).value
    if args.dry_run:
        with services_of(settings) as services:  # not started: a dry run reads the store and writes nothing
            preview = services.erasure.preview(human, args.mentions)
        kinds = ", ".join(f"{kind} {count}" for kind, count in preview.kinds.items())
        print(f"dry run: would erase {preview.resources} resources ({kinds}), {preview.triples} triples in the "
              f"store, and redact the person's names in {preview.mentions} texts; left alone: {preview.left_out}; "
              "nothing was written")  # fmt: skip
        return 0
    actor = args.by or f"{getpass.getuser()} (segb erase)"
    with services_of(settings) as services:
        services.start()  # the applier and the views' keeper: the store and the views follow the erasure
        done = services.erasure.erase_human(human, args.reason, actor, args.mentions)
    receipt = done.receipt
    print(
        f"erased: {receipt.triples_removed} triples from {done.receipts_redacted} posts "
        f"({done.resources} resources), the person's names redacted in {done.mentions_redacted} texts; "
        f"ledger entry {receipt.sequence}, log_id {receipt.log_id}"
    )
    if done.name_still_mentioned:
        kept = done.name_still_mentioned
        texts = "1 text" if kept == 1 else f"{kept} texts"
        print(
            f"note: {texts} that concern someone else still {'contains' if kept == 1 else 'contain'} one of the "
            "person's names; --mentions store redacts them too"
        )
    return 0


def export_person(args: argparse.Namespace, settings: Settings, services_of: ServicesOf) -> int:
    from pyoxigraph import NamedNode

    from segb_server.backend.services.formats import PERSON_EXPORTS, by_name
    from segb_server.backend.services.graph.export import write_graph
    from segb_server.backend.services.people.story_page import story_page
    from segb_server.backend.services.sparql.catalog import Parameter, to_term

    fmt = by_name(PERSON_EXPORTS, args.format)
    human = to_term(Parameter("human", "iri"), args.human).value
    with services_of(settings) as services:
        data = services.people_export.export(human)
        graph = NamedNode(services.store.graph_uri)
        body = story_page(data).encode() if fmt.rdf is None else b"".join(write_graph([data.triples], fmt, graph))
    _write(body, args.output)
    return 0


def _write(body: bytes, output: Path | None) -> None:
    if output is None:
        sys.stdout.buffer.write(body)
        sys.stdout.buffer.flush()
    else:
        output.write_bytes(body)

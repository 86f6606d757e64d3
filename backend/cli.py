"""The `segb` command: serve the API and UI, import and export RDF, check a log against the audit rules.

Settings come from, highest first: command-line flags, environment variables, a `.env` file, defaults.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError
from tqdm import tqdm

from segb_server.backend import cli_evidence, cli_people
from segb_server.backend.config import Settings
from segb_server.backend.services.errors import ServiceError
from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.store.base import StoreError

if TYPE_CHECKING:  # the services are imported by the commands that need them, not whenever the CLI starts
    from segb_server.backend.services.container import Services
    from segb_server.backend.services.rules.catalog import RuleCatalog
    from segb_server.backend.services.sparql.catalog import Catalog, CatalogQuery

IMPORT_USER = "segb-import"  # the receipts of `segb import` name this user


# Files a command creates (the journal, SQLite state, the views, the store, logs, keys, exports) hold people's
# data: only the server's user may read them (600, folders 700); the processes it starts inherit this.
PRIVATE_FILES = 0o077


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    previous = os.umask(PRIVATE_FILES)
    try:
        return args.handler(args)
    except ValidationError as error:
        return _fail(f"invalid setting: {_settings_problem(error)}")
    except (ServiceError, StoreError, StateUnavailable) as error:
        return _fail(str(error))
    except KeyboardInterrupt:
        return 130
    finally:
        os.umask(previous)  # a caller in this process (a test calling main) keeps its own


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="segb",
        description="SEGB server: semantic robot logs, stored and audited. Options left out come from the "
        "environment variable named in their help, then `.env`, then the default shown.",
    )
    parser.add_argument("--version", action="version", version=f"segb {importlib.metadata.version('segb-server')}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    serve = commands.add_parser("serve", help="run the API (default :5000) and the web UI (default :8080)")
    _store_options(serve)
    serve.add_argument("--host", help="interface to listen on (HOST; default 127.0.0.1)")
    serve.add_argument("--api-port", type=int, help="API port (API_PORT; default 5000)")
    serve.add_argument("--ui-port", type=int, help="UI port (UI_PORT; default 8080)")
    serve.add_argument("--backend-url", help="URL the UI uses to reach the API (BACKEND_URL; default the API's)")
    serve.add_argument("--only", choices=["api", "ui"], help="run just one of the two servers (default: both)")
    serve.add_argument("--demo", action="store_true", help="load the demo dataset at start-up if the store is empty")
    serve.add_argument(
        "--workers",
        dest="api_workers",
        type=int,
        help="API processes sharing the port (API_WORKERS; default 1); more than one needs STORE=virtuoso or sparql",
    )
    serve.set_defaults(handler=_serve)

    rebuild = commands.add_parser(
        "rebuild", help="rebuild the store from the journal (recovery, or moving to another store with --store)"
    )
    _store_options(rebuild)
    rebuild.set_defaults(handler=_rebuild)

    copy_state = commands.add_parser(
        "copy-state",
        help="copy the journal and shared contexts into a PostgreSQL database, to run with STATE_URL from then on",
    )
    copy_state.add_argument("--data-dir", type=Path, help="the server's directory (DATA_DIR; default ./data)")
    copy_state.add_argument("--to", required=True, metavar="POSTGRESQL_URL", help="postgresql://user:password@host/db")
    copy_state.set_defaults(handler=_copy_state)

    load = commands.add_parser("import", help="load Turtle (.ttl) or N-Triples (.nt) files into the store")
    _store_options(load)
    load.add_argument("files", nargs="+", type=Path, metavar="FILE", help="a .ttl or .nt file (several may follow)")
    load.set_defaults(handler=_import)

    export = commands.add_parser("export", help="write the events graph out (streamed), or one person's data")
    _store_options(export)
    export.add_argument(
        "--format",
        choices=["turtle", "ntriples", "nquads", "jsonld", "html"],
        help="syntax (default turtle; with --human also html, a page to read, the default there)",
    )
    export.add_argument("--human", metavar="IRI", help="only what is held about this person (GDPR Art. 15)")
    export.add_argument("--output", "-o", type=Path, help="file to write (default: standard output)")
    export.add_argument(
        "--otlp", action="store_true", help="send what robots did as traces to OTEL_EXPORTER_OTLP_ENDPOINT instead"
    )
    export.add_argument("--robot", metavar="IRI", help="with --otlp: only what this robot did")
    export.add_argument("--since", metavar="TIME", help="with --otlp: from this time (ISO 8601 with a time zone)")
    export.add_argument("--until", metavar="TIME", help="with --otlp: up to this time")
    export.set_defaults(handler=_export)

    token = commands.add_parser(
        "token", help="print an API token (the secret comes from SECRET_KEY or --secret-file, never from argv)"
    )
    token.add_argument("--username", required=True, help="who the token names (recorded with every post)")
    token.add_argument(
        "--role",
        action="append",
        required=True,
        choices=["logger", "auditor", "admin"],
        help="a role of the token; repeat for several (logger publishes, auditor reads, admin does everything)",
    )
    token.add_argument("--scope", action="append", metavar="IRI_PREFIX", help=_SCOPE_HELP)
    token.add_argument("--expires-in", type=int, default=3600, help="lifetime in seconds, 60 … 2592000 (default 3600)")
    token.add_argument("--name", help="display name claim (default: none)")
    token.add_argument("--secret-file", type=Path, help="file holding the secret (default: SECRET_KEY)")
    token.add_argument("--allow-weak-secret", action="store_true", help="accept a secret under 32 characters")
    token.add_argument("--json", action="store_true", help="print token, username, roles, scopes, exp as JSON")
    token.set_defaults(handler=_token)

    cli_people.add_erase(commands, _store_options)
    commands.choices["erase"].set_defaults(handler=_erase)
    cli_people.add_retention(commands, _store_options)
    commands.choices["retention"].set_defaults(
        handler=lambda args: cli_people.retention(args, _settings(args, "retention_days"), _services)
    )
    cli_evidence.add_commands(commands, _store_options)
    commands.choices["evidence"].set_defaults(
        handler=lambda args: cli_evidence.evidence(args, _settings(args), _services)
    )
    commands.choices["evidence-key"].set_defaults(handler=lambda args: cli_evidence.evidence_key(args, _settings(args)))
    commands.choices["verify-evidence"].set_defaults(handler=cli_evidence.verify_evidence)

    check = commands.add_parser(
        "check", help="run the audit rules on a log file, offline (exit code 1 when a rule finds a violation)"
    )
    check.add_argument("file", type=Path, metavar="LOG", help="a Turtle (.ttl) or N-Triples (.nt) file")
    check.add_argument("--rules", type=Path, help="folder of rules (RULES_DIR; default the shipped rules)")
    check.add_argument("--format", choices=["text", "json", "junit"], default="text", help="output (default text)")
    check.set_defaults(handler=_check)

    upkeep = commands.add_parser(
        "upkeep",
        help="tell how each kept view (a report's rows, a timeline kind's, a rule's findings, the graph index) is kept "
        "current as robots write; with --diff, compare a view's kept rows with its query evaluated in full",
    )
    upkeep.add_argument(
        "report",
        nargs="?",
        help="a view: a report's name (conversations), a timeline kind's (timeline/message) or a rule's "
        "(rules/unanswered-message); default: every kept view",
    )
    upkeep.add_argument("key", nargs="?", help="with --diff: only the rows of this key (e.g. a message's IRI)")
    upkeep.add_argument(
        "--diff",
        action="store_true",
        help="compare the view's kept rows (caught up with the journal) with its query evaluated in full on the "
        "store of DATA_DIR (exit code 1 when they differ; the server must be stopped, as for `segb rebuild`)",
    )
    upkeep.add_argument("--sparql-dir", type=Path, help="directory of the .rq files (SPARQL_DIR)")
    upkeep.add_argument("--rules-dir", type=Path, help="folder of the audit rules (RULES_DIR)")
    _store_options(upkeep)
    upkeep.set_defaults(handler=_upkeep)

    demo = commands.add_parser("demo", help="publish the demo dataset (robots ARI and TIAGo) to a running server")
    demo.add_argument("--server", help="API base URL (default http://127.0.0.1:<API_PORT>)")
    demo.add_argument("--token", help="bearer token with the logger role, when the server has SECRET_KEY set")
    demo.set_defaults(handler=_demo)
    return parser


_SCOPE_HELP = (
    "an IRI prefix the token may write about (the subjects of its triples); repeat for several, e.g. the robot's "
    "own namespace and the shared people namespace (default: no limit)"
)


def _store_options(command: argparse.ArgumentParser) -> None:
    command.add_argument(
        "--store",
        choices=["oxigraph", "memory", "virtuoso", "sparql"],
        help="triple store (STORE; default oxigraph, the embedded store in DATA_DIR)",
    )
    command.add_argument("--data-dir", type=Path, help="where the server keeps its files (DATA_DIR; default ./data)")


def _settings(args: argparse.Namespace, *names: str) -> Settings:
    overrides: dict[str, Any] = {}
    for name in ("store", "data_dir", *names):
        value = getattr(args, name, None)
        if value is not None:
            overrides[name] = value
    return Settings(**overrides)


# --- serve -------------------------------------------------------------------------------------------


def _serve(args: argparse.Namespace) -> int:
    names = ("host", "api_port", "ui_port", "backend_url", "api_workers")
    settings = _settings(args, *names)
    from segb_server.backend.listening import CannotListen
    from segb_server.backend.services.observability.worker_metrics import metrics_shared_by_workers
    from segb_server.backend.serving import (
        DataDirUnwritable,
        WorkersRefused,
        check_data_dir,
        check_shareable,
        configure_logging,
        hand_down,
        serve,
        serve_api_workers,
        warn_when_open,
    )

    configure_logging(settings)

    if args.demo and args.only == "ui":
        return _fail("--demo fills the API's store: drop --only ui")
    try:
        if args.only in (None, "api"):
            _check_catalog(settings)
            check_data_dir(settings)
            warn_when_open(settings)
        check_shareable(settings, demo=args.demo)
    except (WorkersRefused, DataDirUnwritable) as refused:
        return _fail(str(refused))

    def listening() -> None:
        if args.only in (None, "api"):
            print(f"SEGB API  http://{settings.host}:{settings.api_port}/docs", file=sys.stderr)
        if args.only in (None, "ui"):
            print(f"SEGB UI   http://{settings.host}:{settings.ui_port}/reports", file=sys.stderr)

    passed = ("store", "data_dir", *names)
    try:
        if settings.api_workers > 1 and args.only != "ui":
            hand_down({name: getattr(args, name) for name in passed if getattr(args, name, None)})
            with metrics_shared_by_workers():  # each worker counts in its own files there; a scrape sums them
                serve_api_workers(settings, with_ui=args.only is None, listening=listening)
        else:
            api, ui = args.only in (None, "api"), args.only in (None, "ui")
            serve(settings, api=api, ui=ui, demo=args.demo, listening=listening)
    except CannotListen as error:  # a port that is taken: one line, which one and how to choose another
        return _fail(str(error))
    return 0


def _check_catalog(settings: Settings) -> None:
    """Fail before serving when the SPARQL queries are missing (raises CatalogError: one line, exit 2)."""
    from segb_server.backend.services.container import REQUIRED_QUERIES
    from segb_server.backend.services.sparql.catalog import Catalog

    Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)


# --- import / export ---------------------------------------------------------------------------------


def _import(args: argparse.Namespace) -> int:
    settings = _settings(args)
    from segb_server.backend.services.ingest.service import FILE_FORMATS, UNREADABLE_FILE

    missing = [str(path) for path in args.files if not path.is_file()]
    if missing:
        return _fail(f"no such file: {', '.join(missing)}")
    unreadable = [path.name for path in args.files if path.suffix.lower() not in FILE_FORMATS]
    if unreadable:  # before the store opens and a progress bar starts
        return _fail(f"{', '.join(unreadable)}: {UNREADABLE_FILE}")
    with _services(settings) as services:
        total = sum(path.stat().st_size for path in args.files)
        with tqdm(total=total, unit="B", unit_scale=True, desc="import", file=sys.stderr) as bar:
            for path in args.files:
                result = services.ingest.import_file(path, actor=IMPORT_USER, progress=bar.update)
                bar.write(f"{path}: {result.triples_read} triples read, {result.triples_new} new")
    return 0


def _check(args: argparse.Namespace) -> int:
    """Findings of every rule on one file, in an in-memory store: the robot's own CI runs it before deploying."""
    from pyoxigraph import RdfFormat

    from segb_server.backend.services.ingest.parsing import parse_quads
    from segb_server.backend.services.rules import check_output
    from segb_server.backend.services.rules.catalog import RuleCatalog
    from segb_server.backend.services.rules.offline import check_quads

    settings = Settings(**({"rules_dir": args.rules} if args.rules is not None else {}))
    if not args.file.is_file():
        return _fail(f"no such file: {args.file}")
    if args.rules is not None and not args.rules.is_dir():
        return _fail(f"no such folder of rules: {args.rules}")
    catalog = RuleCatalog(settings.rules_dir)
    data = args.file.read_bytes()
    rdf_format = RdfFormat.N_TRIPLES if args.file.suffix == ".nt" else RdfFormat.TURTLE
    quads = parse_quads(data, rdf_format, max_triples=settings.max_triples_per_post)
    report = check_quads(catalog, quads, data.decode("utf-8", errors="replace"))
    name = str(args.file)
    if args.format == "json":
        sys.stdout.write(check_output.as_json(report, name))
    elif args.format == "junit":
        sys.stdout.write(check_output.as_junit(report, name, catalog))
    else:
        sys.stdout.write(check_output.as_text(report, name))
    return 1 if report.violations else 0


def _rebuild(args: argparse.Namespace) -> int:
    settings = _settings(args)
    with _services(settings) as services:
        writes, store = services.writes, services.store
        if not writes.apply_leadership.try_acquire():
            holder = writes.apply_leadership.where
            return _fail(f"a server is running on this journal (it holds {holder}): stop it first")
        journal = writes.journal
        start = journal.last_clearing()
        removed = store.clear(through=start)
        print(
            f"cleared the {store.kind} store ({removed} triples); applying journal entries {start + 1}…",
            file=sys.stderr,
        )
        writes.apply_now()
        applied = writes.applied
        print(f"{store.kind} store rebuilt from the journal through entry {applied}: {store.count()} triples")
    return 0


def _upkeep(args: argparse.Namespace) -> int:
    from segb_server.backend.services.rules.catalog import RuleCatalog
    from segb_server.backend.services.sparql.catalog import Catalog
    from segb_server.backend.services.views.kept_queries.describe import describe, describe_others

    settings = _settings(args, "sparql_dir", "rules_dir")
    views = _kept_queries(Catalog(settings.sparql_dir), RuleCatalog(settings.rules_dir))
    if args.report is None:
        if args.diff:
            return _fail("--diff compares one view: name it (e.g. `segb upkeep --diff conversations`)")
        print("\n\n".join("\n".join(lines) for lines in [*(describe(query) for query in views), describe_others()]))
        return 0
    # A report by its name; the timeline's kinds and the rules, kept alike, by theirs (`timeline/message`).
    wanted = args.report if "/" in args.report else f"reports/{args.report}"
    found = [query for query in views if query.name == wanted]
    if not found:
        names = ", ".join(query.name.removeprefix("reports/") for query in views)
        return _fail(f"no kept view named {args.report!r}; views: {names}")
    if args.diff:
        return _upkeep_diff(settings, found[0], args.key)
    if args.key is not None:
        return _fail("a KEY is for --diff")
    print("\n".join(describe(found[0])))
    return 0


def _kept_queries(catalog: Catalog, rules: RuleCatalog) -> list[CatalogQuery]:
    """Every query kept as rows: the reports, the timeline's kinds and the SPARQL rules, in that order."""
    from segb_server.backend.services.reports.folder import FOLDER
    from segb_server.backend.services.timeline.kinds import FOLDER as TIMELINE_FOLDER

    sparql_rules = [rule.query for rule in rules.sparql() if rule.query is not None]
    return [*catalog.under(FOLDER), *catalog.under(TIMELINE_FOLDER), *sparql_rules]


def _upkeep_diff(settings: Settings, query: CatalogQuery, key: str | None) -> int:
    from segb_server.backend.services.views.kept_queries.diff import NotKept, diff_view, told

    with _services(settings) as services:
        writes = services.writes
        if not writes.apply_leadership.try_acquire():
            return _fail(
                f"a server is running on this journal (it holds {writes.apply_leadership.where}): stop it first"
            )
        services.start()  # apply what the journal holds, and catch the views up with it
        writes.apply_now()
        through = writes.applied
        print(f"catching the views up with journal entry {through}…", file=sys.stderr)
        if not writes.wait_viewed(through, timeout=3600):
            return _fail(f"the views did not catch up with entry {through} within an hour")
        kept = {
            "reports": services.reports.kept_queries(),
            "timeline": services.timeline_rows,
            "rules": services.findings.kept,
        }[query.name.split("/", 1)[0]]
        if kept is None:
            return _fail("the views are not kept here (KEEP_VIEWS=false): nothing to compare")
        try:
            difference = diff_view(kept, services.store, query, key)
        except NotKept as reason:
            return _fail(str(reason))
    print("\n".join(told(difference)))
    return 0 if difference.same else 1


def _copy_state(args: argparse.Namespace) -> int:
    from segb_server.backend.services.ops.leadership import LOCK_FILE, Leadership
    from segb_server.backend.services.shared_context.state import STATE_FILE, ContextState
    from segb_server.backend.services.writing.journal import Journal
    from segb_server.backend.services.writing.journal_file import journal_path
    from segb_server.backend.state.copying import CONTEXT_TABLES, JOURNAL_TABLES, TargetNotEmpty, copy_tables
    from segb_server.backend.state.opening import open_state
    from segb_server.backend.state.postgres import PostgresDatabase, redacted

    settings = _settings(args)
    if not args.to.startswith(("postgresql://", "postgres://")):
        return _fail("--to must be a postgresql:// URL")
    if settings.state_url == args.to:
        return _fail("the state is already in that database (STATE_URL)")
    journal_file = journal_path(settings.data_dir)
    if not settings.state_url and not journal_file.is_file():
        return _fail(f"no journal to copy: {journal_file} does not exist")
    server = Leadership(settings.data_dir / LOCK_FILE)
    if not server.try_acquire():
        return _fail(f"a server is running on {settings.data_dir} (it holds {LOCK_FILE}): stop it first")
    try:
        parts = (
            (journal_file.name, "journal", JOURNAL_TABLES, Journal),
            (STATE_FILE, "contexts", CONTEXT_TABLES, ContextState),
        )
        for file, writers, tables, keeper in parts:
            source = open_state(settings.state_url, settings.data_dir / file, writers=writers)
            target = PostgresDatabase(args.to, writers=writers)
            try:
                keeper(target)  # creates the tables, as a server would
                copied = copy_tables(source, target, tables)
            finally:
                source.close()
                target.close()
            print(f"{writers}: " + ", ".join(f"{rows} rows of {table}" for table, rows in copied.items()))
        journal = Journal(PostgresDatabase(args.to, writers="journal"))
        verification = journal.verify(deep=True)
        journal.close()
    except TargetNotEmpty as error:
        return _fail(f"{error}: copy into a new, empty database")
    finally:
        server.release()
    if not verification.valid:
        return _fail(f"the copy does not verify: {verification.first_broken}")
    print(
        f"the copy verifies: {verification.receipts} receipts, content included. "
        f"Start the server with STATE_URL={redacted(args.to)} (and its password)."
    )
    return 0


@contextlib.contextmanager
def _services(settings: Settings) -> Iterator[Services]:
    """The store and services of a command that runs without the server (the store must not be in use)."""
    from segb_server.backend.services.container import build_services
    from segb_server.backend.store.factory import open_store

    store = open_store(settings)
    try:
        services = build_services(settings, store)
        try:
            yield services
        finally:
            services.close()
    finally:
        store.close()


def _erase(args: argparse.Namespace) -> int:
    return cli_people.erase(args, _settings(args), _services)


def _export(args: argparse.Namespace) -> int:
    from segb_server.backend.services.formats import EXPORTS, by_name
    from segb_server.backend.services.graph.export import stream_graph
    from segb_server.backend.store.factory import open_store

    if args.otlp:
        return _export_otlp(args)
    if args.human is not None:
        args.format = args.format or "html"
        return cli_people.export_person(args, _settings(args), _services)
    if args.format == "html":
        return _fail("--format html is a person's page: add --human IRI")
    settings = _settings(args)
    store = open_store(settings)
    try:
        chunks = stream_graph(store, by_name(EXPORTS, args.format or "turtle"))
        if args.output is None:
            for chunk in chunks:
                sys.stdout.buffer.write(chunk)
            sys.stdout.buffer.flush()
        else:
            with args.output.open("wb") as output:
                for chunk in chunks:
                    output.write(chunk)
    finally:
        store.close()
    return 0


def _export_otlp(args: argparse.Namespace) -> int:
    from segb_server.backend.services.errors import InvalidParameter
    from segb_server.backend.services.observability.otlp import ExportFailed
    from segb_server.backend.services.observability.trace_export import NoEndpoint, export_window
    from segb_server.backend.services.sparql.catalog import Catalog
    from segb_server.backend.store.factory import open_store

    settings = _settings(args)
    filters = {"robot": args.robot, "since": args.since, "until": args.until}
    store = open_store(settings)
    try:
        sent = export_window(store, Catalog(settings.sparql_dir), settings.otel_exporter_otlp_endpoint, filters,
                             with_text=settings.trace_message_text)  # fmt: skip
    except (InvalidParameter, NoEndpoint, ExportFailed) as refused:
        return _fail(str(refused))
    finally:
        store.close()
    print(f"sent {sent} spans to {settings.otel_exporter_otlp_endpoint}", file=sys.stderr)
    return 0


def _demo(args: argparse.Namespace) -> int:
    from segb_server.backend.demo import publish_demo

    server = args.server or f"http://127.0.0.1:{Settings().api_port}"
    print(publish_demo(server, args.token))
    return 0


def _token(args: argparse.Namespace) -> int:
    import json
    from datetime import UTC, datetime

    from segb_server.backend.auth import TokenRequestError, mint_token

    if args.secret_file is not None:
        try:
            secret = args.secret_file.read_text(encoding="utf-8").strip()
        except OSError as error:
            return _fail(f"cannot read the secret file: {error}")
    else:
        # Settings, so SECRET_KEY is read as the server reads it: the environment, then `.env`.
        secret = Settings(allow_weak_secret=True).secret_key
    if not secret:
        return _fail("no secret: set SECRET_KEY or pass --secret-file")
    try:
        minted = mint_token(
            secret,
            username=args.username,
            roles=args.role,
            expires_in=args.expires_in,
            name=args.name,
            scopes=args.scope or (),
            allow_weak_secret=args.allow_weak_secret,
        )
    except TokenRequestError as error:
        return _fail(str(error))
    if args.json:
        expires = datetime.fromtimestamp(minted.expires_at, UTC).isoformat()
        print(
            json.dumps(
                {
                    "token": minted.token,
                    "username": minted.username,
                    "roles": minted.roles,
                    "exp": minted.expires_at,
                    "scopes": minted.scopes,
                    "exp_utc": expires,
                    "algorithm": "HS256",
                }
            )
        )
    else:
        print(minted.token)
    return 0


def _fail(message: str) -> int:
    print(f"segb: error: {message}", file=sys.stderr)
    return 2


def _settings_problem(error: ValidationError) -> str:
    return "; ".join(
        f"{'.'.join(str(p) for p in issue['loc']) or 'settings'}: {issue['msg']}" for issue in error.errors()
    )


if __name__ == "__main__":
    sys.exit(main())

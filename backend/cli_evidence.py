"""`segb evidence`, `segb evidence-key` and `segb verify-evidence`: evidence bundles from the command line. The
first two read the server's data directory (the embedded store must not be in use); the check needs nothing but
the bundle and, to know who signed it, the server's public key."""

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
StoreOptions = Callable[[argparse.ArgumentParser], None]


def add_commands(commands: argparse._SubParsersAction, store_options: StoreOptions) -> None:
    evidence = commands.add_parser("evidence", help="write a signed evidence bundle of one window (a zip archive)")
    store_options(evidence)
    evidence.add_argument("--robot", metavar="IRI", help="only what this robot did (default: every robot)")
    evidence.add_argument("--since", metavar="TIME", help="from this time on, ISO 8601 with a zone (…T09:00:00Z)")
    evidence.add_argument("--until", metavar="TIME", help="up to this time, ISO 8601 with a zone")
    evidence.add_argument("--output", "-o", type=Path, required=True, help="the bundle to write (.zip)")
    evidence.add_argument("--by", help="who exports, as the manifest records it (default: the system user)")

    key = commands.add_parser("evidence-key", help="print the server's public key for evidence bundles (PEM)")
    key.add_argument("--data-dir", type=Path, help="the server's directory (DATA_DIR; default ./data)")

    check = commands.add_parser(
        "verify-evidence",
        help="check an evidence bundle offline: exit 0 verified with the server's key, 1 not verified, 3 intact but "
        "signed by a key not given with --public-key",
    )
    check.add_argument("bundle", type=Path, metavar="BUNDLE", help="the .zip written by segb evidence or GET /evidence")
    check.add_argument(
        "--public-key", type=Path, metavar="PEM", help="the server's public key (without it: the key the bundle holds)"
    )
    check.add_argument(
        "--max-size",
        type=_mebibytes,
        default=512,
        metavar="MIB",
        help="the most the bundle's files may inflate to in all, in MiB (default 512)",
    )


def evidence(args: argparse.Namespace, settings: Settings, services_of: ServicesOf) -> int:
    filters = {"robot": args.robot, "since": args.since, "until": args.until}
    with services_of(settings) as services:
        bundle = services.evidence.build(filters, args.by or f"{getpass.getuser()} (segb evidence)")
        fingerprint = services.evidence.key.fingerprint
    args.output.write_bytes(bundle.data)
    print(
        f"{args.output}: {bundle.triples} triples, {bundle.receipts} receipts up to entry {bundle.head}, "
        f"{len(bundle.data)} bytes; signed with key {fingerprint}"
    )
    return 0


def evidence_key(args: argparse.Namespace, settings: Settings) -> int:
    from segb_server.backend.services.evidence.key import ServerKey

    key = ServerKey.at(settings.data_dir)
    sys.stdout.write(key.public_pem().decode())
    print(f"fingerprint (SHA-256): {key.fingerprint}", file=sys.stderr)
    return 0


VERIFIED, NOT_VERIFIED, UNTRUSTED_KEY = 0, 1, 3  # 2: a usage error, as for every command


def verify_evidence(args: argparse.Namespace) -> int:
    """Every fact, the problems (when more than one), then one verdict line; its exit status says which."""
    from segb_server.backend.services.evidence.verify import verify_bundle

    try:
        expected = args.public_key.read_bytes() if args.public_key is not None else None
    except OSError as error:
        print(f"segb: error: cannot read the public key: {error}", file=sys.stderr)
        return 2
    report = verify_bundle(args.bundle, expected, args.max_size << 20)
    for fact in report.facts:
        print(f"  {_shown(fact)}")
    if len(report.problems) > 1:
        for problem in report.problems:
            print(f"FAILED: {_shown(problem)}")
    if report.problems:
        more = f" (and {len(report.problems) - 1} more problems, above)" if len(report.problems) > 1 else ""
        print(f"{args.bundle}: NOT verified: {_shown(report.problems[0])}{more}")
        return NOT_VERIFIED
    if not report.trusted:
        print(
            f"{args.bundle}: intact, but signed by an untrusted key: {report.signer}, the key the bundle carries; "
            "pass the server's key with --public-key to verify it"
        )
        return UNTRUSTED_KEY
    print(f"{args.bundle}: verified")
    return VERIFIED


def _shown(text: str) -> str:
    """Text from a bundle (an erasure's reason, a triple) with control characters escaped: an escape sequence in
    it could otherwise rewrite the terminal's lines, the verdict among them."""
    return "".join(char if char.isprintable() else char.encode("unicode_escape").decode() for char in text)


def _mebibytes(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"not a whole number of MiB: {text!r}")
    return int(text)

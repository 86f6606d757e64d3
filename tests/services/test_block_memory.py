"""The memory of re-sent blocks: per account and write scopes, per journal epoch and header, bounded in accounts
and blocks, and never holding a block one of whose triples was withheld."""

from __future__ import annotations

from pyoxigraph import RdfFormat

from segb_server.backend.services.ingest.republish import BlockMemory

HEADER = "@prefix ex: <https://example.org/> .\n"
DOCUMENT = (HEADER + "".join(f'\nex:s{i} ex:p "{i}" ;\n    ex:q ex:o{i} .\n' for i in range(4))).encode()
TRIPLES = 8


def remembered(memory: BlockMemory, account: tuple[str, tuple[str, ...]], epoch: int = 0) -> int:
    """Read and record DOCUMENT as `account`; the triples the read skipped."""
    reading = memory.read(DOCUMENT, RdfFormat.TURTLE, account, epoch, 1000)
    memory.recorded(reading, account, epoch, 0, lambda _digests: True)
    assert reading.held + len(reading.quads) == TRIPLES
    return reading.held


def test_a_document_sent_again_is_skipped_for_its_account_only() -> None:
    memory = BlockMemory()

    assert remembered(memory, ("ari", ())) == 0
    assert remembered(memory, ("ari", ())) == TRIPLES
    assert remembered(memory, ("bo", ())) == 0
    assert remembered(memory, ("ari", ("https://example.org/",))) == 0  # other scopes: another account


def test_a_new_epoch_reads_everything_again() -> None:
    memory = BlockMemory()
    remembered(memory, ("ari", ()), epoch=3)

    assert remembered(memory, ("ari", ()), epoch=4) == 0
    assert remembered(memory, ("ari", ()), epoch=4) == TRIPLES


def test_the_least_recently_posting_account_is_forgotten_past_the_bounds() -> None:
    memory = BlockMemory(max_blocks=10, max_accounts=5)
    for name in ("ari", "bo", "cy"):  # four blocks each: the third account passes ten blocks
        remembered(memory, (name, ()))

    assert remembered(memory, ("cy", ())) == TRIPLES
    assert remembered(memory, ("ari", ())) == 0


def test_blocks_of_a_post_with_withheld_triples_are_remembered_only_if_the_journal_holds_them() -> None:
    memory = BlockMemory()
    account = ("ari", ())
    reading = memory.read(DOCUMENT, RdfFormat.TURTLE, account, 0, 1000)
    memory.recorded(reading, account, 0, 1, lambda _digests: False)

    assert memory.read(DOCUMENT, RdfFormat.TURTLE, account, 0, 1000).held == 0


def blocks_of(text: str) -> list[str]:
    return [block for block in text.removeprefix(HEADER).split("\n\n") if block.strip()]


def test_a_remembered_block_sent_twice_makes_the_document_read_whole() -> None:
    memory, account = BlockMemory(), ("ari", ())
    remembered(memory, account)
    twice = (HEADER + "\n\n" + "\n\n".join([*blocks_of(DOCUMENT.decode()), blocks_of(DOCUMENT.decode())[0]])).encode()

    reading = memory.read(twice, RdfFormat.TURTLE, account, 0, 1000)

    assert (reading.held, len(reading.quads)) == (0, TRIPLES + 2)


def test_a_changed_block_replaces_its_subject_s_old_one_and_a_left_out_block_is_not_counted() -> None:
    memory, account = BlockMemory(), ("ari", ())
    remembered(memory, account)
    changed = DOCUMENT.replace(b'ex:p "0"', b'ex:p "zero"')
    reading = memory.read(changed, RdfFormat.TURTLE, account, 0, 1000)
    assert (reading.held, len(reading.quads)) == (TRIPLES - 2, 2)  # the changed block alone is parsed
    memory.recorded(reading, account, 0, 0, lambda _digests: True)

    # The block of ex:s3 left out, the changed block sent again: six triples skipped, none parsed.
    without_last = (HEADER + "\n\n" + "\n\n".join(blocks_of(changed.decode())[:3])).encode()
    again = memory.read(without_last, RdfFormat.TURTLE, account, 0, 1000)

    assert (again.held, len(again.quads)) == (TRIPLES - 2, 0)
    # The old bytes of ex:s0 are forgotten: sent again, they are parsed (and the new ones are not skipped with them).
    old = memory.read(DOCUMENT, RdfFormat.TURTLE, account, 0, 1000)
    assert (old.held, len(old.quads)) == (TRIPLES - 2, 2)

"""Where else than the store and the journal what robots logged is held, and how each place forgets an erasure:
the shared-context state, the server log, the copies users' SPARQL runs on, the views' files, the journal's own
write-ahead log."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.people.erasure import Forgetting, Forgotten
from segb_server.backend.services.shared_context.service import SharedContextService
from segb_server.backend.services.sparql.runner import QueryRunner
from segb_server.backend.services.writing.journal import Journal
from segb_server.backend.state.sqlite import vacuum


def forgetting(
    journal: Journal,
    contexts: SharedContextService,
    queries: QueryRunner,
    server_log: ServerLog | None,
    view_files: Sequence[Path],
) -> Forgetting:
    def shared_contexts(what: Forgotten) -> None:
        if what.before is not None:
            contexts.forget_before(what.before)
        else:
            contexts.forget(set(what.iris), set(what.texts))

    def log(what: Forgotten) -> None:
        if server_log is None:
            return
        if what.before is not None:
            server_log.forget_before(what.before)
        else:
            server_log.forget(what.iris, what.texts)

    def views(_what: Forgotten) -> None:
        for path in view_files:
            vacuum(path)

    return Forgetting(
        now=[lambda _what: journal.compact(), shared_contexts, log, lambda _what: queries.forget()],
        after_views=[views, log],  # the log again: lines written while the views were built
    )

"""Row names shared by the runs, the report and the targets."""

VIRTUOSO_JOURNAL = "virtuoso, INGEST_ACK=journal (its default)"
VIRTUOSO_STORE = "virtuoso, INGEST_ACK=store"
BASELINE = "naive baseline"
NO_OP = "no-op server (client + HTTP only)"
ONE_REPORT = "embedded, only the participants report kept current"

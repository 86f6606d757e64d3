"""Where the reports are: the `.rq` files under `sparql/reports/`, and their names' prefix in the catalog (read by
the views' lanes, which serve the reports first, without the reports' service)."""

FOLDER = "reports"

"""Everything that keeps the views current from the journal's stream of new triples, in one package.

- `keeper.py`: the views' keeper (which steps to take next, erasures and clearings) and `lanes.py`, one lane per
  view, so that each view advances at its own pace; `preparing.py`: building and catching views up at start.
- `delta.py`: a batch's new triples, indexed once; `seen_terms.py`: which of its IRIs the store never held.
- `database.py`, `terms.py`, `signal.py`, `cursors.py`: a view's SQLite file, its table of terms, its change
  signal, its pages' cursors.
- `kept_queries/`: a query kept as rows (reports, timeline kinds, SPARQL rules): plan, keys, rows.
- `graph_index.py` (and its `graph_*.py`): the graph's nodes and links; `shape_view.py` (checked by
  `shape_checks.py`): the SHACL findings, node by node; `timeline_rows.py`: the timeline read from its kinds' rows.
- `process.py`, `channel.py`: the views' own process, and the embedded store it reads through the API's.
- `pace.py`: how long a post's answer waits for the views.
- `diff` (`kept_queries/diff.py`) and `kept_queries/describe.py`: `segb upkeep`, for a newcomer debugging a view.
"""

"""Everything that keeps the views current from the journal's stream of new triples, in one package.

- `keeper.py`: the views' keeper: batches of the applied steps (`steps.py`) handed to every view, erasures and
  clearings; `lanes.py`: one lane per view, so that each view advances at its own pace, and posts go ahead of an
  import in the views that read their keys from the store (`lane_hosting.py`: what a lane asks of the keeper);
  `turns.py`: how many views update at once, and which goes next (the reports first); `progress.py`: how far each
  view is; `preparing.py`: builds, catch-ups, views set aside; `view.py`: what a kept view is.
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

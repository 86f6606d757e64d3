#!/usr/bin/env bash
# mypy over the code as it is installed (segb_server.backend, .ui, .examples), from a temporary view of the tree:
# the repository keeps its folders at the top level, so mypy sees them through links named as installed.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
view=$(mktemp -d)
trap 'rm -rf "$view"' EXIT
mkdir "$view/segb_server"
for folder in backend ui examples; do ln -s "$root/$folder" "$view/segb_server/$folder"; done
cd "$view"
# Not `exec`: the shell must outlive mypy for its trap to remove the view.
python3 -m mypy --config-file "$root/pyproject.toml" --cache-dir "$view/.mypy_cache" \
  -p segb_server.backend -p segb_server.ui -p segb_server.examples "$@"

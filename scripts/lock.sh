#!/usr/bin/env bash
# Refresh the hashed locks from pyproject.toml: requirements.lock (what the server needs at run time) and
# requirements-test.lock (that plus the test tools). The test lock is resolved first and the run-time lock is
# constrained to it, so both pin the same versions. Needs pip-tools: `python3 -m pip install pip-tools`.
# Run it with the oldest supported Python (3.11), commit both files, then run ./scripts/test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
# --build-deps-for wheel: setuptools too (pyproject's build-system), so the image builds the project offline.
common=(--quiet --generate-hashes --no-emit-find-links --no-emit-index-url --strip-extras --allow-unsafe --upgrade
  --build-deps-for wheel)
python3 -m piptools compile "${common[@]}" --extra test --output-file requirements-test.lock pyproject.toml
constraints=$(mktemp)
trap 'rm -f "$constraints"' EXIT
grep -E '^[A-Za-z0-9][A-Za-z0-9._-]*==' requirements-test.lock | sed 's/ \\$//' >"$constraints"
python3 -m piptools compile "${common[@]}" --constraint "$constraints" --output-file requirements.lock pyproject.toml
# The temporary file's name, in the header and the `# via` notes, would change the lock at every refresh.
sed -i "s#$constraints#<requirements-test.lock pins>#g" requirements.lock

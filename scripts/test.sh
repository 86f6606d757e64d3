#!/usr/bin/env bash
# The README's test command. Installs what the tests need — Debian's Virtuoso, Chromium, PostgreSQL, nginx and,
# for the container tier, Docker's daemon and debootstrap, when missing; the pinned Python packages from
# requirements-test.lock (hash-checked); the project itself — then runs pytest (the container tier last).
# Extra arguments go to pytest, e.g. `./scripts/test.sh -m "not browser and not virtuoso"`, or
# `./scripts/test.sh -m containers` for the container tier alone.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
command -v virtuoso-t >/dev/null 2>&1 || missing+=(virtuoso-opensource-7-bin)
command -v chromium >/dev/null 2>&1 || missing+=(chromium fonts-dejavu-core)
command -v docker-compose >/dev/null 2>&1 || missing+=(docker-compose)
command -v curl >/dev/null 2>&1 || missing+=(curl)
command -v wget >/dev/null 2>&1 || missing+=(wget)
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

pip=(python3 -m pip install -q --disable-pip-version-check)
"${pip[@]}" --require-hashes -r requirements-test.lock
# The build backend (setuptools) comes from the lock too: no build isolation fetching it unpinned.
"${pip[@]}" --no-deps --no-build-isolation -e .
exec python3 -m pytest "$@"

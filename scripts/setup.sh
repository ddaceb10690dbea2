#!/usr/bin/env bash
# Idempotent set-up: a virtualenv in .venv with the package (and, with --test, its test and scale extras), the
# page's npm packages, and, with --test, Debian's chromium for the browser tests. Fast when nothing
# changed: each step is skipped when its stamp matches its inputs.
set -euo pipefail
cd "$(dirname "$0")/.."
want_test=0
[ "${1:-}" = "--test" ] && want_test=1
PY=${PYTHON:-python3}

stamp_ok() { [ -f "$1" ] && [ "$(cat "$1")" = "$2" ]; }

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi
extras=""
[ $want_test = 1 ] && extras="[test,scale]"
key="$(sha256sum pyproject.toml | cut -c1-16)$extras"
if ! stamp_ok .venv/.setup-stamp "$key"; then
  echo "setup: installing python packages$extras"
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e ".$extras"
  echo "$key" > .venv/.setup-stamp
fi

key="$(sha256sum web/package.json web/package-lock.json | sha256sum | cut -c1-16)"
if ! stamp_ok web/node_modules/.setup-stamp "$key"; then
  echo "setup: installing npm packages for the page"
  (cd web && npm ci --no-audit --no-fund --no-update-notifier --loglevel=error)
  echo "$key" > web/node_modules/.setup-stamp
fi

# OpenMP: a large garment's passes run on two threads, launched from the service's worker threads at once,
# which needs a thread-safe numba threading layer (sim/blocks.py; without it they run on one)
if command -v apt-get >/dev/null && ! ldconfig -p 2>/dev/null | grep -q libgomp.so.1; then
  echo "setup: installing Debian's libgomp1 (OpenMP) for the two-thread passes"
  SUDO=""
  [ "$(id -u)" = 0 ] || SUDO="sudo"
  { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libgomp1 >/dev/null; } \
    || echo "setup: libgomp1 not installed: large garments run on one thread"
fi

if [ $want_test = 1 ] && [ ! -x /usr/bin/chromium ]; then
  echo "setup: installing Debian's chromium for the browser tests"
  SUDO=""
  [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi

#!/usr/bin/env bash
# Set up (idempotent, with the test extra and chromium) and run every test, the test files shared among two
# workers (TRYON_TEST_WORKERS; 0 runs them in this process). Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --test
.venv/bin/tryon warmup  # compile the kernels once, into the disk cache every test process loads
# by file: a module's fixtures (its served process, its catalogue, the quick bench) are made once, on one worker
exec .venv/bin/python -m pytest -n "${TRYON_TEST_WORKERS:-2}" --dist loadfile "$@"

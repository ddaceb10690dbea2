#!/usr/bin/env bash
# Set up (idempotent, with the test extra and chromium) and run every test. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --test
.venv/bin/tryon warmup  # compile the kernels once, into the disk cache every test process loads
exec .venv/bin/python -m pytest "$@"

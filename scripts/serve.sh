#!/usr/bin/env bash
# Set up (idempotent), ingest the catalogue (quick when cached), and run the service.
# Extra arguments go to `tryon serve` (e.g. --host 0.0.0.0 --port 8080).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# compile the kernels (into the disk cache the service loads at start-up) beside the ingestion: on a fresh
# machine both take tens of seconds, on two cores at once
.venv/bin/tryon warmup > /dev/null &
warming=$!
.venv/bin/tryon ingest --catalogue garments/
wait "$warming" || echo "serve: the warm-up failed; the service warms up at start-up instead" >&2
exec .venv/bin/tryon serve "$@"

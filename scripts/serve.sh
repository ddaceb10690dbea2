#!/usr/bin/env bash
# Set up (idempotent), ingest the catalogue (quick when cached), and run the service.
# Extra arguments go to `tryon serve` (e.g. --host 0.0.0.0 --port 8080).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/tryon ingest --catalogue garments/
exec .venv/bin/tryon serve "$@"

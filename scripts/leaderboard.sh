#!/usr/bin/env bash
# Regenerate leaderboard/ from a clean checkout in one command: set up, then run the committed plan
# (leaderboard/plan.yaml). Resumable: run it again after an interruption. Extra arguments go to
# `openreloc-bench campaign` (e.g. --executor ray --ray-address ADDR, --workers N, --render-only). The verdict
# table of the boards replaces the verdict block of README.md and leaderboard/README.md.
# DATA and WORK default to data/ and results/campaign/ (both ignored by git).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
start=$(date +%s)
.venv/bin/openreloc-bench campaign leaderboard/plan.yaml --data "${DATA:-data}" --work "${WORK:-results/campaign}" \
  --out leaderboard --verdict-into README.md --verdict-into leaderboard/README.md "$@"
echo "[leaderboard] total wall time: $(( ($(date +%s) - start) / 60 )) min"

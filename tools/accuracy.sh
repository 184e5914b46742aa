#!/usr/bin/env bash
# Regenerates docs/accuracy_defaults.md: runs scenes/ces_pcb.yaml at its
# own settings and a reference of it converged in its solve (half the
# step, a hundredth of its residual tolerance, a fifth of its penetration
# tolerance) at several seeds, and writes the error of the products and
# of the landing distributions against the reference, with the cost of
# each run and the overlaps each left. A seed feeds the same particles at
# any setting, so the products are compared particle by particle: the
# error's standard error is what the settings' differences give, not the
# sampling of the feed.
# Needs a built ces-sim (default build/ces-sim) and python3.
# Usage: tools/accuracy.sh [--report-only] [path/to/ces-sim]
# (--report-only: the runs in out/accuracy as they are, the document again.)
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/runs.sh
out=out/accuracy
doc=docs/accuracy_defaults.md
seeds=(1 2 3)
mkdir -p "$out"

if ! $report_only; then
  for seed in "${seeds[@]}"; do
    run "$out" "defaults_$seed" scenes/ces_pcb.yaml --seed "$seed"
    run "$out" "reference_$seed" scenes/ces_pcb.yaml --seed "$seed" "${reference[@]}"
  done
fi
python3 tools/accuracy_report.py "$out" "$doc" "${reference[*]}" "${seeds[@]}"


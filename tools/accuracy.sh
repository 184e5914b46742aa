#!/usr/bin/env bash
# Regenerates docs/accuracy_defaults.md: runs scenes/ces_pcb.yaml at its
# own settings and a reference of it converged in its solve (half the
# step, a thirtieth of its residual tolerance, a fifth of its penetration
# tolerance) at several seeds, and writes the error of the products and
# of the landing distributions against the reference, with the cost of
# each run and the overlaps each left. A seed feeds the same particles at
# any setting, so the products are compared particle by particle: the
# error's standard error is what the settings' differences give, not the
# sampling of the feed. Four more sections split that error: the defaults
# against their own step's converged solve (the reference's tolerances at
# the defaults' step: the solve's share), that converged solve against the
# reference (the step's share), a residual tolerance of 1 mm/s at the
# defaults' step against the converged solve (what the defaults' tighter
# 0.3 mm/s buys), and the reference against its solve tightened again (half its
# tolerances, twice its iteration cap: how far the reference itself is
# from converged in its solve).
# Needs a built ces-sim (default build/ces-sim) and python3.
# Usage: tools/accuracy.sh [--report-only] [path/to/ces-sim]
# (--report-only: the runs in out/accuracy as they are, the document again.)
# A full run takes over an hour on 2 cores, most of it in the tightened
# references.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/runs.sh
out=out/accuracy
doc=docs/accuracy_defaults.md
seeds=(1 2 3)
solve=("${converged_solve[@]}")
loose=(--set solver.tolerance=1e-3)
tight=(--set time.step=0.125ms --set solver.tolerance=5e-6 --set solver.penetration_tolerance=0.01
       --set solver.max_iterations=800)
mkdir -p "$out"

if ! $report_only; then
  for seed in "${seeds[@]}"; do
    run "$out" "defaults_$seed" scenes/ces_pcb.yaml --seed "$seed"
    run "$out" "reference_$seed" scenes/ces_pcb.yaml --seed "$seed" "${reference[@]}"
    run "$out" "solve_$seed" scenes/ces_pcb.yaml --seed "$seed" "${solve[@]}"
    run "$out" "loose_$seed" scenes/ces_pcb.yaml --seed "$seed" "${loose[@]}"
    run "$out" "tight_$seed" scenes/ces_pcb.yaml --seed "$seed" "${tight[@]}"
  done
fi
python3 tools/accuracy_report.py "$out" "$doc" "${reference[*]}" "${seeds[@]}"
echo >> "$doc"
python3 tools/accuracy_report.py --section defaults "The defaults against a converged solve at their own step" \
  "The defaults against the same step with the reference's tolerances and cap \
(\`${solve[*]}\`): the part of the error above that the solve makes; the rest is the \
step's. The reference in this section is that run." \
  --against solve "$out" "$doc" "${solve[*]}" "${seeds[@]}"
echo >> "$doc"
python3 tools/accuracy_report.py --section solve "A converged solve at the defaults' step against the reference" \
  "The runs of the section above at the defaults' step, their solve converged \
(\`${solve[*]}\`), against the reference at half that step: the part of the error that \
the step makes." \
  "$out" "$doc" "${reference[*]}" "${seeds[@]}"
echo >> "$doc"
python3 tools/accuracy_report.py --section loose "A looser residual tolerance at the defaults' step" \
  "The defaults with a residual tolerance of 1 mm/s instead of 0.3 (\`${loose[*]}\`) \
against the converged solve at the same step: the error the defaults' tighter tolerance \
takes away, and what it saves. The reference in this section is the converged solve." \
  --against solve "$out" "$doc" "${loose[*]}" "${seeds[@]}"
echo >> "$doc"
python3 tools/accuracy_report.py --section tight "The reference against a tighter solve of itself" \
  "The reference again with its solve tightened at the same step (\`${tight[*]}\`), \
compared with the reference as the defaults are above: how far the reference's products \
are from converged in its solve. A difference of the defaults well above this one is their \
own error, not the reference's." \
  "$out" "$doc" "${tight[*]}" "${seeds[@]}"


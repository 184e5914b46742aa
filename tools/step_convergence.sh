#!/usr/bin/env bash
# Regenerates docs/accuracy_step.md: whether the products of
# scenes/ces_pcb.yaml converge as the step shrinks. Runs the scene at its
# own settings at 0.25, 0.125, 0.0625 and 0.03125 ms (seed 1), then the
# same particles fed sparsely (2 g/s for 10 s, so that they land one by
# one and barely touch each other), with and without the electrostatics,
# and with them and the solve converged (a residual tolerance of 1e-5 m/s,
# a thirtieth of the default, and up to 400 iterations), at 0.25, 0.125
# and 0.0625 ms; and writes
# their products against the finest step of each series, particle by
# particle.
# Needs a built ces-sim (default build/ces-sim) and python3.
# Usage: tools/step_convergence.sh [--report-only] [path/to/ces-sim]
# (--report-only: the runs in out/step as they are, the document again.)
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/runs.sh
out=out/step
doc=docs/accuracy_step.md
mkdir -p "$out"
sparse=(--set feeds.nozzle.rate=2g/s --set feeds.nozzle.duration=10s --set time.end=14s)

# The scene without its electrostatics: the machine file with that
# section cut out, beside a copy of the scene that includes it and does
# not ask for the field's picture.
uncharged=$out/uncharged/ces_pcb.yaml
mkdir -p "$out/uncharged/machines"
grep -v '^  field:' scenes/ces_pcb.yaml > "$uncharged"
cp scenes/machines/ces_splitters.yaml "$out/uncharged/machines/"
awk '/^[a-z_]+:/ { skip = ($1 == "electrostatics:") } !skip' scenes/machines/ces_machine.yaml \
  > "$out/uncharged/machines/ces_machine.yaml"

# One run: NAME SCENE ARGS..., on one thread, seed 1.
one() { run "$out" "$1" "$2" --threads 1 --seed 1 "${@:3}"; }
if ! $report_only; then
  # Two at a time, the longest first.
  one dense_0.03125 scenes/ces_pcb.yaml --set time.step=0.03125ms &
  finest=$!
  one dense_0.0625 scenes/ces_pcb.yaml --set time.step=0.0625ms
  one dense_0.125 scenes/ces_pcb.yaml --set time.step=0.125ms
  one dense_0.25 scenes/ces_pcb.yaml --set time.step=0.25ms
  wait $finest
  for step in 0.0625 0.125 0.25; do
    one "sparse_$step" scenes/ces_pcb.yaml "${sparse[@]}" --set time.step=${step}ms &
    charged=$!
    one "uncharged_$step" "$uncharged" "${sparse[@]}" --set time.step=${step}ms
    wait $charged
  done
  converged=("${sparse[@]}" --set solver.tolerance=1e-5 --set solver.max_iterations=400)
  one converged_0.0625 scenes/ces_pcb.yaml "${converged[@]}" --set time.step=0.0625ms &
  finest=$!
  one converged_0.125 scenes/ces_pcb.yaml "${converged[@]}" --set time.step=0.125ms
  one converged_0.25 scenes/ces_pcb.yaml "${converged[@]}" --set time.step=0.25ms
  wait $finest
fi
python3 tools/step_report.py "$out" "$doc"


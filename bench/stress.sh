#!/bin/bash
# Full versions of the stress scenes (scenes/stress/): runs each as it
# stands (tests/stress_test.cpp runs short versions) and prints each run's
# row of the pass criteria's measures and verdict as it ends; at the end
# writes the table, OUT_DIR/accuracy_stress.md (bench/stress_report.py).
# Usage, from the repository root:
#   bash bench/stress.sh [OUT_DIR] [SCENE_NAME...]        (default: bench/out/stress, all)
# The 1e5-particle dense flow and step_10ms are the long ones: name the
# others to leave them out. One thread each.
set -u
out=${1:-bench/out/stress}; shift || true
bin=${CES_SIM:-build/ces-sim}
runs=("$@")
[ ${#runs[@]} -eq 0 ] && runs=(mass_ratio_sphere mass_ratio_plate drum_fine impact_plate
  impact_mesh step_10ms friction_0 friction_1 bin_pile dense_flow degenerate)
report=bench/stress_report.py
for name in "${runs[@]}"; do
  scene=scenes/stress/$name.yaml sets=()
  case $name in
    friction_0) scene=scenes/stress/friction.yaml ;;
    friction_1) scene=scenes/stress/friction.yaml
                sets=(--set materials.grain.friction=1 --set materials.steel.friction=1) ;;
  esac
  "$bin" "$scene" -o "$out/$name" --threads 1 --quiet --include-path scenes "${sets[@]}"
  python3 "$report" --row "$out" "$name"
done
python3 "$report" --doc "$out" "$out/accuracy_stress.md" "${runs[@]}"

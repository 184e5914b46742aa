#!/bin/bash
# Full versions of the stress scenes (scenes/stress/): runs each as it
# stands (tests/stress_test.cpp runs short versions) and prints one line per
# run with the pass criteria's measures. Usage, from the repository root:
#   bash bench/stress.sh [OUT_DIR] [SCENE_NAME...]        (default: bench/out/stress, all)
# The 1e5-particle dense flow is the long one (73 minutes): name the
# others to leave it out. One thread each.
set -u
out=${1:-bench/out/stress}; shift || true
bin=${CES_SIM:-build/ces-sim}
runs=("$@")
[ ${#runs[@]} -eq 0 ] && runs=(mass_ratio_sphere mass_ratio_plate drum_fine impact_plate
  impact_mesh step_10ms friction_0 friction_1 bin_pile dense_flow degenerate)
for name in "${runs[@]}"; do
  scene=scenes/stress/$name.yaml sets=()
  case $name in
    friction_0) scene=scenes/stress/friction.yaml ;;
    friction_1) scene=scenes/stress/friction.yaml
                sets=(--set materials.grain.friction=1 --set materials.steel.friction=1) ;;
  esac
  "$bin" "$scene" -o "$out/$name" --threads 1 --quiet --include-path scenes "${sets[@]}"
  python3 - "$out/$name/summary.json" "$name" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); s = j["solver"]; e = j["energy"]; b = j["balance"]
gain = e["max_gain_relative"]
print(f"{sys.argv[2]:18s} complete={j['complete']} wall={j['wall_time_s']['total']:.0f}s "
      f"particles={b['fed']['count']} left_domain={b['lost_by_reason']['left domain']['count']} "
      f"non_finite={b['lost_by_reason']['non-finite state']['count']} balance_exact={b['exact']} penetration={100 * s['max_penetration_relative']:.2f}% "
      f"wall_penetration={100 * s['max_wall_penetration_relative']:.2f}% "
      f"energy_gain={gain if isinstance(gain, str) else f'{100 * gain:.3g}%'} "
      f"residual_p95={s['residual_p95_mps']:.2g}m/s at_cap={s['steps_at_iteration_cap']}/{s['steps_solved']} "
      f"{j['reason']}")
PY
done

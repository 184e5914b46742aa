#!/bin/bash
# The figures of docs/reliability.md, measured: inputs fuzzed, crashes,
# hangs and memory blow-ups per fuzz target, and results lost by runs
# killed with SIGKILL. Writes bench/out/reliability.txt (and prints it, then
# the tables bench/reliability_figures.py makes of it);
# bench/results/reliability.txt is a committed copy. Usage, from the
# repository root, after `bash .ci/fuzz` (the fuzz build in build-fuzz/) and
# the Release build in build/:
#   bash bench/reliability.sh [FUZZ_SECONDS] [KILL_TRIALS]    (default: 600, 20)
# The three targets fuzz at once, FUZZ_SECONDS each, with the limits of the
# CI's fuzz tests (fuzz/limits), from the seeds and past findings into a
# corpus of their own.
#
# Each kill trial starts tests/scenes/tiny.yaml (2.5 s simulated, a
# checkpoint every 0.1 s) into a folder holding a complete earlier run,
# kills it with SIGKILL at a random moment of its run, checks that the
# earlier run's files are byte for byte as they were, then resumes it and
# checks that its results are the bytes of an uninterrupted run. The
# resumed run is the next trial's earlier run.
set -eu
seconds=${1:-600}
trials=${2:-20}
bin=${CES_SIM:-build/ces-sim}
fuzz=${FUZZ_BUILD:-build-fuzz}/fuzz
out=bench/out/reliability
report=bench/out/reliability.txt
rm -rf "$out"
mkdir -p "$out"

run_args=(tests/scenes/tiny.yaml --set "time.end=2.5 s" --set "feeds.hopper.duration=2 s"
          --set "output.checkpoint.every=0.1 s" --quiet)
results=(bins.csv products.csv crossings.csv lost.csv trajectories.csv trajectories.pvd)

# Hashes of a folder's files, the checkpoint folder aside.
hashes() { (cd "$1" && find . -path ./partial -prune -o -type f -print | LC_ALL=C sort | xargs sha256sum); }
# Hashes of the results alone (summary.json holds wall times).
result_hashes() {
  (cd "$1" && sha256sum "${results[@]}" && find trajectories -type f | LC_ALL=C sort | xargs sha256sum)
}

mapfile -t limits < <(grep '^-' fuzz/limits)

fuzz_target() {
  local target=$1 dict=$2 dir=$out/$1
  mkdir -p "$dir/corpus" "$dir/findings"
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    LSAN_OPTIONS=suppressions=fuzz/lsan.supp \
    "$fuzz/fuzz_$target" -max_total_time="$seconds" "${limits[@]}" \
      -print_final_stats=1 -dict="$fuzz/$dict" \
      -artifact_prefix="$dir/findings/" "$dir/corpus" "$fuzz/seeds/$target" \
      "fuzz/regressions/$target" > "$dir/log.txt" 2>&1 || true
  local f=$dir/findings
  printf '%-11s inputs=%s seconds=%s crashes=%s hangs=%s memory=%s leaks=%s slowest_s=%s peak_rss_mb=%s\n' \
    "$target" \
    "$(awk '/stat::number_of_executed_units/ {print $2}' "$dir/log.txt")" "$seconds" \
    "$(find "$f" -name 'crash-*' -o -name 'deadly-*' | wc -l)" \
    "$(find "$f" -name 'timeout-*' | wc -l)" "$(find "$f" -name 'oom-*' | wc -l)" \
    "$(find "$f" -name 'leak-*' | wc -l)" \
    "$(awk '/stat::slowest_unit_time_sec/ {print $2}' "$dir/log.txt")" \
    "$(awk '/stat::peak_rss_mb/ {print $2}' "$dir/log.txt")" > "$dir/line.txt"
}

fuzz_target scene_yaml scene.dict &
fuzz_target scene_json scene.dict &
fuzz_target units units.dict &
wait

# The uninterrupted run, its wall time, and the first earlier run.
start=$(date +%s%N)
"$bin" "${run_args[@]}" -o "$out/whole"
wall=$(python3 -c "print(($(date +%s%N) - $start) / 1e9)")
result_hashes "$out/whole" > "$out/whole.sha"
dir=$out/killed
"$bin" "${run_args[@]}" -o "$dir"
earlier_lost=0 resumed_differ=0 killed=0
for i in $(seq "$trials"); do
  hashes "$dir" > "$out/before.sha"
  delay=$(python3 -c "import random; print(round(random.uniform(0, $wall), 3))")
  "$bin" "${run_args[@]}" -o "$dir" & pid=$!
  sleep "$delay"
  if kill -KILL "$pid" 2>/dev/null; then
    killed=$((killed + 1))
    wait "$pid" 2>/dev/null || true
    hashes "$dir" > "$out/after.sha"
    cmp -s "$out/before.sha" "$out/after.sha" || earlier_lost=$((earlier_lost + 1))
  else  # it completed first, replacing the earlier run as it should
    wait "$pid"
  fi
  if [ -f "$dir/summary.json" ] && [ ! -d "$dir/partial" ]; then
    :  # complete
  elif [ -f "$dir/partial/checkpoint.bin" ]; then
    "$bin" resume "$dir" --quiet
  else  # killed before its first checkpoint: run again
    "$bin" "${run_args[@]}" -o "$dir"
  fi
  result_hashes "$dir" | cmp -s - "$out/whole.sha" || resumed_differ=$((resumed_differ + 1))
done

{
  echo "# bash bench/reliability.sh $seconds $trials"
  echo "# machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) cores"
  echo "# fuzz targets (clang, libFuzzer, ASan, UBSan), at once:"
  cat "$out"/scene_yaml/line.txt "$out"/scene_json/line.txt "$out"/units/line.txt
  echo "# runs killed with SIGKILL at a random moment (uninterrupted run: ${wall%.*} s):"
  echo "kill_trials=$trials killed_while_running=$killed earlier_results_changed=$earlier_lost resumed_results_differing=$resumed_differ"
} | tee "$report"
python3 bench/reliability_figures.py "$report"

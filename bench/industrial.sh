#!/bin/bash
# The plant-scale scene, scenes/ces_industrial.yaml, measured: one run on
# every core to END simulated seconds (default: the scene's 5 s), its last
# 0.05 s resumed from its checkpoint on one thread and on two (the machine
# full), then the first SHORT seconds (default 0.1) on one thread and on
# two, three times each, alternating.
# Writes bench/out/industrial/industrial.txt (and prints it): the machine,
# its load, the commands, and per run the wall time per stage, particles,
# contacts, iterations, residual, overlap and peak resident memory (GNU
# time's maximum RSS), the memory per particle and per contact, and the
# 1 -> 2 thread speed-up. Usage, from the repository root:
#   bash bench/industrial.sh [END [SHORT]]
# The runs are started at nice 10: on a shared machine they take what the
# others leave, and the file says how loaded it was.
set -eu
scene_end=5  # scenes/ces_industrial.yaml's time.end, in seconds
end=${1:-$scene_end}
short=${2:-0.1}
bin=${CES_SIM:-build/ces-sim}
scene=scenes/ces_industrial.yaml
out=bench/out/industrial
mkdir -p "$out"
cores=$(nproc)

# One run: its folder, and GNU time's report beside it; more --set pairs
# may follow.
run() {
  local name=$1 threads=$2 until=$3 dir=$out/$1
  shift 3
  rm -rf "$dir"
  echo "nice -n 10 $bin $scene --set time.end=${until}s ${*:+$* }--threads $threads -q -o $dir" \
    > "$out/$name.command"
  /usr/bin/time -v -o "$out/$name.time" nice -n 10 "$bin" "$scene" --set "time.end=${until}s" \
    "$@" --threads "$threads" -q -o "$dir" > /dev/null
}

# The full run's checkpoint, copied as it appears (the run clears it when
# it ends) into two folders that `ces-sim resume` continues.
span=0.05
at=$(python3 -c "print(round($end - $span, 6)) if $end > 2 * $span else exit(1)") || {
  echo "bench/industrial.sh: END must be over twice $span s" >&2
  exit 2
}
keep_checkpoint() {
  local from=$out/full/partial
  until [ -f "$from/checkpoint.bin" ]; do sleep 1; done
  for threads in 1 2; do
    rm -rf "$out/resume_$threads"
    mkdir -p "$out/resume_$threads"
    cp -r "$from" "$out/resume_$threads/partial"
  done
}
resume() {
  local threads=$1 dir=$out/resume_$1
  echo "nice -n 10 $bin resume $dir --threads $threads -q" > "$out/resume_$threads.command"
  /usr/bin/time -v -o "$out/resume_$threads.time" nice -n 10 "$bin" resume "$dir" \
    --threads "$threads" -q > /dev/null
}

# The load the machine carried: its 1-minute load average every 10 s.
sample_load() {
  while :; do cut -d' ' -f1 /proc/loadavg >> "$out/load.txt"; sleep 10; done
}
rm -f "$out/load.txt"
sample_load &
sampler=$!
keeper=
trap 'kill $sampler $keeper 2>/dev/null || true' EXIT

start=$(date -u '+%Y-%m-%d %H:%M UTC')
run empty "$cores" 0.0005  # one step: the process without particles
keep_checkpoint &
keeper=$!
run full "$cores" "$end" --set "output.checkpoint.every=${at}s"
wait $keeper
resume 1
resume 2
# The short runs three times each, alternating: on a shared machine a busy
# moment moves one of them, not the speed-up taken from their medians.
for k in 1 2 3; do
  run "one_$k" 1 "$short"
  run "two_$k" 2 "$short"
done
kill $sampler

python3 bench/industrial_report.py "$out" "$start" "$cores" "$end" "$short" "$scene_end" "$at" \
  > "$out/industrial.txt"
cat "$out/industrial.txt"

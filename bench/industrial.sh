#!/bin/bash
# The plant-scale scene, scenes/ces_industrial.yaml, measured: one run on
# every core to END simulated seconds (default: the scene's 5 s), its last
# 0.05 s resumed from its checkpoint on one thread and on two (the machine
# full), then the first SHORT seconds (default 0.1) on one thread and on
# two, three times each, alternating.
# Writes bench/out/industrial/industrial.txt (and prints it): the machine,
# its load, the commands, and per run the wall time per stage, particles,
# contacts, iterations, residual, overlap and peak resident memory (GNU
# time's maximum RSS), the memory per particle and per contact (fitted to
# the full run's steps.csv), and the 1 -> 2 thread speed-up. Usage, from the repository root:
#   bash bench/industrial.sh [END [SHORT]]
#   bash bench/industrial.sh --resume    # the bench an interruption stopped
# The runs are started at nice 10: on a shared machine they take what the
# others leave, and the file says how loaded it was.
# The full run writes a checkpoint every 0.05 s, so that a bench stopped
# midway (the scene's 5 s take hours) goes on with --resume, from the full
# run's last checkpoint, with the same binary; its summary counts the wall
# time of every process it took.
set -eu
scene_end=5  # scenes/ces_industrial.yaml's time.end, in seconds
bin=${CES_SIM:-build/ces-sim}
scene=scenes/ces_industrial.yaml
out=bench/out/industrial
mkdir -p "$out"
cores=$(nproc)
resuming=false
if [ "${1:-}" = --resume ]; then
  [ $# -eq 1 ] || { echo "bench/industrial.sh: --resume takes no other argument" >&2; exit 2; }
  [ -f "$out/bench.args" ] || { echo "bench/industrial.sh: no bench in $out to resume" >&2; exit 2; }
  resuming=true
  read -r end short < "$out/bench.args"
else
  end=${1:-$scene_end}
  short=${2:-0.1}
fi

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

# The full run's checkpoint at AT, END less one span, copied as it
# appears (the next one replaces it, and the run clears the last when it
# ends) into two folders that `ces-sim resume` continues.
span=0.05
at=$(python3 -c "
n = $end / $span
print(round($end - $span, 6)) if n > 2 and abs(n - round(n)) < 1e-9 else exit(1)") || {
  echo "bench/industrial.sh: END must be a multiple of $span s, over twice it" >&2
  exit 2
}
checkpoint_at() {  # whether the full run's checkpoint is that at AT (it writes the summary after it)
  python3 - "$out/full/partial" "$at" <<'PY'
import json, pathlib, sys
folder, at = pathlib.Path(sys.argv[1]), float(sys.argv[2])
try:
    t = json.loads((folder / "summary.json").read_text())["simulated_time_s"]
except (OSError, ValueError, KeyError):
    sys.exit(1)
sys.exit(0 if (folder / "checkpoint.bin").exists() and abs(t - at) < 1e-9 else 1)
PY
}
ended_early() {
  echo "bench/industrial.sh: the full run ended before its checkpoint at $at s was kept;" \
    "run the bench afresh" >&2
  exit 1
}
# Looks again only when the run has written its summary (each checkpoint,
# minutes apart), so that the watching costs the timed run nothing.
keep_checkpoint() {
  local seen= now
  while :; do
    now=$(stat -c %Y "$out/full/partial/summary.json" 2>/dev/null || true)
    if [ "$now" != "$seen" ]; then
      seen=$now
      checkpoint_at && break
      complete "$out/full" && ended_early
    fi
    sleep 5
  done
  for threads in 1 2; do
    rm -rf "$out/resume_$threads"
    mkdir -p "$out/resume_$threads"
    cp -r "$out/full/partial" "$out/resume_$threads/partial"
  done
  # The summary the resumes start from (ces-sim removes partial/ when a
  # run completes): each resume's own stage times are its final less this.
  cp "$out/resume_1/partial/summary.json" "$out/checkpoint.summary.json"
  touch "$out/resume.ready"
}
complete() {  # whether the run in folder $1 completed
  python3 -c "import json, sys; sys.exit(0 if json.load(open(sys.argv[1])).get('complete') else 1)" \
    "$1/summary.json" 2>/dev/null
}
# The full run: started afresh (also when stopped before its first
# checkpoint), or resumed from its last checkpoint, each process under GNU
# time of its own (full.time, full.time.2, ...).
full_run() {
  if ! $resuming || { ! complete "$out/full" && [ ! -f "$out/full/partial/checkpoint.bin" ]; }; then
    run full "$cores" "$end" --set "output.checkpoint.every=${span}s"
    return
  fi
  complete "$out/full" && return
  local k=2
  while [ -e "$out/full.time.$k" ]; do k=$((k + 1)); done
  echo "nice -n 10 $bin resume $out/full --threads $cores -q" >> "$out/full.command"
  /usr/bin/time -v -o "$out/full.time.$k" nice -n 10 "$bin" resume "$out/full" \
    --threads "$cores" -q > /dev/null
}
resume() {
  local threads=$1 dir=$out/resume_$1
  complete "$dir" && return  # done before the bench was stopped
  echo "nice -n 10 $bin resume $dir --threads $threads -q" > "$out/resume_$threads.command"
  /usr/bin/time -v -o "$out/resume_$threads.time" nice -n 10 "$bin" resume "$dir" \
    --threads "$threads" -q > /dev/null
}

# The load the machine carried: its 1-minute load average every 10 s.
sample_load() {
  while :; do cut -d' ' -f1 /proc/loadavg >> "$out/load.txt"; sleep 10; done
}
if ! $resuming; then
  rm -rf "$out"  # every file of an earlier bench, so that none is taken for this one's
  mkdir -p "$out"
  echo "$end $short" > "$out/bench.args"
  date -u '+%Y-%m-%d %H:%M UTC' > "$out/start.txt"
  # The checkout's commit when the bench began, for the report (HEAD may
  # move while it runs; a CES_SIM binary may come from another).
  git describe --always --dirty > "$out/bench.commit" 2>/dev/null || echo unknown > "$out/bench.commit"
fi
# The binary the bench began with: a resumed run's steps must be its own.
binary_sum=$(sha256sum "$bin" | cut -d' ' -f1)
if $resuming && [ -f "$out/bench.binary" ] && [ "$(cat "$out/bench.binary")" != "$binary_sum" ]; then
  echo "bench/industrial.sh: $bin is not the binary this bench began with" >&2
  exit 2
fi
if $resuming; then date -u '+%Y-%m-%d %H:%M UTC' >> "$out/resumed.txt"; fi
echo "$binary_sum" > "$out/bench.binary"
sample_load &
sampler=$!
keeper=
trap 'kill $sampler $keeper 2>/dev/null || true' EXIT

start=$(cat "$out/start.txt")
# One step: the process without particles.
$resuming && complete "$out/empty" || run empty "$cores" 0.0005
if [ ! -e "$out/resume.ready" ]; then
  if $resuming && complete "$out/full"; then ended_early; fi
  keep_checkpoint &
  keeper=$!
  renice -n 10 -p "$keeper" > /dev/null
fi
full_run
[ -z "$keeper" ] || wait $keeper
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

#!/bin/bash
# A run on a machine whose cores other processes keep busy: one busy loop
# per core runs beside ces-sim while it runs each scene at --threads 1,
# --threads 2 and the default (threads chosen as the run goes), in rounds
# that turn the order each time. Writes bench/out/busy/busy.txt (and prints it):
# each run's wall time, and per scene the medians and their ratios to one
# thread. Usage, from the repository root:
#   bash bench/busy.sh [ROUNDS] [SCENE...]    (default: 5, hopper.yaml and ces_pcb to 0.5 s)
# Run it on an otherwise quiet machine: the loops are the only load meant.
set -eu
rounds=${1:-5}; shift || true
bin=${CES_SIM:-build/ces-sim}
out=bench/out/busy
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=(scenes/hopper.yaml "scenes/ces_pcb.yaml --set time.end=0.5s --set time.until=end")
cores=$(nproc)
mkdir -p "$out"

loops=()
stop_loops() { for p in "${loops[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap stop_loops EXIT
for _ in $(seq "$cores"); do (while :; do :; done) & loops+=($!); done
sleep 1

# One run: its wall time (s) and the threads the run chose, from its summary.
run() {
  local scene=$1 threads=$2 dir=$out/run
  rm -rf "$dir"
  # shellcheck disable=SC2086
  $bin $scene -o "$dir" --quiet $threads > /dev/null
  python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); c=j["threads_chosen"]["steps_at"]; print(j["wall_time_s"]["total"], ",".join(f"{k}:{v}" for k,v in c.items()))' "$dir/summary.json"
}

report=$out/busy.txt
{
  echo "# ces-sim with $cores busy loops beside it (one per core)"
  echo "# machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $cores cores"
  echo "# command: bash bench/busy.sh $rounds${*:+ $*}"
  echo "# scene | threads | round | wall s | steps at each thread count"
} > "$report"
for scene in "${scenes[@]}"; do
  for r in $(seq "$rounds"); do
    order=("--threads 1" "--threads 2" "")
    [ $((r % 2)) -eq 0 ] && order=("" "--threads 2" "--threads 1")
    for t in "${order[@]}"; do
      read -r wall chosen < <(run "$scene" "$t")
      echo "$scene | ${t:-default} | $r | $wall | $chosen" >> "$report"
    done
  done
done
python3 - "$report" >> "$report" <<'PY'
import statistics, sys
rows = [l.split(" | ") for l in open(sys.argv[1]) if not l.startswith("#")]
print("# scene | threads | median wall s | ratio to --threads 1")
for scene in dict.fromkeys(r[0] for r in rows):
    med = {t: statistics.median(float(r[3]) for r in rows if r[0] == scene and r[1] == t)
           for t in ("--threads 1", "--threads 2", "default")}
    for t, m in med.items():
        print(f"{scene} | {t} | {m:.3f} | {m / med['--threads 1']:.2f}")
PY
cat "$report"

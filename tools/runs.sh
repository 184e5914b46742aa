# Sourced by the tools that run ces-sim many times and write a document
# from the runs (tools/accuracy.sh, tools/accuracy_industrial.sh,
# tools/step_convergence.sh). Reads the arguments [--report-only]
# [path/to/ces-sim] into report_only and sim; defines run, converged_solve
# and reference.

report_only=false
if [[ ${1:-} == --report-only ]]; then report_only=true; shift; fi
sim=${1:-build/ces-sim}

# run OUT NAME SCENE ARGS...: runs SCENE into OUT/NAME, keeping the load
# average before and after in OUT/NAME.load. A run that fails stops the
# tool, naming the run: a document made without it would be wrong.
run() {
  local out=$1 name=$2 scene=$3
  shift 3
  cut -d' ' -f1 /proc/loadavg > "$out/$name.load"
  "$sim" "$scene" -o "$out/$name" --quiet "$@" ||
    { echo "$0: the run $name failed: $sim $scene -o $out/$name $*" >&2; exit 1; }
  cut -d' ' -f1 /proc/loadavg >> "$out/$name.load"
}

# The converged reference of tools/accuracy.sh, against which
# tools/accuracy_industrial.sh measures too: half the reference scene's
# 0.25 ms step, and its solve converged (converged_solve, which
# tools/accuracy.sh also runs at the scene's own step): a thirtieth of its
# residual tolerance (0.3 mm/s) and a fifth of its penetration tolerance
# (0.1).
converged_solve=(--set solver.tolerance=1e-5 --set solver.penetration_tolerance=0.02
                 --set solver.max_iterations=400)
reference=(--set time.step=0.125ms "${converged_solve[@]}")

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
report_only=false
if [[ ${1:-} == --report-only ]]; then report_only=true; shift; fi
sim=${1:-build/ces-sim}
out=out/accuracy
doc=docs/accuracy_defaults.md
seeds=(1 2 3)
mkdir -p "$out"
# Half the scene's 0.25 ms step, a hundredth of its residual tolerance
# (1 mm/s) and a fifth of its penetration tolerance (0.1).
reference=(--set time.step=0.125ms --set solver.tolerance=1e-5 --set solver.penetration_tolerance=0.02
           --set solver.max_iterations=400)

# Runs a scene into $out/NAME and keeps the load average before and after.
run() {
  local name=$1
  shift
  cut -d' ' -f1 /proc/loadavg > "$out/$name.load"
  "$sim" scenes/ces_pcb.yaml -o "$out/$name" --quiet "$@" || true
  cut -d' ' -f1 /proc/loadavg >> "$out/$name.load"
}
if ! $report_only; then
  for seed in "${seeds[@]}"; do
    run "defaults_$seed" --seed "$seed"
    run "reference_$seed" --seed "$seed" "${reference[@]}"
  done
fi

python3 - "$out" "$doc" "$(nproc)" "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)" \
  "${reference[*]}" "${seeds[@]}" <<'EOF'
import csv, json, random, sys
out, doc, cores, cpu, reference, *seeds = sys.argv[1:]
runs = [f"{kind}_{seed}" for seed in seeds for kind in ("defaults", "reference")]

def fates(run):
    """Per particle id: (material, mass, product), product None when lost.
    Checked against the run's products.csv, which the run computed itself."""
    out_ = {}
    for r in csv.DictReader(open(f"{out}/{run}/crossings.csv")):
        if r["collector"] == "bins":
            out_[r["id"]] = (r["material"], float(r["mass_kg"]), r["product"])
    for r in csv.DictReader(open(f"{out}/{run}/lost.csv")):
        out_[r["id"]] = (r["material"], float(r["mass_kg"]), None)
    mine = products([out_])
    for r in csv.DictReader(open(f"{out}/{run}/products.csv")):
        g, rec = mine.get((r["product"], r["material"]), (0.0, 0.0))
        assert abs(g - float(r["grade"])) < 1e-6 and abs(rec - float(r["recovery"])) < 1e-6, (run, r)
    return out_

def products(runs_fates, weights=None):
    """Grade and recovery per (product, material) over several runs'
    particles, each counted `weights[k][id]` times (1 when None)."""
    in_product, known = {}, {}
    for k, f in enumerate(runs_fates):
        w = weights[k] if weights else None
        for pid, (material, mass, product) in f.items():
            m = mass * (w.get(pid, 0) if w is not None else 1)
            known[material] = known.get(material, 0.0) + m
            if product is not None:
                key = (product, material)
                in_product[key] = in_product.get(key, 0.0) + m
    result = {}
    for (product, material), m in in_product.items():
        total = sum(v for (p, _), v in in_product.items() if p == product)
        result[(product, material)] = (m / total if total else 0.0,
                                       m / known[material] if known[material] else 0.0)
    for product in {p for p, _ in in_product}:
        for material in known:
            result.setdefault((product, material), (0.0, 0.0))
    return result

def difference(a, b, weights=None):
    pa, pb = products(a, weights), products(b, weights)
    return {k: (pa.get(k, (0, 0))[0] - pb.get(k, (0, 0))[0],
                pa.get(k, (0, 0))[1] - pb.get(k, (0, 0))[1]) for k in set(pa) | set(pb)}

def paired_errors(a, b, resamples=1000):
    """Standard error of the difference by the bootstrap over particles,
    each seed's particles resampled on their own, one draw serving both
    runs (the same particle in each): a particle that lands in the same
    product in both runs adds nothing to it."""
    rng = random.Random(1)
    sums = {}
    for _ in range(resamples):
        weights = []
        for f in a:
            ids = list(f)
            w = {}
            for pid in rng.choices(ids, k=len(ids)):
                w[pid] = w.get(pid, 0) + 1
            weights.append(w)
        for k, (dg, dr) in difference(a, b, weights).items():
            s = sums.setdefault(k, [0.0, 0.0, 0.0, 0.0])
            s[0] += dg; s[1] += dg * dg; s[2] += dr; s[3] += dr * dr
    return {k: tuple(max(s[i + 1] / resamples - (s[i] / resamples) ** 2, 0.0) ** 0.5
                     for i in (0, 2)) for k, s in sums.items()}

def landing(run, material):
    """Mass per bin of the bins collector and the bins' width."""
    rows = [r for r in csv.DictReader(open(f"{out}/{run}/bins.csv"))
            if r["collector"] == "bins" and r["material"] == material]
    return [float(r["mass_kg"]) for r in rows], float(rows[0]["to_m"]) - float(rows[0]["from_m"])

def w1(a, b, width):
    """Wasserstein-1 distance of two mass distributions on the same bins,
    each normalised: the area between their cumulative sums."""
    ta, tb = sum(a) or 1.0, sum(b) or 1.0
    ca = cb = area = 0.0
    for x, y in zip(a, b):
        ca, cb = ca + x / ta, cb + y / tb
        area += abs(ca - cb) * width
    return area

summary = {run: json.load(open(f"{out}/{run}/summary.json")) for run in runs}
load = {run: open(f"{out}/{run}.load").read().split() for run in runs}
mine = [fates(f"defaults_{s}") for s in seeds]
ref = [fates(f"reference_{s}") for s in seeds]
for a, b in zip(mine, ref):
    assert set(a) == set(b), "a seed fed other particles at the reference's settings"
p, pr = products(mine), products(ref)
se = paired_errors(mine, ref)
seed_list = ", ".join(seeds)
particles = sum(len(f) for f in mine)
lines = [
    "# Accuracy of the defaults",
    "",
    "`scenes/ces_pcb.yaml` as shipped (no solver section: the defaults)",
    "against a reference of it whose solve is converged, at half the step",
    f"(`{reference}`), at seeds {seed_list}. Whether the products are",
    "converged in the step, this comparison does not show.",
    f"Generated by `tools/accuracy.sh` on {cores} cores ({cpu}); do not edit",
    "by hand.",
    "",
    "A seed feeds the same particles at any setting (each particle draws from",
    "its own random stream), so the two runs of a seed are compared particle",
    f"by particle. Products over the {len(seeds)} seeds' {particles} particles together, in",
    "percentage points; the difference is the defaults' minus the reference's,",
    "± its standard error: the bootstrap over particles, each drawn for both",
    "runs at once, so that a particle landing in the same product in both adds",
    "nothing to it and the error is what the settings' differences give.",
    "",
    "| product | material | grade | reference | difference | recovery | reference | difference |",
    "|---|---|---|---|---|---|---|---|",
]
for key in sorted(pr):
    g, r = p.get(key, (0.0, 0.0))
    gr, rr = pr[key]
    eg, er = se.get(key, (0.0, 0.0))
    lines.append(f"| {key[0]} | {key[1]} | {100 * g:.2f} | {100 * gr:.2f} "
                 f"| {100 * (g - gr):+.2f} ± {100 * eg:.2f} "
                 f"| {100 * r:.2f} | {100 * rr:.2f} | {100 * (r - rr):+.2f} ± {100 * er:.2f} |")
d = difference(mine, ref)
def largest(diffs, i):
    return max(abs(v[i]) for v in diffs.values())
switched = sum(1 for a, b in zip(mine, ref) for pid in a if a[pid][2] != b[pid][2])
per_seed = [difference([a], [b]) for a, b in zip(mine, ref)]
spread = [difference([mine[k]], [mine[0]]) for k in range(1, len(seeds))]
lines += ["", f"Largest difference: grade {100 * largest(d, 0):.2f} points, recovery "
          f"{100 * largest(d, 1):.2f} points. {switched} of the {particles} particles land "
          "in another product at the reference's settings. Each seed on its own: "
          + ", ".join(f"seed {s} {100 * largest(x, 0):.2f} and {100 * largest(x, 1):.2f}"
                      for s, x in zip(seeds, per_seed))
          + " (grade, recovery). One run's sampling of the feed, for scale: the defaults' "
          f"products at seeds {', '.join(seeds[1:])} differ from seed {seeds[0]}'s by up to "
          f"{100 * max(largest(x, 0) for x in spread):.2f} points of grade and "
          f"{100 * max(largest(x, 1) for x in spread):.2f} of recovery.", "",
          "Landing distributions at the bins (mass-weighted, each material normalised,",
          "the seeds together):", "",
          "| material | Wasserstein-1 distance to the reference (mm) |", "|---|---|"]
for material in ("copper", "fr4"):
    a = b = None
    for s in seeds:
        ma, width = landing(f"defaults_{s}", material)
        mb, _ = landing(f"reference_{s}", material)
        a = ma if a is None else [x + y for x, y in zip(a, ma)]
        b = mb if b is None else [x + y for x, y in zip(b, mb)]
    lines.append(f"| {material} | {1e3 * w1(a, b, width):.2f} |")
lines += ["", "| run | step | tolerances (residual, overlap) | iterations (mean, cap) "
          "| steps at the cap | worst overlap / radius | worst wall overlap / radius | warnings "
          "| wall time | load average (start, end) |",
          "|---|---|---|---|---|---|---|---|---|---|"]
for run, s in summary.items():
    so = s["solver"]
    lines.append(f"| {run.replace('_', ', seed ')} | {1e3 * s['step_s']:g} ms | {so['tolerance_mps']:g} m/s, "
                 f"{so['penetration_tolerance']:g} | {so['iterations_mean']:.1f}, "
                 f"{so['max_iterations']} | {so['steps_at_iteration_cap']} of {so['steps_solved']} "
                 f"| {so['max_penetration_relative']:.3f} | {so['max_wall_penetration_relative']:.3f} "
                 f"| {len(s.get('warnings', []))} "
                 f"| {s['wall_time_s']['total']:.0f} s | {load[run][0]}, {load[run][1]} |")
open(doc, "w").write("\n".join(lines) + "\n")
EOF
echo "wrote $doc"

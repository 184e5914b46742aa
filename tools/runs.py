"""What the accuracy tools read from ces-sim's run folders (docs/outputs.md):
each particle's fate, the products made of them, the landings at the bins.
Used by tools/accuracy.sh and tools/step_convergence.sh."""
import csv
import functools
import json
import os
import sys


@functools.cache
def summary(folder):
    """The run's summary.json. A run that failed or was cut short stops the
    tool here, naming it: its products would be a part of the feed's."""
    path = os.path.join(folder, "summary.json")
    if not os.path.exists(path):
        sys.exit(f"{folder}: no summary.json; the run has not finished, or failed before it "
                 "started (run it again without --quiet to see why)")
    s = json.load(open(path))
    if not s.get("complete"):
        sys.exit(f"{folder}: the run did not complete ({s.get('reason', 'no reason given')})")
    return s


def load_average(folder):
    """The machine's load average before and after the run, as the tool kept
    them beside its folder (FOLDER.load)."""
    return open(f"{folder}.load").read().split()


@functools.cache
def fates(folder):
    """Per particle id: (material, mass in kg, product), product None for a
    particle lost from the domain. Checked against the run's own
    products.csv. Read once per folder; callers do not change it."""
    summary(folder)
    out = {}
    for r in csv.DictReader(open(os.path.join(folder, "crossings.csv"))):
        if r["collector"] == "bins":
            out[r["id"]] = (r["material"], float(r["mass_kg"]), r["product"])
    for r in csv.DictReader(open(os.path.join(folder, "lost.csv"))):
        out[r["id"]] = (r["material"], float(r["mass_kg"]), None)
    mine = products([out])
    for r in csv.DictReader(open(os.path.join(folder, "products.csv"))):
        g, rec = mine.get((r["product"], r["material"]), (0.0, 0.0))
        if abs(g - float(r["grade"])) > 1e-6 or abs(rec - float(r["recovery"])) > 1e-6:
            sys.exit(f"{folder}: products.csv does not follow from crossings.csv and lost.csv "
                     f"at {r['product']}, {r['material']}")
    return out


def products(runs_fates, weights=None):
    """(grade, recovery) per (product, material), by mass, over several runs'
    particles together, each counted weights[k][id] times (once when
    weights is None)."""
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


def landings(folder, material):
    """The landing positions along the bins (m) of one material's
    particles, sorted."""
    return sorted(float(r["along_m"]) for r in csv.DictReader(open(os.path.join(folder, "crossings.csv")))
                  if r["collector"] == "bins" and r["material"] == material)


def bins(folder, material):
    """One material's mass per bin of the bins collector (kg), and the
    bins' width (m)."""
    rows = [r for r in csv.DictReader(open(os.path.join(folder, "bins.csv")))
            if r["collector"] == "bins" and r["material"] == material]
    return [float(r["mass_kg"]) for r in rows], float(rows[0]["to_m"]) - float(rows[0]["from_m"])


def machine():
    """'N cores (CPU model)', for a document's header."""
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), "unknown CPU")
    return f"{len(os.sched_getaffinity(0))} cores ({cpu})"

"""bench/industrial.sh's report: reads the runs' summaries, GNU time's
reports and the load samples from OUT, prints the text of industrial.txt.
Usage: python3 bench/industrial_report.py OUT START CORES END SHORT SCENE_END AT
(SCENE_END: the scene's own time.end, in seconds; AT: the full run's
checkpoint, from which resume_1 and resume_2 ran to END)"""
import functools
import json
import platform
import statistics
import sys
from pathlib import Path

out, start, cores, end, short = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
scene_end, at = float(sys.argv[6]), float(sys.argv[7])
STAGES = ["feed", "broadphase", "narrowphase", "forces", "assemble", "solve", "safeguards",
          "integrate", "collect", "output"]


def summary(name):
    return json.loads((out / name / "summary.json").read_text())


def time_reports(name):
    """The run's GNU time reports: NAME.time, then NAME.time.2, ... where
    it was resumed, in the order the processes ran."""
    later = sorted(out.glob(f"{name}.time.*"), key=lambda f: int(f.suffix[1:]))
    return [out / f"{name}.time", *later]


def process_peaks(name):
    """Each of the run's processes' maximum resident set, None for one
    stopped by a signal (its report is empty)."""
    peaks = []
    for report in time_reports(name):
        found = [1024 * int(line.split(":")[1]) for line in report.read_text().splitlines()
                 if "Maximum resident set size" in line]
        peaks.append(found[0] if found else None)
    if not any(peaks):
        raise SystemExit(f"no maximum resident set size in {name}.time")
    return peaks


def peak_rss_bytes(name):
    return max(p for p in process_peaks(name) if p)


def cpu_model():
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def memory_gib():
    kb = int(Path("/proc/meminfo").read_text().split()[1])
    return kb / 2**20


def commit():
    """The commit the bench began at ("-dirty": with uncommitted changes)."""
    recorded = out / "bench.commit"
    return recorded.read_text().strip() if recorded.exists() else "unknown"


def resumes():
    """How many times `--resume` took the bench up again; a bench begun
    before resumed.txt (or partly before) counts at least the full run's
    later processes."""
    log = out / "resumed.txt"
    logged = len(log.read_text().splitlines()) if log.exists() else 0
    return max(logged, len(list(out.glob("full.time.*"))))


def step_seconds(s):
    stages = s["wall_time_s"]["stages"]
    return sum(v for k, v in stages.items() if k != "output")


@functools.cache
def step_rows(name):
    """A run's steps.csv, each row a dict by column name, values as text
    (read once: the full run's, of 2000 steps or more, serves two parts)."""
    lines = (out / name / "steps.csv").read_text().splitlines()
    head = lines[0].split(",")
    return [dict(zip(head, line.split(","))) for line in lines[1:]]


def contact_iterations(rows):
    """The solve's work over these steps: each contact in each iteration."""
    return sum(float(r["contacts"]) * float(r["iterations"]) for r in rows)


def describe(name, title):
    s = summary(name)
    solver, stages = s["solver"], s["wall_time_s"]["stages"]
    step = step_seconds(s)
    print(f"## {title}\n")
    commands = (out / f"{name}.command").read_text().strip().splitlines()
    print("command: " + commands[0])
    for later in commands[1:]:
        print("then, stopped and resumed from its last checkpoint: " + later)
    print(f"simulated {s['simulated_time_s']:g} s in {s['steps']} steps; wall {s['wall_time_s']['total']:.1f} s "
          f"(the run loop), {s['wall_time_s']['total'] / max(s['simulated_time_s'], 1e-12):.0f} s per simulated second; "
          f"threads {s['threads']}")
    print(f"particles at most {solver['particles_max']} ({solver['asleep_max']} asleep at most), "
          f"contacts at most {solver['contacts_max']}; "
          f"fed {s['balance']['fed']['count']} ({s['balance']['fed']['mass_kg'] * 1e3:.1f} g), "
          f"collected {s['balance']['collected']['count']}, balance exact: {s['balance']['exact']}")
    print(f"solver: {solver['iterations_mean']:.1f} iterations per step on average (cap {solver['max_iterations']}), "
          f"{solver['steps_at_iteration_cap']} of {solver['steps_solved']} steps at the cap; residual median "
          f"{solver['residual_median_mps']:.2g} m/s, 95th percentile {solver['residual_p95_mps']:.2g}, "
          f"max {solver['residual_max_mps']:.2g}")
    work = contact_iterations(step_rows(name))
    print(f"solve: {work:.3g} contact-iterations (a contact in one iteration) in {stages['solve']:.1f} s, "
          f"{work / stages['solve'] / s['threads'] / 1e6:.1f} M per second per thread")
    print(f"overlap: worst {solver['max_penetration_m'] * 1e3:.3f} mm, {solver['max_penetration_relative']:.2f} of the "
          f"smaller radius; against walls {solver['max_wall_penetration_relative']:.2f}")
    peaks = process_peaks(name)
    listed = ", ".join(f"{p / 2**20:.0f}" if p else "none (stopped by a signal)" for p in peaks)
    each = f" (its processes' in turn, MiB: {listed})" if len(peaks) > 1 else ""
    print(f"peak resident set: {peak_rss_bytes(name) / 2**20:.0f} MiB{each}\n")
    print("| stage | wall s | share of the step | over solve |")
    print("|---|---|---|---|")
    for k in STAGES:
        print(f"| {k} | {stages[k]:.2f} | {stages[k] / step:.3f} | {stages[k] / stages['solve']:.3f} |")
    print(f"| step (all but output) | {step:.2f} | 1 | {step / stages['solve']:.3f} |\n")
    return s


def load_line():
    samples = [float(x) for x in (out / "load.txt").read_text().split()] if (out / "load.txt").exists() else []
    if not samples:
        return "load average: not sampled"
    return (f"1-minute load average over the bench, sampled every 10 s ({len(samples)} samples): median "
            f"{statistics.median(samples):.2f}, range {min(samples):.2f}-{max(samples):.2f}, on {cores} cores "
            f"(the bench's own runs count in it: up to {cores} of it)")


def slope(points):
    """Least squares y = c + s x over (x, y) points: (c, s)."""
    n = len(points)
    mx, my = sum(x for x, _ in points) / n, sum(y for _, y in points) / n
    s = sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points)
    return my - s * mx, s


def memory_fit(rows):
    """Bytes per particle and per contact from each step's resident set
    against the most particles and contacts held so far (which the arrays'
    capacities follow). The two grow together once the pile forms, so one
    fit of both cannot tell them apart: the cost per particle is fitted to
    the steps before it (contacts at most a quarter of the particles: the
    particles in flight), the cost per contact to what that leaves over all
    steps. Returns (base, per particle, per contact, largest departure,
    steps in flight), or None without resident_mib."""
    points, p, c = [], 0, 0
    for r in rows:
        p, c = max(p, int(r["particles"])), max(c, int(r["contacts"]))
        resident = float(r.get("resident_mib") or 0) * 2**20
        if resident > 0:
            points.append((p, c, resident))
    flight = [(p, m) for p, c, m in points if p > 0 and 4 * c <= p]
    if len(flight) < 3 or not any(c for _, c, _ in points):
        return None
    base, a = slope(flight)
    b = sum(c * (m - base - a * p) for p, c, m in points) / sum(c * c for _, c, _ in points)
    worst = max(abs(m - base - a * p - b * c) for p, c, m in points)
    return base, a, b, worst, len(flight)


def describe_memory(name, s):
    fit = memory_fit(step_rows(name))
    if fit is None:
        print(f"the {name} run's steps.csv does not separate them (no resident_mib, or no steps in flight)")
        return
    base, a, b, worst, flight = fit
    print(f"fitted to the {name} run's steps.csv, each step's resident set against the most particles "
          f"and contacts held so far: {a:.0f} B per particle (from its {flight} steps before the pile, "
          f"contacts at most a quarter of the particles), {b:.0f} B per contact (what that leaves, over "
          f"every step), {base / 2**20:.1f} MiB besides; largest departure from the fit "
          f"{worst / 2**20:.1f} MiB (the arrays grow by doubling)")
    p, c = s["solver"]["particles_max"], s["solver"]["contacts_max"]
    print(f"at its most ({p} particles, {c} contacts) the fit gives {(base + a * p + b * c) / 2**20:.0f} MiB; "
          f"its peak resident set was {peak_rss_bytes(name) / 2**20:.0f} MiB")


print(f"# ces-sim: the industrial scene ({start})\n")
print(f"Machine: {cpu_model()}, {cores} cores, {memory_gib():.0f} GiB; {platform.system()} "
      f"{platform.release()}; commit {commit()} (where the bench began).")
print(load_line() + ".")
resumed = resumes()
print(f"Command: bash bench/industrial.sh {end} {short}" +
      (", then bash bench/industrial.sh --resume" if resumed else "") +
      (f" ({resumed} times)" if resumed > 1 else "") + "\n")
full = describe("full", f"Scene to {end} s on {cores} threads")


def late_pace(name, s):
    """The run's pace over its last tenth, from steps.csv: the machine fills
    for as long as its particles stay in it (flight, and the FR-4 carried
    to the brush), so the whole run's average understates the pace once it
    is full."""
    rows = step_rows(name)
    last = float(rows[-1]["time_s"])
    late = [r for r in rows if float(r["time_s"]) > 0.9 * last]
    seconds = sum(float(r["wall_s"]) for r in late) / (len(late) * s["step_s"])
    print(f"over the last tenth, from {float(late[0]['time_s']):g} s: {seconds:.0f} s per simulated "
          f"second, {late[-1]['particles']} particles and {late[-1]['contacts']} contacts at the end; "
          f"at that pace the scene's {scene_end:g} s (its time.end) take "
          f"{scene_end * seconds / 3600:.1f} h")
    # What the solve alone needs at that point, at the run's own rate: a
    # floor on the pace that no other stage's speed-up lowers.
    work = contact_iterations(late) / (len(late) * s["step_s"])
    stages = s["wall_time_s"]["stages"]
    rate = contact_iterations(rows) / stages["solve"]
    print(f"over the last tenth the solve has {work:.3g} contact-iterations per simulated second: at the "
          f"run's average rate (over the whole run, its loaded periods included), {work / rate:.0f} s per simulated "
          f"second for the solve alone\n")


late_pace("full", full)


def resumed_steps(name):
    """The steps a resumed run made after the checkpoint: their wall
    seconds summed, their count, and the last row."""
    after = [r for r in step_rows(name) if float(r["time_s"]) > at + 1e-9]
    return sum(float(r["wall_s"]) for r in after), len(after), after[-1]


print("## The full machine, 1 -> 2 threads\n")
one_s, steps, one_last = resumed_steps("resume_1")
two_s, _, two_last = resumed_steps("resume_2")
same = all(one_last[k] == two_last[k] for k in one_last if k not in ("wall_s", "resident_mib"))
print("commands: " + (out / "resume_1.command").read_text().strip() + "; " +
      (out / "resume_2.command").read_text().strip())
print(f"the full run's checkpoint at {at:g} s resumed to {end} s ({steps} steps; {one_last['particles']} "
      f"particles and {one_last['contacts']} contacts at the end), the steps' wall_s summed: "
      f"{one_s:.1f} s on 1 thread, {two_s:.1f} s on 2, speed-up {one_s / two_s:.2f}; "
      f"the two end on the same step: {same}\n")


def own_stages(name, start):
    """A resumed run's stage seconds after its checkpoint: its summary's
    less that of the checkpoint it started from."""
    stages = summary(name)["wall_time_s"]["stages"]
    return {k: stages[k] - start[k] for k in STAGES}


# Each resume's own steps, the machine full and otherwise quiet: the
# step over the solve and the solve's rate there, which the full run's
# totals blur with its earlier, emptier and perhaps loaded stretches.
checkpoint = out / "checkpoint.summary.json"
if checkpoint.exists():
    start_stages = json.loads(checkpoint.read_text())["wall_time_s"]["stages"]
    work = contact_iterations([r for r in step_rows("resume_1") if float(r["time_s"]) > at + 1e-9])
    own = {t: own_stages(f"resume_{t}", start_stages) for t in (1, 2)}
    print("| stage | 1 thread, s | over solve | 2 threads, s | over solve |")
    print("|---|---|---|---|---|")
    for k in [*STAGES, "step (all but output)"]:
        cells = []
        for t in (1, 2):
            v = own[t][k] if k in own[t] else sum(x for s, x in own[t].items() if s != "output")
            cells += [f"{v:.2f}", f"{v / own[t]['solve']:.3f}"]
        print(f"| {k} | " + " | ".join(cells) + " |")
    print(f"\nsolve: {work:.3g} contact-iterations; {work / own[1]['solve'] / 1e6:.1f} M per second on "
          f"1 thread, {work / own[2]['solve'] / 2 / 1e6:.1f} M per second per thread on 2\n")


def median_run(prefix):
    """Of PREFIX_1..3, the run whose step time is the median."""
    names = sorted((f"{prefix}_{k}" for k in (1, 2, 3)), key=lambda n: step_seconds(summary(n)))
    return names[1]


one_name, two_name = median_run("one"), median_run("two")
one = describe(one_name, f"First {short} s on 1 thread (the median of three runs)")
two = describe(two_name, f"First {short} s on 2 threads (the median of three runs)")
print("## Speed-up, 1 -> 2 threads\n")
print(f"over the first {short} s, the medians of three runs each: whole step "
      f"{step_seconds(one) / step_seconds(two):.2f}, solve "
      f"{one['wall_time_s']['stages']['solve'] / two['wall_time_s']['stages']['solve']:.2f}, run loop "
      f"{one['wall_time_s']['total'] / two['wall_time_s']['total']:.2f}")
for k in (1, 2, 3):
    a, b = summary(f"one_{k}"), summary(f"two_{k}")
    print(f"- run {k}: step {step_seconds(a):.2f} s on 1 thread, {step_seconds(b):.2f} s on 2 "
          f"({step_seconds(a) / step_seconds(b):.2f}); solve {a['wall_time_s']['stages']['solve']:.2f} "
          f"and {b['wall_time_s']['stages']['solve']:.2f} s")
print()
print("## Memory\n")
empty = peak_rss_bytes("empty")
print(f"peak resident set of the scene's process with no particles (one step): {empty / 2**20:.0f} MiB")
describe_memory("full", full)

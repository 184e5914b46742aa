"""The stress scenes' full runs against their pass criteria (docs/accuracy.md,
section 4; tests/stress_test.cpp checks the short versions the same way).

  stress_report.py --line DIR NAME       one line for the run in DIR/NAME
  stress_report.py --doc DIR DOC NAME... the table of the runs, into DOC

Written by bench/stress.sh."""
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tools"))
import runs  # noqa: E402

PENETRATION_BOUND = 0.05  # of the radius
OVERLAP_WARNING = 0.1  # of the radius: the summary warns above it
ENERGY_GAIN_BOUND = 0.01  # of the peak kinetic energy
# The scenes whose grains may overlap past the bound, with the summary's
# warning (the scene files say why).
REPORTED = {"impact_plate", "impact_mesh", "step_10ms"}
# The heavy body of the mass-ratio scenes (their scene files), resting on
# grains it overlaps: the push-out of overlaps at the recovery speed, and
# lifting it back by the depth it sank, may add up to M (v_r^2 / 2 + g d)
# to the energy (as tests/stress_test.cpp allows).
PUSHED_OUT_KG = {"mass_ratio_sphere": 4.18879e-3, "mass_ratio_plate": 4.18879e-3}
RECOVERY_SPEED = 0.1  # m/s, the scenes' default
GRAVITY = 9.81  # m/s^2, every stress scene's


def summary(folder):
    """The run's summary; a run that failed or was stopped left it in
    partial/, marked incomplete."""
    path = os.path.join(folder, "summary.json")
    if not os.path.exists(path):
        path = os.path.join(folder, "partial", "summary.json")
    return json.load(open(path))


def percent(x, digits=".3g"):
    return "n/a" if isinstance(x, str) else f"{100 * x:{digits}}"


def failures(name, s):
    """What the run misses of the pass criteria, as short phrases."""
    out = []
    solver, lost = s["solver"], s["balance"]["lost_by_reason"]
    if not s["complete"]:
        out.append(f"incomplete ({s['reason']})")
    if lost["non-finite state"]["count"]:
        out.append("NaN or Inf")
    if not s["balance"]["exact"]:
        out.append("mass balance")
    if lost["left domain"]["count"]:
        out.append("left the domain")
    if solver["max_wall_penetration_relative"] > 1.0:
        out.append("a centre past a wall")
    overlap = solver["max_penetration_relative"]
    if overlap > PENETRATION_BOUND and name not in REPORTED:
        out.append("overlap")
    warned = any("overlapped by up to" in w for w in s["warnings"])
    if overlap > OVERLAP_WARNING and not warned:
        out.append("overlap not reported")
    energy = s["energy"]
    if energy["balance"] == "passive" and energy["max_gain_relative"] > energy_bound(name, s):
        out.append("energy gain")
    return out


def energy_bound(name, s):
    """The largest energy gain the criteria allow, relative to the peak
    kinetic energy: 1 %, plus what pushing the heavy body out can add."""
    solver = s["solver"]
    if not solver["max_penetration_relative"]:
        return ENERGY_GAIN_BOUND
    radius = solver["max_penetration_m"] / solver["max_penetration_relative"]
    depth = solver["max_penetration_m"] + radius * solver["max_wall_penetration_relative"]
    push_out = PUSHED_OUT_KG.get(name, 0.0) * (0.5 * RECOVERY_SPEED**2 + GRAVITY * depth)
    return ENERGY_GAIN_BOUND + push_out / s["energy"]["peak_kinetic_J"]


def verdict(name, s):
    missed = failures(name, s)
    if missed:
        return "**fails**: " + ", ".join(missed)
    if s["solver"]["max_penetration_relative"] > PENETRATION_BOUND:
        return "passes (overlap reported)"
    return "passes"


def line(folder, name):
    s = summary(folder)
    solver, b = s["solver"], s["balance"]
    return (f"{name:18s} complete={s['complete']} wall={s['wall_time_s']['total']:.0f}s "
            f"particles={b['fed']['count']} "
            f"left_domain={b['lost_by_reason']['left domain']['count']} "
            f"non_finite={b['lost_by_reason']['non-finite state']['count']} "
            f"balance_exact={b['exact']} "
            f"penetration={percent(solver['max_penetration_relative'], '.2f')}% "
            f"wall_penetration={percent(solver['max_wall_penetration_relative'], '.2f')}% "
            f"energy_gain={percent(s['energy']['max_gain_relative'])}% "
            f"residual_p95={solver['residual_p95_mps']:.2g}m/s "
            f"at_cap={solver['steps_at_iteration_cap']}/{solver['steps_solved']} {s['reason']}")


def row(folder, name):
    s = summary(folder)
    solver, b = s["solver"], s["balance"]
    lost = b["lost_by_reason"]
    return (f"| `{name}` | {1e3 * s['step_s']:g} ms, {solver['max_iterations']} "
            f"| {b['fed']['count']} "
            f"| {lost['left domain']['count']} / {lost['non-finite state']['count']} "
            f"| {'yes' if b['exact'] else 'no'} "
            f"| {percent(solver['max_penetration_relative'], '.2f')} "
            f"| {percent(solver['max_wall_penetration_relative'], '.2f')} "
            f"| {percent(s['energy']['max_gain_relative'])} "
            f"| {solver['residual_p95_mps']:.2g} "
            f"| {solver['steps_at_iteration_cap']}/{solver['steps_solved']} "
            f"| {s['wall_time_s']['total']:.0f} s | {verdict(name, s)} |")


def document(out, names):
    return "\n".join([
        "# Stress scenes, full versions",
        "",
        "The scene files of `scenes/stress/` as they stand, each run on one",
        "thread, against the pass criteria of [accuracy.md](accuracy.md),",
        "section 4 (which also says what each scene tests). Generated by",
        f"`bash bench/stress.sh {out} {' '.join(names)}` on {runs.machine()}, shared",
        "with other jobs (its wall times are not a benchmark); do not edit by hand.",
        "",
        "| scene | step, iterations | particles | lost: left domain / non-finite "
        "| balance exact | worst overlap, % of r | in a wall, % of r "
        "| energy gain, % of peak KE | residual p95 m/s | steps at the cap | wall time "
        "| verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
        *(row(os.path.join(out, n), n) for n in names),
        "",
    ])


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--line":
        print(line(os.path.join(sys.argv[2], sys.argv[3]), sys.argv[3]))
    elif len(sys.argv) >= 5 and sys.argv[1] == "--doc":
        with open(sys.argv[3], "w") as f:
            f.write(document(sys.argv[2], sys.argv[4:]))
    else:
        sys.exit(__doc__)

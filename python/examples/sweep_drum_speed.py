"""Copper grade and recovery in the conductor product against drum speed.

The reference separator, fed for 0.1 s and run for 0.7 s at each speed, so
that the sweep stays short (scenes/ces_pcb.yaml itself feeds for
1 s and runs until every particle is collected). Recovery here is of the
copper collected by then. The brush turns with the drum, as in the
machine (scenes/machines/ces_machine.yaml).
"""
from pathlib import Path

import ces_sim

scene_file = Path(__file__).resolve().parents[2] / "scenes" / "ces_pcb.yaml"
for rpm in (30, 45, 60, 75):
    short = {"time.end": "0.7 s", "time.until": "end", "feeds.nozzle.duration": "0.1 s"}
    speed = {f"bodies.{b}.motion.rotation.speed": f"{rpm} rpm" for b in ("drum", "brush")}
    result = ces_sim.load(scene_file, set={**short, **speed}).run(f"out/sweep/{rpm}rpm")
    p = result.products
    k = list(zip(p["product"], p["material"])).index(("conductor", "copper"))
    print(f"{rpm:3d} rpm: copper grade {100 * p['grade'][k]:5.1f} %, "
          f"recovery {100 * p['recovery'][k]:5.1f} %")

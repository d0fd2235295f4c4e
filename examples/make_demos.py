"""Regenerate the example demonstrations (seeded): python examples/make_demos.py

Each is a synthetic one-shot demonstration with 5 mm tracking noise, tremor, a few tracker
glitches and a varying speed, placed where the matching paper task has its handle.
`cap lfo examples/<demo> --execute` builds the simulated object where the demonstration says
(lfo/scene.py) and runs the estimated skill on it; examples/move_demos.py moves, mirrors and
scales these demonstrations (examples/moved/).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from constraint_aware.lfo.synthetic import TrackingNoise, make_demo
from constraint_aware.sim.tasks import task_config

HERE = Path(__file__).parent


def main() -> None:
    rng = np.random.default_rng(2024)
    noise = TrackingNoise(noise=0.005)
    drawer = task_config("drawer-opening").object
    demo, _ = make_demo(
        "drawer", rng, noise, length=0.3,
        frame=(drawer.handle_position, np.asarray(drawer.axis)),
    )  # fmt: skip
    demo.save(HERE / "drawer_demo.json")
    door = task_config("door-opening").object
    demo, _ = make_demo(
        "door", rng, noise, radius=door.radius, arc_deg=70.0,
        frame=(door.handle_position, np.array([1.0, 0.0, 0.0])),
    )  # fmt: skip
    demo.save(HERE / "door_demo.json")
    handle = task_config("handle-rotating").object
    demo, _ = make_demo(
        "handle", rng, noise, radius=handle.radius, arc_deg=100.0,
        frame=(handle.handle_position, np.array([1.0, 0.0, 0.0])),
    )  # fmt: skip
    demo.save(HERE / "handle_demo.json")
    # the drawer once more as a bare CSV trajectory (no words: geometry alone decides)
    demo, _ = make_demo(
        "drawer", rng, noise, length=0.3,
        frame=(drawer.handle_position, np.asarray(drawer.axis)),
    )  # fmt: skip
    with (HERE / "drawer_path.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "x", "y", "z"])
        for t, p in zip(demo.t, demo.position, strict=True):
            w.writerow([f"{t:.4f}", *(f"{c:.5f}" for c in p)])


if __name__ == "__main__":
    main()

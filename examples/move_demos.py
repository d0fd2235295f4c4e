"""The shipped example demonstrations moved, mirrored, scaled, mislabelled or in the wrong
unit: python examples/move_demos.py (writes examples/moved/*.json)

Each is the shipped demonstration transformed (no new motion is invented) except the closing
drawer, a demonstration of the preset drawer played backwards with the hand's orientation.
`cap lfo examples/moved/<demo> --execute` builds the object where the demonstration says.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from constraint_aware.lfo.demo import load, transformed
from constraint_aware.lfo.synthetic import TrackingNoise, demo_of_object
from constraint_aware.sim.tasks import task_config

HERE = Path(__file__).parent
OUT = HERE / "moved"


def yaw(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def main() -> None:
    OUT.mkdir(exist_ok=True)
    drawer = load(HERE / "drawer_demo.json")
    door = load(HERE / "door_demo.json")
    hinge = np.asarray(task_config("door-opening").object.position)
    # rotated about the vertical through the robot base (the frame's origin)
    transformed(drawer, yaw(90.0)).save(OUT / "drawer_rot90.json")
    transformed(drawer, yaw(200.0)).save(OUT / "drawer_rot200.json")
    # mirrored across the vertical plane y = 0: a left-hinged door
    transformed(door, np.diag([1.0, -1.0, 1.0])).save(OUT / "door_mirrored.json")
    # scaled about the hinge to a 0.35 m door (the shipped one is 0.5 m)
    transformed(door, np.diag([0.7, 0.7, 1.0]), about=hinge).save(OUT / "door_small.json")
    transformed(door, yaw(-60.0)).save(OUT / "door_turned.json")
    # the door in millimetres: a unit error, not a 600 m drawer
    transformed(door, 1000.0 * np.eye(3)).save(OUT / "door_mm.json")
    # a drawer's path with a door's words: geometry decides (prismatic), with a note
    transformed(drawer, np.eye(3), instruction="open the door", object_name="door").save(
        OUT / "drawer_as_door.json"
    )
    # closing the drawer, labelled "open": a warning
    task = task_config("drawer-opening")
    closing = demo_of_object(
        task, 0.3, np.random.default_rng(2025), TrackingNoise(noise=0.005),
        words=("open the drawer", "drawer"), closing=True,
    )  # fmt: skip
    closing.save(OUT / "drawer_closing.json")


if __name__ == "__main__":
    main()

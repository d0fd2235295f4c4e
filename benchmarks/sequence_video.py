"""A video of the execution sequence from home to home: the Jaco on the door. Writes an .mp4.

    nice -n 10 python benchmarks/sequence_video.py [--robot jaco] [--angle 60]
        [--out docs/media/jaco-door-sequence.mp4]

The door task's door (0.5 m from its hinge), demonstrated opened by `--angle` degrees with
5 mm tracking noise; the robot starts at home, sees the door with its head camera, reaches,
grasps the bar, opens the door with the constraint-aware policy, releases, retreats and
returns home. One frame per control period (10 fps: real time), 480 x 360.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.lfo.execute import execute_from_home
from constraint_aware.lfo.infer import infer_skill
from constraint_aware.lfo.synthetic import TrackingNoise, demo_of_object
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.render import SceneRenderer, save_video
from constraint_aware.sim.tasks import task_config

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="jaco")
    parser.add_argument("--angle", type=float, default=60.0, help="demonstrated [deg]")
    parser.add_argument("--out", default=str(ROOT / "docs" / "media" / "jaco-door-sequence.mp4"))
    args = parser.parse_args()
    task = task_config("door-opening")
    demo = demo_of_object(
        task, math.radians(args.angle), np.random.default_rng(0), TrackingNoise(noise=0.005)
    )
    frames: list[Any] = []
    renderer: list[SceneRenderer] = []

    def on_period(sim: Any) -> None:
        if not renderer:
            lookat = np.asarray(task.object.handle_position) + np.array([0.15, 0.0, -0.2])
            renderer.append(
                SceneRenderer(sim.model, width=480, height=360, lookat=lookat, distance=1.9,
                              azimuth=200.0, elevation=-25.0)
            )  # fmt: skip
        frames.append(renderer[0].frame(sim.data))

    result, info = execute_from_home(
        infer_skill(demo), task=task, robot=args.robot, policy=ConstraintAwarePolicy.load(),
        on_period=on_period,
    )  # fmt: skip
    record = result.record
    out = save_video(frames, args.out, fps=10)
    phases = ", ".join(f"{p.name} {p.outcome}" for p in record.phases)
    print(f"{out}: {len(frames)} frames, {out.stat().st_size / 1024:.0f} KB; {phases}")
    print(f"door at {math.degrees(info['progress']):.0f} deg after the sequence")


if __name__ == "__main__":
    main()

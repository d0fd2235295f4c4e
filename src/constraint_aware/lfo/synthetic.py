"""Synthetic demonstrations with ground truth: drawers, doors and handles as a hand tracker
would report them (Gaussian noise, tremor, outliers, varying speed, partial arcs)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from constraint_aware.geometry import FloatArray, random_perpendicular, random_unit, unit
from constraint_aware.lfo.demo import Demonstration
from constraint_aware.lfo.scene import STEP_LENGTH
from constraint_aware.sim.tasks import TaskConfig

Kind = Literal["drawer", "door", "handle"]
KINDS: tuple[Kind, ...] = ("drawer", "door", "handle")
INSTRUCTIONS = {
    "drawer": ("open the drawer", "drawer"),
    "door": ("open the door", "door"),
    "handle": ("turn the handle", "handle"),
}


@dataclass(frozen=True)
class TrackingNoise:
    """How a hand tracker corrupts the path. Units: m, Hz."""

    noise: float = 0.005  # [m] Gaussian std per axis
    tremor: float = 0.002  # [m] amplitude of an 8-12 Hz tremor
    outlier_fraction: float = 0.02  # share of samples replaced by glitches
    outlier_size: float = 0.08  # [m] typical glitch distance
    speed_variation: float = 0.5  # relative speed modulation (0: constant speed)
    rest_time: float = 0.3  # [s] the hand rests before and after the motion


@dataclass(frozen=True)
class GroundTruth:
    kind: Kind
    constraint_type: str
    workplane_normal: FloatArray  # (3,), motion turns positively about it (revolute)
    initial_direction: FloatArray  # (3,)
    radius: float | None  # [m]
    centre: FloatArray | None  # (3,) [m]
    arc_deg: float | None


def _progress(rng: np.random.Generator, n: int, duration: float, variation: float) -> FloatArray:
    """Progress s in [0, 1] at n equally spaced samples (monotone, speed-modulated)."""
    t = np.linspace(0.0, duration, n)
    phase = rng.uniform(0, 2 * math.pi)
    speed = 1.0 + variation * np.sin(2 * math.pi * t / duration * rng.uniform(0.5, 1.5) + phase)
    speed = np.clip(speed, 0.1, None)
    s = np.concatenate([[0.0], np.cumsum(speed[1:] * np.diff(t))])
    return np.asarray(s / s[-1])


def make_demo(
    kind: Kind,
    rng: np.random.Generator,
    tracking: TrackingNoise | None = None,
    rate: float = 30.0,
    arc_deg: float | None = None,
    radius: float | None = None,
    length: float | None = None,
    frame: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[Demonstration, GroundTruth]:
    """One demonstration and its truth.

    frame: (start point (3,), initial direction (3,)) to place the motion; by default random.
    For revolute kinds the workplane is horizontal (doors, table-top cranks) unless `frame`
    implies otherwise; for drawers the motion is a straight pull.
    """
    tr = tracking or TrackingNoise()
    if kind == "drawer":
        length = length or rng.uniform(0.2, 0.35)
        start = frame[0] if frame else rng.uniform(-0.3, 0.3, 3) + np.array([0.5, 0.0, 0.8])
        u = unit(frame[1]) if frame else unit(np.array([1.0, rng.uniform(-0.3, 0.3), 0.0]))
        duration = length / 0.1
        n = int(duration * rate) + 1
        s = _progress(rng, n, duration, tr.speed_variation)
        path = start + np.outer(s * length, u)
        normal = unit(np.cross(u, [0.0, 0.0, 1.0]))
        truth = GroundTruth(kind, "prismatic", normal, u, None, None, None)
    else:
        if kind == "door":
            radius = radius or rng.uniform(0.4, 0.9)
            arc_deg = arc_deg or rng.uniform(45.0, 90.0)
        else:
            radius = radius or rng.uniform(0.08, 0.2)
            arc_deg = arc_deg or rng.uniform(60.0, 180.0)
        axis = np.array([0.0, 0.0, 1.0])
        if frame:
            start, tangent = frame[0], unit(frame[1])
        else:
            start = rng.uniform(-0.3, 0.3, 3) + np.array([0.5, 0.0, 0.9])
            tangent = unit(np.array([*random_unit(rng, 1)[0, :2], 0.0]))
        radial = np.cross(axis, tangent)  # from the hand toward the centre (positive turn)
        centre = start + radius * radial
        r0 = start - centre
        sweep = math.radians(arc_deg)
        duration = radius * sweep / 0.1
        n = int(duration * rate) + 1
        s = _progress(rng, n, duration, tr.speed_variation)
        ang = s * sweep
        path = centre + np.cos(ang)[:, None] * r0 + np.sin(ang)[:, None] * np.cross(axis, r0)
        truth = GroundTruth(kind, "revolute", axis, tangent, radius, centre, arc_deg)
    instruction, obj = INSTRUCTIONS[kind]
    stamps, noisy = _track(path, rng, tr, rate)
    return Demonstration(instruction, obj, stamps, noisy), truth


def _track(
    path: FloatArray, rng: np.random.Generator, tr: TrackingNoise, rate: float
) -> tuple[FloatArray, FloatArray]:
    """(timestamps (M,) [s], positions (M, 3) [m]): the path with rests before and after, as a
    tracker reports it (jittered stamps, tremor, Gaussian noise, glitches)."""
    n_rest = int(tr.rest_time * rate)
    path = np.concatenate([np.repeat(path[:1], n_rest, 0), path, np.repeat(path[-1:], n_rest, 0)])
    path = np.asarray(path, dtype=np.float64)
    dt = 1.0 / rate
    stamps = (np.arange(len(path)) + rng.uniform(-0.2, 0.2, len(path))) * dt  # jittered
    freq = rng.uniform(8.0, 12.0)
    tremor_dir = random_perpendicular(rng, np.array([[0.0, 0.0, 1.0]]))[0]
    path = path + tr.tremor * np.sin(2 * math.pi * freq * stamps)[:, None] * tremor_dir
    path = path + rng.normal(0.0, tr.noise, path.shape)
    n_out = round(tr.outlier_fraction * len(path))
    if n_out:
        idx = rng.choice(np.arange(n_rest, len(path) - n_rest), size=n_out, replace=False)
        jumps = random_unit(rng, n_out) * tr.outlier_size * rng.uniform(0.5, 1.5, (n_out, 1))
        path[idx] = path[idx] + jumps
    return np.asarray(stamps), np.asarray(path)


# --- demonstrations of any placed object -----------------------------------------------------
#: The words a demonstrator says for each object kind (sim.tasks.KINDS).
KIND_INSTRUCTIONS = {
    "drawer": ("open the drawer", "drawer"),
    "plate": ("slide the plate", "plate"),
    "pole": ("pull the pole", "pole"),
    "window": ("open the window", "window"),
    "door": ("open the door", "door"),
    "lid": ("open the lid", "lid"),
    "crank": ("turn the crank", "crank"),
}
HAND_SPEED = 0.1  # [m/s] mean speed of the demonstrating hand along the path


@dataclass(frozen=True)
class Placement:
    """A randomly placed object (the truth) and the travel [m] or angle [rad] demonstrated."""

    kind: str
    task: TaskConfig
    goal: float


def random_placement(kind: str, rng: np.random.Generator) -> Placement:
    """An object of `kind` at a random pose in front of the robot (base at the origin).

    Any yaw; doors and cranks turning either way (a left- or right-hinged door); radii:
    doors 0.35-1.0 m, lids 0.2-0.6 m, cranks 0.06-0.2 m; demonstrated travel 0.15-0.35 m
    (slides), 45-90 deg (doors), 45-80 deg (lids), 60-150 deg (cranks).
    """
    from constraint_aware.sim.tasks import object_for, task_from_object

    yaw = rng.uniform(0.0, 2 * math.pi)
    horizontal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    spot = np.array([rng.uniform(0.35, 0.75), rng.uniform(-0.35, 0.35), rng.uniform(0.6, 1.1)])
    up = np.array([0.0, 0.0, 1.0])
    if kind in ("drawer", "plate", "pole"):
        obj = object_for(kind, position=_t(spot), axis=_t(horizontal))
        goal = rng.uniform(0.15, 0.35)
    elif kind == "window":
        obj = object_for(kind, position=_t(spot), axis=_t(up), handle_axis=_t(horizontal))
        goal = rng.uniform(0.15, 0.35)
    elif kind in ("door", "crank"):
        sense = 1.0 if rng.uniform() < 0.5 else -1.0  # right- or left-hinged / turning
        radius = rng.uniform(0.35, 1.0) if kind == "door" else rng.uniform(0.06, 0.2)
        hinge = spot - radius * horizontal
        obj = object_for(
            kind, position=_t(hinge), axis=(0.0, 0.0, sense), radial=_t(horizontal),
            radius=radius,
        )  # fmt: skip
        goal = math.radians(rng.uniform(45.0, 90.0) if kind == "door" else rng.uniform(60, 150))
    elif kind == "lid":
        radius = rng.uniform(0.2, 0.6)
        hinge = spot - radius * horizontal
        obj = object_for(
            kind, position=_t(hinge), axis=_t(np.cross(horizontal, up)), radial=_t(horizontal),
            radius=radius,
        )  # fmt: skip
        goal = math.radians(rng.uniform(45.0, 80.0))
    else:
        from constraint_aware.errors import UnknownNameError
        from constraint_aware.sim.tasks import KINDS

        raise UnknownNameError("object kind", kind, list(KINDS))
    task = task_from_object(kind, obj, success_progress=goal, step_length=STEP_LENGTH)
    return Placement(kind, task, goal)


def demo_of_object(
    task: TaskConfig,
    goal: float,
    rng: np.random.Generator,
    tracking: TrackingNoise | None = None,
    rate: float = 30.0,
    words: tuple[str, str] | None = None,
    closing: bool = False,
    orientation: bool = True,
    point_offset: FloatArray | None = None,
) -> Demonstration:
    """A demonstration of operating `task`'s object from joint position 0 to `goal`: the
    tracked point's path as a tracker reports it, with the hand's orientation (its mount on
    the handle, turning with a hinge) unless `orientation` is False. `closing` plays it
    backwards (from `goal` back to 0). Words: the kind's (KIND_INSTRUCTIONS) unless given.

    Args:
        point_offset: (3,) [m] where the tracked point sits relative to the handle's grasp
            centre at joint position 0, world frame; it moves rigidly with the hand (turns
            with a hinge). None: the tracker follows the grasp centre itself.
    """
    from scipy.spatial.transform import Rotation

    tr = tracking or TrackingNoise()
    o = task.object
    handle = o.handle_position
    if point_offset is not None:
        handle = handle + np.asarray(point_offset, dtype=float)
    path_length = goal * (o.radius if o.joint_type == "revolute" else 1.0)
    duration = path_length / HAND_SPEED
    n = int(duration * rate) + 1
    s = _progress(rng, n, duration, tr.speed_variation)
    q = s * goal
    axis = np.asarray(o.axis, dtype=float)
    mount = Rotation.from_matrix(task.hand_mount())
    if o.joint_type == "prismatic":
        path = handle + np.outer(q, axis)
        rots = Rotation.concatenate([mount] * n)
    else:
        turn = Rotation.from_rotvec(np.outer(q, axis))
        path = np.asarray(o.position) + turn.apply(handle - np.asarray(o.position))
        rots = turn * mount
    if closing:
        path, rots = path[::-1], rots[::-1]
    stamps, noisy = _track(path, rng, tr, rate)
    instruction, name = words or KIND_INSTRUCTIONS.get(task.name, ("", ""))
    quats = None
    if orientation:
        n_rest = int(tr.rest_time * rate)
        idx = np.clip(np.arange(len(noisy)) - n_rest, 0, n - 1)
        x, y, z, w = rots[idx].as_quat().T
        quats = np.stack([w, x, y, z], axis=1)
    return Demonstration(instruction, name, stamps, noisy, quats)


@dataclass(frozen=True)
class HandOffset:
    """How far a human's tracked hand point lies from the robot's contact point: a constant
    offset of uniformly drawn length up to `max_offset` [m] in a uniformly drawn direction,
    plus Gaussian `jitter` [m] std per axis (the tracker's idea of where the hand is: wrist,
    knuckles or the palm's centre)."""

    max_offset: float = 0.05  # [m]
    jitter: float = 0.01  # [m] per axis

    def draw(self, rng: np.random.Generator) -> FloatArray:
        """(3,) [m] one demonstration's offset, world frame."""
        direction = random_unit(rng, 1)[0]
        offset = direction * rng.uniform(0.0, self.max_offset)
        return np.asarray(offset + rng.normal(0.0, self.jitter, 3))


def _t(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))

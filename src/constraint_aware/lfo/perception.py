"""Seeing the demonstrated object: where the head camera looks, the demonstration's nominal
grasp, the recognized contact point, and the skill corrected by it.

Only the demonstration (its skill parameters) and the camera are read here. The demonstration
locates the object roughly: a human's tracked hand point (wrist, knuckles) is not the robot's
contact point (lfo/synthetic.py's `HandOffset`: up to 5 cm, plus 1 cm). It gives the nominal
grasp (`nominal_frame`: origin at the tracked point, orientation the hand mount of the object
built from the skill, lfo/scene.py), which places the crop (recognizer.py). The recognizer's
contact point then replaces the demonstrated start (`corrected_skill`); for a hinge, whose
axis the demonstration's circle fit locates (a rigid offset moves the tracked point on a
circle about the same axis), the radius and the initial direction follow from it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import FloatArray, unit
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.lfo.scene import scene_from_skill
from constraint_aware.recognizer import (
    CROP_SIZE,
    DEPTH_RANGE,
    GraspFrame,
    Recognition,
    Recognizer,
    depth_crop,
    handle_shape,
)
from constraint_aware.sim.camera import (
    CameraIntrinsics,
    CameraMount,
    CameraPose,
    DepthImage,
    look_at,
)
from constraint_aware.spatial import Pose

HORIZONTAL = 0.3  # a direction's horizontal part longer than this fixes "in front"


@dataclass(frozen=True)
class HeadCamera:
    """A robot's head camera, placed from the demonstrated point: `distance` [m] in front of it
    (horizontally, on the side the hand comes from), `height` [m] above it, `lateral` [m] to
    the left of that line, looking at the point."""

    distance: float
    height: float
    lateral: float
    intrinsics: CameraIntrinsics


#: Each robot's head camera (a RealSense-like 640 x 480 depth stream; the Jaco's stands
#: higher and to the side, with a narrower field of view).
HEAD_CAMERAS: dict[str, HeadCamera] = {
    "hook-hand": HeadCamera(0.75, 0.55, 0.0, CameraIntrinsics(640, 480, 58.0)),
    "jaco": HeadCamera(0.65, 0.75, 0.2, CameraIntrinsics(640, 480, 50.0)),
}
HEAD_CAMERA_NAME = "head_camera"


def nominal_frame(skill: SkillParameters) -> tuple[str, GraspFrame]:
    """The handle shape the demonstrated force-exertion type grasps and the nominal grasp
    frame: origin at the demonstrated start (3,) [m], axes the hand mount of the object
    built from the skill (z: the approach; for a pole, x points up)."""
    if skill.start_position is None:
        raise UnknownNameError("skill field", "start_position", ["a skill with a start"])
    shape = handle_shape(skill.grasp, skill.constraint_type)
    mount = np.asarray(scene_from_skill(skill).task.hand_mount(), dtype=float)
    return shape, GraspFrame(np.asarray(skill.start_position, dtype=float), mount)


def front_direction(skill: SkillParameters, approach: FloatArray) -> FloatArray:
    """(3,) horizontal unit: the side of the object the robot looks from. The side the hand
    approaches from; for a vertical approach, the side the handle moves toward (plates,
    cranks), the hinge-to-handle side (a lid), else across the workplane normal toward the
    robot's base (the world origin)."""
    z = np.array([0.0, 0.0, 1.0])
    candidates = [-np.asarray(approach, dtype=float), np.asarray(skill.initial_direction)]
    if skill.centre is not None and skill.start_position is not None:
        candidates.append(np.asarray(skill.start_position) - np.asarray(skill.centre))
    for v in candidates:
        h = v - float(v @ z) * z
        if float(np.linalg.norm(h)) > HORIZONTAL:
            return np.asarray(unit(h))
    across = unit(np.cross(z, np.asarray(skill.workplane_normal, dtype=float)))
    start = np.asarray(skill.start_position if skill.start_position is not None else np.zeros(3))
    to_base = -start
    if float(across @ to_base) < 0.0:
        across = -across
    return np.asarray(across)


def head_camera(robot: str, skill: SkillParameters) -> CameraMount:
    """The robot's head camera (`HEAD_CAMERAS`, by embodiment name) aimed at the demonstrated
    point."""
    name = robot.partition(":")[0]
    if name not in HEAD_CAMERAS:
        raise UnknownNameError("robot with a head camera", name, list(HEAD_CAMERAS))
    spec = HEAD_CAMERAS[name]
    _, frame = nominal_frame(skill)
    target = frame.origin
    front = front_direction(skill, frame.rotation[:, 2])
    left = np.cross(np.array([0.0, 0.0, 1.0]), front)
    position = target + spec.distance * front + spec.height * np.array([0.0, 0.0, 1.0])
    position = position + spec.lateral * left
    return CameraMount(HEAD_CAMERA_NAME, look_at(position, target), spec.intrinsics)


@dataclass(frozen=True)
class WristCamera:
    """A robot's wrist camera: at `position` (3,) [m] in the tool frame (z the approach), its
    optical axis along the tool's z and image x along the tool's x; it looks from `standoff`
    [m] back from the perceived contact point, on the approach line (the hand then aside of
    it, out of the view's centre)."""

    position: tuple[float, float, float]
    standoff: float
    intrinsics: CameraIntrinsics

    def mount(self) -> CameraMount:
        """The camera in the tool frame (for composing it onto the robot's hand)."""
        return CameraMount(
            WRIST_CAMERA_NAME, CameraPose(np.asarray(self.position), np.eye(3)), self.intrinsics
        )

    def look_pose(self, point: FloatArray, orientation: Rotation) -> Pose:
        """The tool pose at `orientation` (its z the approach) from which the camera looks at
        `point` (3,) [m] along the approach from `standoff`."""
        rotation = orientation.as_matrix()
        eye = np.asarray(point, dtype=float) - self.standoff * rotation[:, 2]
        return Pose(eye - rotation @ np.asarray(self.position), orientation)


#: Each robot's wrist camera (a RealSense-like depth stream on a bracket 8 cm off the hand's
#: axis, 20 cm behind the tool point: on the Jaco, on its last link behind the flange). Its
#: standoff is then the pre-grasp's depth: the look pose is the pre-grasp moved 8 cm aside.
WRIST_CAMERAS: dict[str, WristCamera] = {
    "hook-hand": WristCamera((0.08, 0.0, -0.20), 0.30, CameraIntrinsics(640, 480, 58.0)),
    "jaco": WristCamera((0.08, 0.0, -0.20), 0.30, CameraIntrinsics(640, 480, 58.0)),
}
WRIST_CAMERA_NAME = "wrist_camera"


def wrist_camera(robot: str) -> WristCamera:
    """The robot's wrist camera (`WRIST_CAMERAS`, by embodiment name)."""
    name = robot.partition(":")[0]
    if name not in WRIST_CAMERAS:
        raise UnknownNameError("robot with a wrist camera", name, list(WRIST_CAMERAS))
    return WRIST_CAMERAS[name]


def crop_corners(frame: GraspFrame) -> FloatArray:
    """(8, 3) [m] world corners of the crop's box (for a camera's region of interest)."""
    half = 0.5 * CROP_SIZE
    local = np.array(
        [
            [x, y, z]
            for x in (-half, half)
            for y in (-half, half)
            for z in (-DEPTH_RANGE, DEPTH_RANGE)
        ]
    )
    return frame.to_world(local)


@dataclass(frozen=True)
class Perception:
    """What the camera showed: the crop (height map [m]), its frame, the handle shape and the
    recognizer's result."""

    shape: str
    frame: GraspFrame
    height: FloatArray
    recognition: Recognition


def perceive(skill: SkillParameters, image: DepthImage, recognizer: Recognizer) -> Perception:
    """Crop the image around the demonstrated grasp and recognize the contact point."""
    shape, frame = nominal_frame(skill)
    height = depth_crop(image.points(), frame)
    return Perception(shape, frame, height, recognizer.recognize(height, frame, shape))


def perceive_again(
    first: Perception, images: list[DepthImage], recognizer: Recognizer
) -> Perception:
    """The second look: the points of `images` (the head camera's and the wrist camera's from
    the look pose) in one crop around the first recognition's contact point, recognized
    again. Each view fills what the other hides; the nearer one's points are the finer."""
    frame = GraspFrame(np.asarray(first.recognition.contact_point), first.frame.rotation)
    points = np.concatenate([image.points() for image in images])
    height = depth_crop(points, frame)
    return Perception(first.shape, frame, height, recognizer.recognize(height, frame, first.shape))


def corrected_skill(skill: SkillParameters, recognition: Recognition) -> SkillParameters:
    """The skill with the recognized contact point as its start. A hinge keeps its fitted
    axis line; the radius becomes the contact point's distance from it, the centre the foot
    of that distance and the initial direction the opening tangent there."""
    p = np.asarray(recognition.contact_point, dtype=float)
    out = dataclasses.replace(skill, start_position=[float(v) for v in p])
    if skill.constraint_type != "revolute" or skill.centre is None or skill.axis is None:
        return out
    axis = unit(np.asarray(skill.axis, dtype=float))
    centre = np.asarray(skill.centre, dtype=float)
    rel = p - centre
    foot = centre + float(rel @ axis) * axis
    radial = p - foot
    radius = float(np.linalg.norm(radial))
    normal = np.asarray(skill.workplane_normal, dtype=float)
    tangent = unit(np.cross(normal, radial))
    if float(tangent @ np.asarray(skill.initial_direction)) < 0.0:
        tangent = -tangent
    return dataclasses.replace(
        out,
        centre=[float(v) for v in foot],
        radius=radius,
        initial_direction=[float(v) for v in tangent],
    )

"""Learning-from-Observation: skill parameters from a one-shot demonstration, and their run.

`load(path)` reads a demonstration (cap-demo/1 JSON or a t,x,y,z CSV), `infer_skill(demo)`
gives the `SkillParameters` (constraint, workplane, initial direction, radius, grasp, goal,
with warnings for what was assumed), and `execute(skill, robot=...)` runs them on a simulated
object built where the demonstration happened. Names are resolved on first use, so importing
this package imports neither MuJoCo nor the executor.
"""

from __future__ import annotations

from constraint_aware.lazy import lazy_getattr

_EXPORTS = {
    "DemoError": "demo",
    "Demonstration": "demo",
    "load": "demo",
    "InferenceError": "infer",
    "SkillParameters": "infer",
    "infer_skill": "infer",
    "execute": "execute",
    "DemonstratedScene": "scene",
    "scene_from_skill": "scene",
    "UncertainEstimateError": "plausibility",
    "UnitError": "plausibility",
}
__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)

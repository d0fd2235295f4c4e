"""`constraint_aware/SingleSystem-v0`: the training environment with Gymnasium's render API."""

from __future__ import annotations

from typing import Any

import numpy as np

from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import FloatArray
from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.env import SingleSystemEnv

RENDER_MODES: tuple[str, ...] = ("rgb_array",)
RENDER_SIZE = (320, 320)  # [px] width, height of an rgb_array frame


def check_render_mode(render_mode: str | None, valid: tuple[str, ...] = RENDER_MODES) -> None:
    if render_mode is not None and render_mode not in valid:
        raise UnknownNameError("render_mode", render_mode, valid)


def draw_single_system(batch: SingleSystemBatch, index: int = 0) -> np.ndarray:
    """(H, W, 3) uint8: episode `index` seen along its workplane normal.

    Grey: the joint axis u; blue: the motion direction d; red: the guide force F (scaled to the
    1 cm step force k * step_length). Drawn with matplotlib's object API (no pyplot).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from constraint_aware.figio import new_figure

    p = batch.params
    normal = p.workplane_normal[index]
    e1 = p.axis[index]
    e2 = np.cross(normal, e1)

    def plane(v: FloatArray) -> tuple[float, float]:
        return float(v @ e1), float(v @ e2)

    width, height = RENDER_SIZE
    fig = new_figure(figsize=(width / 80, height / 80), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.02, 0.02, 0.96, 0.96))
    ax.plot([-1.2, 1.2], [0.0, 0.0], color="grey", lw=3)
    step_force = float(p.stiffness[index]) * batch.config.step_length
    for vec, color in (
        (batch.direction[index], "tab:blue"),
        (batch.force[index] / step_force, "tab:red"),
    ):
        x, y = plane(vec)
        ax.annotate("", xy=(x, y), xytext=(0.0, 0.0), arrowprops={"color": color, "width": 3})
    ax.set_xlim(-1.2, 1.2)
    ax.set_ylim(-1.2, 1.2)
    ax.set_aspect("equal")
    ax.axis("off")
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


class SingleSystemGymEnv(SingleSystemEnv):
    """`SingleSystemEnv` (see its docstring for the episode) plus `render_mode="rgb_array"`.

    Keywords: `config` (EnvConfig: every range of the episode distribution), `backend`
    ("analytic" closed form or "mujoco"), `render_mode` (None or "rgb_array": a schematic of
    the episode in its workplane, `draw_single_system`). Randomness comes only from the
    generator seeded by `reset(seed=...)`.
    """

    metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES), "render_fps": 5}  # noqa: RUF012

    def __init__(
        self,
        config: EnvConfig | None = None,
        backend: str = "analytic",
        render_mode: str | None = None,
    ) -> None:
        check_render_mode(render_mode)
        super().__init__(config, backend)
        self.render_mode = render_mode

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            return None
        return draw_single_system(self._batch, 0)

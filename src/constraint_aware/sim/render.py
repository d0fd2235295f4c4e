"""Offscreen rendering of a task: snapshots and videos (MUJOCO_GL=egl works headless)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from constraint_aware.errors import CapError


class SceneRenderer:
    """Renders frames of a model/data pair from a free camera aimed at `lookat`."""

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int = 640,
        height: int = 480,
        lookat: np.ndarray | None = None,
        distance: float = 1.1,
        azimuth: float = 150.0,
        elevation: float = -25.0,
    ) -> None:
        try:
            self.renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as exc:  # no GL context: headless without EGL/OSMesa
            raise CapError(
                f"offscreen rendering unavailable ({exc}); set MUJOCO_GL=egl or osmesa"
            ) from exc
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.lookat[:] = lookat if lookat is not None else model.stat.center
        self.camera.distance = distance
        self.camera.azimuth = azimuth
        self.camera.elevation = elevation

    def frame(self, data: mujoco.MjData) -> np.ndarray:
        """(height, width, 3) uint8 RGB."""
        self.renderer.update_scene(data, self.camera)
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()


def save_png(image: np.ndarray, path: str | Path) -> Path:
    import matplotlib.pyplot as plt

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(out, image)
    return out


def save_video(frames: list[np.ndarray], path: str | Path, fps: int = 10) -> Path:
    """Write frames as .gif (Pillow) or .mp4 (needs ffmpeg through matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.animation as animation
    import matplotlib.pyplot as plt
    from matplotlib.artist import Artist

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not frames:
        raise CapError("no frames to write")
    h, w = frames[0].shape[:2]
    fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.axis("off")
    im = ax.imshow(frames[0])

    def update(i: int) -> list[Artist]:
        im.set_data(frames[i])
        return [im]

    anim = animation.FuncAnimation(fig, update, frames=len(frames), interval=1000 / fps)
    if out.suffix == ".gif":
        anim.save(str(out), writer=animation.PillowWriter(fps=fps))
    elif out.suffix == ".mp4":
        if not animation.FFMpegWriter.isAvailable():
            plt.close(fig)
            raise CapError("writing .mp4 needs ffmpeg on the PATH; use a .gif path instead")
        anim.save(str(out), writer=animation.FFMpegWriter(fps=fps))
    else:
        plt.close(fig)
        raise CapError(f"video format {out.suffix!r}; valid: .gif, .mp4")
    plt.close(fig)
    return out

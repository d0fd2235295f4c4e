"""Offscreen rendering of a task: snapshots and videos.

GL backend. MuJoCo chooses its OpenGL platform from the `MUJOCO_GL` environment variable once,
when `import mujoco` first runs (module `mujoco.rendering.classic.gl_context`); unset, Linux
gets GLFW, which needs a display. Importing this package never touches the variable. Only when
a `SceneRenderer` is built, and only on Linux without a display and without a user choice of
`MUJOCO_GL`, do we render through EGL: we set `MUJOCO_GL=egl` (so that a later first import of
MuJoCo, and any child process, agrees) and, because MuJoCo has usually been imported already by
then, create the EGL context ourselves instead of relying on MuJoCo's import-time choice. Every
other case (a display, macOS, Windows, or `MUJOCO_GL` set by the user) uses MuJoCo's own
`mujoco.Renderer` and its own choice.

Videos: `.gif` through Pillow directly; `.mp4` through imageio with the `imageio-ffmpeg` wheel's
bundled ffmpeg (the `video` extra); no system ffmpeg is needed.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from constraint_aware.errors import CapError, InvalidInputError

VIDEO_SUFFIXES: tuple[str, ...] = (".gif", ".mp4")
IMAGE_SUFFIXES: tuple[str, ...] = (".png",)


_chose_egl = False  # set once this module chose EGL (and set MUJOCO_GL) for a headless Linux


def headless_egl_needed() -> bool:
    """True on Linux without a display when the user has not chosen `MUJOCO_GL` (or when
    this module already chose EGL for them: MuJoCo's import-time choice was made before)."""
    if _chose_egl:
        return True
    if "MUJOCO_GL" in os.environ or platform.system() != "Linux":
        return False
    return not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class _EglRenderer:
    """mujoco.Renderer's job on an EGL context we own (MuJoCo picked GLFW at import)."""

    MAX_GEOM = 10000  # geoms a frame draws at most
    FONT_SCALE = mujoco.mjtFontScale.mjFONTSCALE_150

    def __init__(self, model: mujoco.MjModel, height: int, width: int) -> None:
        from mujoco.egl import GLContext  # sets PYOPENGL_PLATFORM=egl itself if unset

        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise InvalidInputError(
                f"image {width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        self._gl = GLContext(width, height)
        self._gl.make_current()
        self._model = model
        self._scene = mujoco.MjvScene(model, maxgeom=self.MAX_GEOM)
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._context = mujoco.MjrContext(model, self.FONT_SCALE.value)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._context)
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._rgb = np.empty((height, width, 3), dtype=np.uint8)
        self._camera: mujoco.MjvCamera | None = None

    def update_scene(self, data: mujoco.MjData, camera: mujoco.MjvCamera) -> None:
        mujoco.mjv_updateScene(
            self._model,
            data,
            self._option,
            self._perturb,
            camera,
            mujoco.mjtCatBit.mjCAT_ALL.value,
            self._scene,
        )

    def render(self) -> np.ndarray:
        self._gl.make_current()
        mujoco.mjr_render(self._rect, self._scene, self._context)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._context)
        return np.flipud(self._rgb)  # OpenGL's rows run bottom-up

    def close(self) -> None:
        self._context.free()
        self._gl.free()


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
        self.renderer: Any
        try:
            if headless_egl_needed():
                global _chose_egl
                _chose_egl = True
                os.environ["MUJOCO_GL"] = "egl"
                self.renderer = _EglRenderer(model, height=height, width=width)
            else:
                self.renderer = mujoco.Renderer(model, height=height, width=width)
        except CapError:
            raise
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
        return np.array(self.renderer.render(), copy=True)

    def close(self) -> None:
        self.renderer.close()


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an (H, W, 3) uint8 image as PNG (Pillow)."""
    from PIL import Image

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(out)
    return out


def check_video_path(path: str | Path) -> Path:
    """Fail before any simulation if `path` cannot be written as a video here.

    `.gif` needs only Pillow (a dependency of matplotlib); `.mp4` needs the `video` extra
    (imageio and imageio-ffmpeg, whose wheel bundles ffmpeg).
    """
    out = Path(path)
    suffix = out.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise InvalidInputError(
            f"video {str(out)!r}: suffix {suffix or '(none)'!r}; valid: {', '.join(VIDEO_SUFFIXES)}"
        )
    if suffix == ".mp4":
        try:
            import imageio.v2  # noqa: F401
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()  # the wheel's bundled binary
        except (ImportError, RuntimeError) as exc:
            raise CapError(
                f"writing .mp4 needs the 'video' extra ({exc}): "
                "pip install 'constraint-aware[video]'; or write a .gif"
            ) from exc
    return out


def save_video(frames: Sequence[np.ndarray], path: str | Path, fps: int = 10) -> Path:
    """Write (H, W, 3) uint8 frames as .gif (Pillow) or .mp4 (imageio + imageio-ffmpeg)."""
    out = check_video_path(path)
    if not frames:
        raise CapError("no frames to write")
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() == ".gif":
        from PIL import Image

        images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
        images[0].save(
            out,
            save_all=True,
            append_images=images[1:],
            duration=round(1000 / fps),  # [ms] per frame
            loop=0,
        )
    else:
        import imageio.v2 as imageio

        # macro_block_size 1: keep odd frame sizes instead of resizing them with a warning
        writer: Any = imageio.get_writer(out, fps=fps, codec="libx264", macro_block_size=1)
        with writer:
            for f in frames:
                writer.append_data(np.asarray(f, dtype=np.uint8))
    return out

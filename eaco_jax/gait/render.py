"""Offscreen video of a simulated gait (MP4 through imageio-ffmpeg, or GIF).

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported, and importing it
with ``MUJOCO_GL=egl`` on a host without a loadable libEGL crashes. :func:`ensure_headless_gl`
(call it before anything imports mujoco) therefore chooses, when no display is set: ``egl`` only
if libEGL loads, else ``osmesa`` only if libOSMesa loads, else ``disable`` (no video, and
:data:`GL_NOTE` says why in one line naming ``MUJOCO_GL``); with ``video=False`` it sets
``disable`` without probing anything. A user's own ``MUJOCO_GL`` is kept unless it names a
library that does not load. :func:`render_video` raises :class:`RenderUnavailable` with the
reason when no context can be made, so callers can say so and skip only the video.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib.util
import os
from pathlib import Path

import numpy as np

_LIBS = {"egl": ("EGL", "libEGL.so.1"), "osmesa": ("OSMesa", "libOSMesa.so.8")}
GL_NOTE: str | None = None
"""Why offscreen video is off on this host (one line), or None."""


class RenderUnavailable(RuntimeError):
    """No offscreen OpenGL context could be created on this machine."""


def gl_library_loads(backend: str) -> bool:
    """Whether the shared library MuJoCo's ``backend`` ("egl" | "osmesa") needs can be loaded
    (and PyOpenGL, which MuJoCo drives it through, is installed). Loads no GL context."""
    if importlib.util.find_spec("OpenGL") is None:
        return False
    name, fallback = _LIBS[backend]
    for candidate in (ctypes.util.find_library(name), fallback):
        if not candidate:
            continue
        try:
            ctypes.CDLL(candidate)
            return True
        except OSError:
            continue
    return False


def ensure_headless_gl(video: bool = True) -> str | None:
    """Set ``MUJOCO_GL`` so that importing mujoco cannot crash (call before importing mujoco);
    return the backend chosen (None: a display is set and the user chose nothing)."""
    global GL_NOTE
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if not video and not chosen:
        os.environ["MUJOCO_GL"] = "disable"
        GL_NOTE = "video off (--no-video): MUJOCO_GL=disable"
        return "disable"
    if chosen in _LIBS:
        if not gl_library_loads(chosen):
            GL_NOTE = (f"MUJOCO_GL={chosen} but lib{_LIBS[chosen][0]} does not load here: "
                       "video off (install it, or set MUJOCO_GL=osmesa/egl to one that loads)")
            os.environ["MUJOCO_GL"] = "disable"
            return "disable"
        return chosen
    if chosen or os.environ.get("DISPLAY"):
        return chosen or None
    for backend in ("egl", "osmesa"):
        if gl_library_loads(backend):
            os.environ["MUJOCO_GL"] = backend
            return backend
    os.environ["MUJOCO_GL"] = "disable"
    GL_NOTE = ("no display and neither libEGL nor libOSMesa loads: video off "
               "(install libegl1 or libosmesa6 and set MUJOCO_GL=egl or osmesa)")
    return "disable"


def render_frames(
    model,
    qpos: np.ndarray,
    *,
    width: int = 480,
    height: int = 360,
    track_body: str | None = None,
    distance: float = 1.6,
    azimuth: float = 120.0,
    elevation: float = -15.0,
) -> np.ndarray:
    """Render one RGB frame per row of ``qpos`` (T, nq); the camera follows ``track_body``."""
    import mujoco

    if os.environ.get("MUJOCO_GL", "").strip().lower() in ("disable", "disabled", "off"):
        raise RenderUnavailable(GL_NOTE or "MUJOCO_GL=disable: offscreen rendering is off")
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # GL context creation failures come as several exception types
        raise RenderUnavailable(
            f"offscreen rendering failed ({err}); set MUJOCO_GL=egl or osmesa and install "
            "libegl1/libosmesa6"
        ) from err
    data = mujoco.MjData(model)
    cam = mujoco.MjvCamera()
    cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elevation
    if track_body is not None:
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, track_body)
        if cam.trackbodyid < 0:
            raise ValueError(f"body {track_body!r} not in the model")
    frames = np.empty((len(qpos), height, width, 3), np.uint8)
    try:
        for i, q in enumerate(np.asarray(qpos)):
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=cam)
            frames[i] = renderer.render()
    finally:
        renderer.close()
    return frames


def write_video(frames: np.ndarray, path: str | Path, fps: float = 30.0) -> Path:
    """Write frames as MP4 (H.264 via imageio-ffmpeg) or GIF, chosen by the file suffix."""
    import imageio.v2 as imageio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        imageio.mimsave(path, list(frames), duration=1.0 / fps, loop=0)
    elif path.suffix.lower() == ".mp4":
        imageio.mimsave(path, list(frames), fps=fps, codec="libx264", macro_block_size=8)
    else:
        raise ValueError(f"video path must end in .mp4 or .gif, got {path.name!r}")
    return path


def render_video(
    model,
    qpos: np.ndarray,
    dt: float,
    path: str | Path,
    *,
    fps: float = 30.0,
    track_body: str | None = None,
    **camera,
) -> Path:
    """Render a trajectory sampled every ``dt`` seconds to ``path`` at ``fps`` frames/s."""
    stride = max(1, int(round(1.0 / (fps * dt))))
    frames = render_frames(model, np.asarray(qpos)[::stride], track_body=track_body, **camera)
    return write_video(frames, path, fps=1.0 / (stride * dt))

"""Offscreen video of a simulated gait (MP4 through imageio-ffmpeg, or GIF).

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported; headless machines
need ``egl`` (GPU or Mesa) or ``osmesa``. :func:`ensure_headless_gl` sets ``egl`` if the user has
not chosen, and :func:`render_video` raises :class:`RenderUnavailable` with the reason when no
context can be made, so callers can say so and skip only the video.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


class RenderUnavailable(RuntimeError):
    """No offscreen OpenGL context could be created on this machine."""


def ensure_headless_gl() -> None:
    """Default ``MUJOCO_GL`` to ``egl`` when no display is set (call before importing mujoco)."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"


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

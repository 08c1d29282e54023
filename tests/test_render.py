"""A real offscreen render of a falling box to MP4 and GIF (skips only if no GL context)."""

import numpy as np
import pytest

from eaco_jax.gait.render import RenderUnavailable, ensure_headless_gl, render_video

XML = """<mujoco><worldbody><light pos="0 0 3"/><geom type="plane" size="2 2 .1"/>
<body name="box" pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_render_falling_box(tmp_path, suffix):
    ensure_headless_gl()
    import mujoco

    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    qpos = []
    for _ in range(200):
        mujoco.mj_step(model, data)
        qpos.append(data.qpos.copy())
    try:
        path = render_video(model, np.array(qpos), model.opt.timestep, tmp_path / f"v{suffix}",
                            fps=25, track_body="box")
    except RenderUnavailable as err:
        pytest.skip(str(err))
    assert path.stat().st_size > 1000
    import imageio.v2 as imageio

    if suffix == ".gif":
        frames = imageio.mimread(path)
    else:  # the ffmpeg reader's len() is inf, so iterate instead of list()
        with imageio.get_reader(path, "ffmpeg") as reader:
            frames = [frame for frame in reader]
    assert len(frames) >= 5 and np.asarray(frames[0]).std() > 1  # not a blank image


# ------------------------------------------------------------------ choosing MUJOCO_GL safely
@pytest.fixture
def clean_env(monkeypatch):
    import eaco_jax.gait.render as render

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr(render, "GL_NOTE", None)
    return render


def test_egl_only_when_libegl_loads(clean_env, monkeypatch):
    import os

    render = clean_env
    monkeypatch.setattr(render, "gl_library_loads", lambda b: b == "egl")
    assert render.ensure_headless_gl() == "egl" and os.environ["MUJOCO_GL"] == "egl"
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setattr(render, "gl_library_loads", lambda b: b == "osmesa")
    assert render.ensure_headless_gl() == "osmesa"
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setattr(render, "gl_library_loads", lambda b: False)
    assert render.ensure_headless_gl() == "disable"
    assert "MUJOCO_GL" in render.GL_NOTE and "\n" not in render.GL_NOTE


def test_user_choice_kept_unless_its_library_is_missing(clean_env, monkeypatch):
    import os

    render = clean_env
    monkeypatch.setattr(render, "gl_library_loads", lambda b: False)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert render.ensure_headless_gl() == "disable" and "MUJOCO_GL=egl" in render.GL_NOTE
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    assert render.ensure_headless_gl() == "glfw" and os.environ["MUJOCO_GL"] == "glfw"
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.delenv("MUJOCO_GL")
    assert render.ensure_headless_gl() is None and "MUJOCO_GL" not in os.environ


def test_no_video_touches_no_gl(clean_env, monkeypatch):
    render = clean_env

    def boom(_):
        raise AssertionError("probed a GL library")

    monkeypatch.setattr(render, "gl_library_loads", boom)
    assert render.ensure_headless_gl(video=False) == "disable"


def test_host_without_gl_imports_and_skips_video():
    """As on a bare GPU host without libEGL: importing eaco_jax and mujoco works, no warp noise,
    and a video request says why in one line naming MUJOCO_GL."""
    import os
    import subprocess
    import sys

    code = (
        "import eaco_jax.gait.render as r\n"
        "r.gl_library_loads = lambda b: False\n"
        "print(r.ensure_headless_gl())\n"
        "import mujoco, eaco_jax, eaco_jax.problems.gait\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco/>')\n"
        "try:\n"
        "    r.render_frames(m, [[]])\n"
        "except r.RenderUnavailable as e:\n"
        "    print('unavailable:', e)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "disable"
    assert lines[-1].startswith("unavailable:") and "MUJOCO_GL" in lines[-1]
    assert "Failed to import warp" not in out.stdout + out.stderr


def test_warp_notes_dropped_but_real_errors_kept():
    from eaco_jax.gait.mjx_import import drop_warp_notes

    text = ("Failed to import warp: No module named 'warp'\n"
            "Failed to import mujoco_warp: No module named 'warp'\n"
            "Failed to import warp: CUDA driver version is insufficient\n"
            "other line\n")
    assert drop_warp_notes(text) == ("Failed to import warp: CUDA driver version is insufficient\n"
                                     "other line\n")


def test_warp_silenced_on_releases_with_log_level():
    """Warp 1.19 reads ``config.log_level`` (``quiet`` is gone): its greeting and "Module ...
    load" lines went to stdout inside a gait-eval ``--json`` record. A stand-in module
    carries the two config layouts (CI has no warp-lang)."""
    import types

    from eaco_jax.gait.mjx_import import silence_warp

    new = types.SimpleNamespace(LOG_WARNING=30, config=types.SimpleNamespace(log_level=20))
    silence_warp(new)
    assert new.config.log_level == 30 and new.config.quiet is True
    old = types.SimpleNamespace(config=types.SimpleNamespace(quiet=False))
    silence_warp(old)
    assert old.config.quiet is True and not hasattr(old.config, "log_level")

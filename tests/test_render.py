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

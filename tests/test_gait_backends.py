"""MJX and native MuJoCo agree: the same gait parameters give the same torso path and fitness.

One compiled MJX rollout (2 gaits x 1 s) serves both MJX checks; they are marked slow because
compiling MJX's step for this model takes 2.5-8 minutes on the shared 2-core CPU (the rollout
itself takes seconds). ``test_problem_errors`` runs the native backend in CI.
Stated tolerance: torso positions within 1 mm and fitness within 5 mm
after 1 s (float32 MJX vs float64 C engine, same model and solver settings).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.fitness import gait_fitness
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.gait import make_gait_problem

HORIZON = 1.0


def _gait(**kw):
    v = dict(step_length=0.0, hip_height=0.22, duty_ratio=0.6, period=0.5, foot_lift=0.0,
             step_width=0.0, lateral_sway=0.0, torso_pitch=0.0, arm_swing=0.0,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    v.update(kw)
    return [v[n] for n in we.PARAM_NAMES]


@pytest.fixture(scope="module")
def runs():
    x = jnp.asarray([_gait(), _gait(step_length=0.06, foot_lift=0.02, period=0.4,
                                    lateral_sway=0.01, arm_swing=0.3)], jnp.float32)
    out = {}
    for backend in ("native", "mjx"):
        p = make_gait_problem("nao", backend=backend, horizon=HORIZON)
        tr = jax.jit(p.trace)(x)
        fit = gait_fitness(p.summarize(tr))
        out[backend] = (np.asarray(tr), {k: np.asarray(v) for k, v in fit.items()})
    return out


@pytest.mark.slow
def test_backends_agree(runs):
    tn, fn = runs["native"]
    tm, fm = runs["mjx"]
    assert tn.shape == tm.shape == (2, int(HORIZON / 0.02) + 1, 7)
    np.testing.assert_allclose(tm[..., :3], tn[..., :3], atol=1e-3)
    np.testing.assert_allclose(fm["fitness"], fn["fitness"], atol=5e-3)
    np.testing.assert_array_equal(fm["fell"], fn["fell"])
    assert fn["distance_m"][1] > 0.02  # the second gait really walks


@pytest.mark.slow
def test_stands_still_on_mjx(runs):
    tm, fm = runs["mjx"]
    assert np.linalg.norm(tm[0, -1, :2] - tm[0, 0, :2]) < 0.01
    assert abs(tm[0, -1, 2] - 0.305) < 0.01 and not fm["fell"][0]


def test_problem_errors():
    with pytest.raises(ProblemError, match="known robots"):
        make_gait_problem("asimo")
    with pytest.raises(ProblemError, match="unknown backend"):
        make_gait_problem("nao", backend="gpu")
    p = make_gait_problem("nao", backend="native", horizon=0.2)
    with pytest.raises(ProblemError, match="solutions must be"):
        p.evaluate(jnp.zeros((3, 5)))
    ev = jax.jit(p.evaluate)(jnp.asarray([_gait(step_length=0.05)] * 2, jnp.float32))
    assert ev.f.shape == (2,) and np.all(np.isfinite(ev.f)) and np.all(ev.violation == 0)


def test_native_backend_without_cpu_platform_says_how_to_fix():
    """JAX_PLATFORMS=cuda hides the CPU device pure_callback needs: a clear error up front."""
    import os
    import subprocess
    import sys

    code = ("from eaco_jax.problems.gait import make_gait_problem\n"
            "make_gait_problem('nao', backend='native')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "JAX_PLATFORMS": "cuda"}, timeout=120)
    assert out.returncode != 0
    assert "ProblemError" in out.stderr and "JAX_PLATFORMS=cuda,cpu" in out.stderr


def test_colony_runs_native_rollouts_inside_scan():
    """The native backend's pure_callback works inside minimize's jitted lax.scan."""
    import eaco_jax as ea
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    p = make_gait_problem("nao", backend="native", horizon=0.2)
    strategy = ContinuousEACO(num_ants=3, archive_size=3, refine_ants=0, repair_steps=0)
    res = ea.minimize(p, strategy, seed=0, iterations=2)
    assert np.isfinite(res.best_cost) and res.best_cost <= 0.0
    assert np.all(res.best_solution >= np.asarray(p.lower) - 1e-6)
    assert int(res.evaluations) == 2 * 3


def test_backends_agree_short_horizon():
    """CI version of test_backends_agree, through ``simulate(record=True)`` (which also records
    joint angles): one walking gait, 0.2 s, same tolerances; joints within 0.01 rad."""
    g = _gait(step_length=0.06, foot_lift=0.02, period=0.4, lateral_sway=0.01, arm_swing=0.3)
    p = make_gait_problem("nao", backend="native", horizon=0.2)
    runs = {b: p.simulate(g, record=True, backend=b) for b in ("native", "mjx")}
    n, m = runs["native"], runs["mjx"]
    assert m["backend"] == "mjx" and n["backend"] == "native"
    assert m["torso_xyz"].shape == n["torso_xyz"].shape == (11, 3)
    assert m["qpos"].shape == n["qpos"].shape and np.all(np.isfinite(m["qpos"]))
    np.testing.assert_allclose(m["torso_xyz"], n["torso_xyz"], atol=1e-3)
    for name in ("LHipPitch", "LKneePitch", "LAnklePitch", "RHipPitch"):
        np.testing.assert_allclose(m["joints"][name], n["joints"][name], atol=1e-2)
    np.testing.assert_allclose(m["controls"], n["controls"])
    assert abs(m["fitness"] - n["fitness"]) < 5e-3 and m["fell"] == n["fell"]

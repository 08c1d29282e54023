"""Colony evaluation split over devices equals the single-device evaluation.

Runs in a subprocess with two forced CPU devices (XLA flags must be set before JAX starts).
"""

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import jax, jax.numpy as jnp, numpy as np
    assert len(jax.devices()) == 2, jax.devices()
    sys_path = {path!r}
    import sys; sys.path.insert(0, sys_path)
    from test_driver import RandomSearch, Sphere
    import eaco_jax as ea
    from eaco_jax.problems.sharding import shard

    problem = Sphere(lower=-jnp.ones(3), upper=jnp.ones(3))
    sharded = shard(problem)
    x = jax.random.uniform(jax.random.key(0), (8, 3))
    a, b = jax.jit(problem.evaluate)(x), jax.jit(sharded.evaluate)(x)
    np.testing.assert_allclose(a.f, b.f, rtol=1e-6)
    one = ea.minimize(problem, RandomSearch(), seed=2, iterations=6)
    two = ea.minimize(sharded, RandomSearch(), seed=2, iterations=6)
    np.testing.assert_allclose(one.history["best_cost"], two.history["best_cost"], rtol=1e-6)
    uneven = jax.jit(sharded.evaluate)(x[:3])  # 3 ants over 2 devices: padded by XLA
    np.testing.assert_allclose(uneven.f, a.f[:3], rtol=1e-6)
    print("SHARDING-OK")
    """
)


def test_sharded_evaluation_matches_single_device():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
               JAX_PLATFORMS="cpu")
    code = SCRIPT.format(path=os.path.dirname(__file__))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300)
    assert "SHARDING-OK" in out.stdout, out.stdout + out.stderr

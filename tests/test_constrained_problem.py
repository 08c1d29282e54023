"""ConstrainedProblem validation, batching, pytree use, and the CEC2006 suite's optima."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.problems import ConstrainedProblem, cec2006, float64
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.cec2006 import BUILDERS


def obj(x):
    return jnp.sum(x**2)


def ineq(x):
    return jnp.stack([x[0] + x[1] - 1.0])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(lower=[0.0, 1.0], upper=[1.0, 0.0]), "reversed"),
        (dict(lower=[0.0, float("nan")], upper=[1.0, 1.0]), "finite"),
        (dict(lower=[0.0, 0.0, 0.0], upper=[1.0, 1.0]), "same length"),
        (dict(lower=[[0.0]], upper=[[1.0]]), "1-D"),
        (dict(lower=[0.0, 0.0], upper=[1.0, 1.0], objective=lambda x: x * 2), "scalar"),
        (dict(lower=[0.0, 0.0], upper=[1.0, 1.0], inequality=lambda x: jnp.outer(x, x)), "1-D"),
        (dict(lower=[0.0, 0.0], upper=[1.0, 1.0], equality=lambda x: x[5:7] @ jnp.ones(3)),
         "fails"),
        (dict(lower=[0.0, 0.0], upper=[1.0, 1.0], objective=3.0), "function"),
    ],
)
def test_bad_problems_raise_one_clear_error(kwargs, match):
    args = dict(objective=obj, inequality=ineq, equality=None)
    args.update(kwargs)
    objective = args.pop("objective")
    with pytest.raises(ProblemError, match=match):
        ConstrainedProblem(objective, args.pop("inequality"), args.pop("equality"), **args)


def test_evaluate_batched_and_jittable():
    prob = ConstrainedProblem(obj, ineq, lambda x: jnp.stack([x[0] - x[1]]),
                              lower=[-2.0, -2.0], upper=[2.0, 2.0], name="toy")
    x = jnp.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]])
    ev = jax.jit(lambda p, s: p.evaluate(s))(prob, x)
    np.testing.assert_allclose(ev.f, [0.0, 2.0, 0.5])
    np.testing.assert_allclose(ev.violation, [0.0, 1.0, 0.0], atol=1e-7)
    assert prob.kind == "continuous" and prob.dim == 2
    assert prob.num_inequality == 1 and prob.num_equality == 1
    leaves = jax.tree.leaves(prob)
    assert len(leaves) == 2  # only the bounds are traced


KNOWN_X = {
    "g01": [1] * 9 + [3, 3, 3, 1],
    "g09": [2.330499, 1.951372, -0.4775414, 4.365726, -0.6244870, 1.038131, 1.594227],
    "g10": [579.306685017979589, 1359.97067807935605, 5109.97065743133317, 182.01769963061534,
            295.601173702746792, 217.982300369384632, 286.41652592786852, 395.601173702746735],
    "g13": [-1.71714224003, 1.59572124049468, 1.8272502406271, -0.763659881912867,
            -0.76365986736498],
}


def test_cec2006_known_optima():
    with float64():
        for name, x in KNOWN_X.items():
            prob = cec2006(name)
            ev = prob.evaluate(jnp.asarray([x], prob.dtype))
            assert abs(float(ev.f[0]) - prob.f_star) < 1e-4, name
            assert float(ev.violation[0]) < 1e-6, name


def test_cec2006_lookup():
    for name in BUILDERS:
        assert cec2006(name).name == name
    assert cec2006("G2").name == "g10"  # the paper's naming
    with pytest.raises(ProblemError, match="unknown CEC2006 problem"):
        cec2006("g42")


def test_a_flax_dataclass_with_the_bounds_as_its_only_leaves():
    import dataclasses

    prob = ConstrainedProblem(obj, ineq, lower=[0.0, 0.0], upper=[1.0, 2.0], name="p")
    assert dataclasses.is_dataclass(prob)
    paths = [jax.tree_util.keystr(k) for k, _ in jax.tree_util.tree_leaves_with_path(prob)]
    assert paths == [".lower", ".upper"]
    again = jax.tree.map(lambda x: x * 2, prob)  # unflattened: functions and counts kept
    assert (again.objective, again.num_inequality, again.num_equality) == (obj, 1, 0)
    np.testing.assert_array_equal(again.upper, [2.0, 4.0])
    wider = prob.replace(upper=jnp.array([3.0, 3.0]))
    assert wider.name == "p" and wider.inequality is ineq and wider.dim == 2
    with pytest.raises(dataclasses.FrozenInstanceError):
        prob.name = "q"


#: g06's problem hash in float64 as checkpoints stored it while ConstrainedProblem was a
#: custom pytree node (leaves by flat index); recorded from that class
G06_HASH_BEFORE_DATACLASS = "344b89779e870cd8"


def test_a_checkpoint_stored_before_the_dataclass_resumes(tmp_path):
    """The problem's leaves gained names (``.lower`` for ``[<flat index 0>]``), which changes
    its hash; a checkpoint holding the former hash is the same run and resumes bit-identically."""
    import json
    import shutil

    import eaco_jax as ea
    from eaco_jax.driver import checkpoint
    from eaco_jax.driver.checkpoint import read_meta, tree_hash
    from eaco_jax.strategies import ContinuousEACO

    with float64():
        assert tree_hash(cec2006("g06"), by_index=True) == G06_HASH_BEFORE_DATACLASS
    strategy = ContinuousEACO(num_ants=8, archive_size=10)
    kw = dict(seed=2, iterations=30, chunk_size=10)
    unbroken = ea.minimize(cec2006("g06"), strategy, **kw)
    folder = tmp_path / "g06"
    ea.minimize(cec2006("g06"), strategy, checkpointing=ea.Checkpointing(folder, every=10), **kw)
    shutil.rmtree(folder / "30")
    shutil.rmtree(folder / "20")
    stored = folder / "10" / "meta" / "metadata"
    meta = json.loads(stored.read_text())  # as the former writer sealed it
    meta.pop("meta_digest")
    meta.pop("problem_hash_by_index")
    meta["problem"]["hash"] = G06_HASH_BEFORE_DATACLASS
    stored.write_text(json.dumps({**meta, "meta_digest": checkpoint._meta_digest(meta)}))
    assert read_meta(folder)["problem"]["hash"] == G06_HASH_BEFORE_DATACLASS
    resumed = ea.minimize(cec2006("g06"), strategy,
                          checkpointing=ea.Checkpointing(folder, every=10), **kw)
    np.testing.assert_array_equal(resumed.x, unbroken.x)
    np.testing.assert_array_equal(resumed.history["best_cost"], unbroken.history["best_cost"])
    assert resumed.f == unbroken.f

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

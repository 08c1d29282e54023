"""The CEC2006 constrained benchmark g01-g13 (Liang et al. 2006, "Problem definitions and
evaluation criteria for the CEC 2006 special session on constrained real-parameter optimization").

Each problem is a :class:`~eaco_jax.problems.constrained.ConstrainedProblem` carrying its best
known optimum ``f_star`` from that report. The paper's G1-G4 are g01, g10, g09, g13 (see
PAPER_NOTES.md section 2). For the 1e-4 success rule on g04, g05, g09, g10 build the problem and run
inside :func:`eaco_jax.problems.constrained.float64` (float32 is too coarse at |f| >= ~500).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.constrained import ConstrainedProblem

Array = jax.Array

#: best known optima of the CEC2006 report
F_STAR: dict[str, float] = {
    "g01": -15.0,
    "g02": -0.80361910412559,
    "g03": -1.00050010001000,
    "g04": -30665.538671783,
    "g05": 5126.4967140071,
    "g06": -6961.81387558015,
    "g07": 24.3062090681,
    "g08": -0.0958250414180359,
    "g09": 680.630057374402,
    "g10": 7049.24802052867,
    "g11": 0.7499,
    "g12": -1.0,
    "g13": 0.053941514041898,
}


def _g01() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return 5.0 * jnp.sum(x[:4]) - 5.0 * jnp.sum(x[:4] ** 2) - jnp.sum(x[4:13])

    def g(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7, x8, x9, x10, x11, x12 = (x[i] for i in range(12))
        return jnp.stack([
            2 * x1 + 2 * x2 + x10 + x11 - 10,
            2 * x1 + 2 * x3 + x10 + x12 - 10,
            2 * x2 + 2 * x3 + x11 + x12 - 10,
            -8 * x1 + x10,
            -8 * x2 + x11,
            -8 * x3 + x12,
            -2 * x4 - x5 + x10,
            -2 * x6 - x7 + x11,
            -2 * x8 - x9 + x12,
        ])

    upper = [1.0] * 9 + [100.0] * 3 + [1.0]
    return ConstrainedProblem(f, g, lower=[0.0] * 13, upper=upper, name="g01",
                              f_star=F_STAR["g01"])


def _g02() -> ConstrainedProblem:
    n = 20

    def f(x: Array) -> Array:
        c = jnp.cos(x)
        i = jnp.arange(1, n + 1, dtype=x.dtype)
        num = jnp.abs(jnp.sum(c**4) - 2.0 * jnp.prod(c**2))
        return -num / jnp.sqrt(jnp.maximum(jnp.sum(i * x**2), 1e-30))

    def g(x: Array) -> Array:
        return jnp.stack([0.75 - jnp.prod(x), jnp.sum(x) - 7.5 * n])

    return ConstrainedProblem(f, g, lower=[0.0] * n, upper=[10.0] * n, name="g02",
                              f_star=F_STAR["g02"])


def _g03() -> ConstrainedProblem:
    n = 10

    def f(x: Array) -> Array:
        return -(jnp.sqrt(float(n)) ** n) * jnp.prod(x)

    def h(x: Array) -> Array:
        return jnp.stack([jnp.sum(x**2) - 1.0])

    return ConstrainedProblem(f, None, h, lower=[0.0] * n, upper=[1.0] * n, name="g03",
                              f_star=F_STAR["g03"])


def _g04() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        x1, _, x3, _, x5 = (x[i] for i in range(5))
        return 5.3578547 * x3**2 + 0.8356891 * x1 * x5 + 37.293239 * x1 - 40792.141

    def g(x: Array) -> Array:
        x1, x2, x3, x4, x5 = (x[i] for i in range(5))
        u = 85.334407 + 0.0056858 * x2 * x5 + 0.0006262 * x1 * x4 - 0.0022053 * x3 * x5
        v = 80.51249 + 0.0071317 * x2 * x5 + 0.0029955 * x1 * x2 + 0.0021813 * x3**2
        w = 9.300961 + 0.0047026 * x3 * x5 + 0.0012547 * x1 * x3 + 0.0019085 * x3 * x4
        return jnp.stack([u - 92, -u, v - 110, -v + 90, w - 25, -w + 20])

    return ConstrainedProblem(f, g, lower=[78.0, 33.0, 27.0, 27.0, 27.0],
                              upper=[102.0, 45.0, 45.0, 45.0, 45.0], name="g04",
                              f_star=F_STAR["g04"])


def _g05() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return 3 * x[0] + 0.000001 * x[0] ** 3 + 2 * x[1] + (0.000002 / 3) * x[1] ** 3

    def g(x: Array) -> Array:
        return jnp.stack([-x[3] + x[2] - 0.55, -x[2] + x[3] - 0.55])

    def h(x: Array) -> Array:
        x1, x2, x3, x4 = (x[i] for i in range(4))
        return jnp.stack([
            1000 * jnp.sin(-x3 - 0.25) + 1000 * jnp.sin(-x4 - 0.25) + 894.8 - x1,
            1000 * jnp.sin(x3 - 0.25) + 1000 * jnp.sin(x3 - x4 - 0.25) + 894.8 - x2,
            1000 * jnp.sin(x4 - 0.25) + 1000 * jnp.sin(x4 - x3 - 0.25) + 1294.8,
        ])

    return ConstrainedProblem(f, g, h, lower=[0.0, 0.0, -0.55, -0.55],
                              upper=[1200.0, 1200.0, 0.55, 0.55], name="g05",
                              f_star=F_STAR["g05"])


def _g06() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return (x[0] - 10) ** 3 + (x[1] - 20) ** 3

    def g(x: Array) -> Array:
        return jnp.stack([
            -((x[0] - 5) ** 2) - (x[1] - 5) ** 2 + 100,
            (x[0] - 6) ** 2 + (x[1] - 5) ** 2 - 82.81,
        ])

    return ConstrainedProblem(f, g, lower=[13.0, 0.0], upper=[100.0, 100.0], name="g06",
                              f_star=F_STAR["g06"])


def _g07() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7, x8, x9, x10 = (x[i] for i in range(10))
        return (x1**2 + x2**2 + x1 * x2 - 14 * x1 - 16 * x2 + (x3 - 10) ** 2
                + 4 * (x4 - 5) ** 2 + (x5 - 3) ** 2 + 2 * (x6 - 1) ** 2 + 5 * x7**2
                + 7 * (x8 - 11) ** 2 + 2 * (x9 - 10) ** 2 + (x10 - 7) ** 2 + 45)

    def g(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7, x8, x9, x10 = (x[i] for i in range(10))
        return jnp.stack([
            -105 + 4 * x1 + 5 * x2 - 3 * x7 + 9 * x8,
            10 * x1 - 8 * x2 - 17 * x7 + 2 * x8,
            -8 * x1 + 2 * x2 + 5 * x9 - 2 * x10 - 12,
            3 * (x1 - 2) ** 2 + 4 * (x2 - 3) ** 2 + 2 * x3**2 - 7 * x4 - 120,
            5 * x1**2 + 8 * x2 + (x3 - 6) ** 2 - 2 * x4 - 40,
            x1**2 + 2 * (x2 - 2) ** 2 - 2 * x1 * x2 + 14 * x5 - 6 * x6,
            0.5 * (x1 - 8) ** 2 + 2 * (x2 - 4) ** 2 + 3 * x5**2 - x6 - 30,
            -3 * x1 + 6 * x2 + 12 * (x9 - 8) ** 2 - 7 * x10,
        ])

    return ConstrainedProblem(f, g, lower=[-10.0] * 10, upper=[10.0] * 10, name="g07",
                              f_star=F_STAR["g07"])


def _g08() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        num = jnp.sin(2 * jnp.pi * x[0]) ** 3 * jnp.sin(2 * jnp.pi * x[1])
        den = x[0] ** 3 * (x[0] + x[1])
        return -num / jnp.where(den == 0, 1e-30, den)

    def g(x: Array) -> Array:
        return jnp.stack([x[0] ** 2 - x[1] + 1, 1 - x[0] + (x[1] - 4) ** 2])

    return ConstrainedProblem(f, g, lower=[0.0, 0.0], upper=[10.0, 10.0], name="g08",
                              f_star=F_STAR["g08"])


def _g09() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7 = (x[i] for i in range(7))
        return ((x1 - 10) ** 2 + 5 * (x2 - 12) ** 2 + x3**4 + 3 * (x4 - 11) ** 2
                + 10 * x5**6 + 7 * x6**2 + x7**4 - 4 * x6 * x7 - 10 * x6 - 8 * x7)

    def g(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7 = (x[i] for i in range(7))
        return jnp.stack([
            -127 + 2 * x1**2 + 3 * x2**4 + x3 + 4 * x4**2 + 5 * x5,
            -282 + 7 * x1 + 3 * x2 + 10 * x3**2 + x4 - x5,
            -196 + 23 * x1 + x2**2 + 6 * x6**2 - 8 * x7,
            4 * x1**2 + x2**2 - 3 * x1 * x2 + 2 * x3**2 + 5 * x6 - 11 * x7,
        ])

    return ConstrainedProblem(f, g, lower=[-10.0] * 7, upper=[10.0] * 7, name="g09",
                              f_star=F_STAR["g09"])


def _g10() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return x[0] + x[1] + x[2]

    def g(x: Array) -> Array:
        x1, x2, x3, x4, x5, x6, x7, x8 = (x[i] for i in range(8))
        return jnp.stack([
            -1 + 0.0025 * (x4 + x6),
            -1 + 0.0025 * (x5 + x7 - x4),
            -1 + 0.01 * (x8 - x5),
            -x1 * x6 + 833.33252 * x4 + 100 * x1 - 83333.333,
            -x2 * x7 + 1250 * x5 + x2 * x4 - 1250 * x4,
            -x3 * x8 + 1250000 + x3 * x5 - 2500 * x5,
        ])

    return ConstrainedProblem(f, g, lower=[100.0, 1000.0, 1000.0] + [10.0] * 5,
                              upper=[10000.0] * 3 + [1000.0] * 5, name="g10",
                              f_star=F_STAR["g10"])


def _g11() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return x[0] ** 2 + (x[1] - 1) ** 2

    def h(x: Array) -> Array:
        return jnp.stack([x[1] - x[0] ** 2])

    return ConstrainedProblem(f, None, h, lower=[-1.0, -1.0], upper=[1.0, 1.0], name="g11",
                              f_star=F_STAR["g11"])


def _g12() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return -(100 - jnp.sum((x - 5) ** 2)) / 100

    def g(x: Array) -> Array:
        c = jnp.arange(1, 10, dtype=x.dtype)
        d0 = (x[0] - c) ** 2
        d1 = (x[1] - c) ** 2
        d2 = (x[2] - c) ** 2
        d = d0[:, None, None] + d1[None, :, None] + d2[None, None, :]
        return jnp.stack([jnp.min(d) - 0.0625])

    return ConstrainedProblem(f, g, lower=[0.0] * 3, upper=[10.0] * 3, name="g12",
                              f_star=F_STAR["g12"])


def _g13() -> ConstrainedProblem:
    def f(x: Array) -> Array:
        return jnp.exp(jnp.prod(x))

    def h(x: Array) -> Array:
        x1, x2, x3, x4, x5 = (x[i] for i in range(5))
        return jnp.stack([
            jnp.sum(x**2) - 10,
            x2 * x3 - 5 * x4 * x5,
            x1**3 + x2**3 + 1,
        ])

    return ConstrainedProblem(f, None, h, lower=[-2.3, -2.3, -3.2, -3.2, -3.2],
                              upper=[2.3, 2.3, 3.2, 3.2, 3.2], name="g13",
                              f_star=F_STAR["g13"])


BUILDERS: dict[str, Callable[[], ConstrainedProblem]] = {
    "g01": _g01, "g02": _g02, "g03": _g03, "g04": _g04, "g05": _g05, "g06": _g06,
    "g07": _g07, "g08": _g08, "g09": _g09, "g10": _g10, "g11": _g11, "g12": _g12,
    "g13": _g13,
}

#: the paper's names for its four constrained benchmarks (PAPER_NOTES.md section 2)
PAPER_NAMES = {"G1": "g01", "G2": "g10", "G3": "g09", "G4": "g13"}


def cec2006(name: str) -> ConstrainedProblem:
    """The CEC2006 problem ``name`` ("g01".."g13", or the paper's "G1".."G4")."""
    key = PAPER_NAMES.get(str(name).upper(), str(name).lower())
    if key not in BUILDERS:
        raise ProblemError(
            f"unknown CEC2006 problem {name!r}; choose one of {', '.join(BUILDERS)} "
            f"(or the paper's G1-G4)"
        )
    return BUILDERS[key]()

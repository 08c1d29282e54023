"""Constraint handling: how two (objective, violation) pairs compare.

Three selectable methods, all pure functions of arrays so a strategy can sort its archive
with them under ``jit``/``vmap``:

* ``"penalty"`` - the paper's static penalty: cost = f + PEN * violation.
* ``"deb"`` - Deb's feasibility rules (Deb 2000): a feasible solution beats an infeasible one;
  two feasible ones compare by f; two infeasible ones by violation.
* ``"epsilon"`` - the epsilon-constrained method (Takahama & Sakai 2006): violations up to
  epsilon count as zero, then Deb's rules; epsilon shrinks to 0 on a schedule
  (:func:`epsilon_schedule`).

Two operators move one point with the constraints' derivatives (autodiff):
:func:`gradient_repair` (Newton steps onto the violated constraints) and :func:`sqp_direction`
(a Newton step on the KKT conditions of the active constraints, the continuous strategy's local
refinement).

Violation is the CEC2006 total (see :func:`eaco_jax.problems.constrained.violation_of`:
inequality excess plus equality excess beyond |h| <= 1e-4), so ``violation == 0`` is feasible.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from eaco_jax.errors import ConfigError

Array = jax.Array

METHODS = ("epsilon", "deb", "penalty")


def check_method(method: str) -> str:
    """``method`` if known, else a ValueError naming the choices."""
    if method not in METHODS:
        raise ConfigError(f"unknown constraint method {method!r}; choose one of {METHODS}")
    return method


def sort_keys(f: Array, violation: Array, method: str, epsilon: Array = 0.0,
              penalty: Array = 0.3) -> tuple[Array, Array]:
    """``(primary, secondary)`` keys: a is better than b iff (p_a, s_a) < (p_b, s_b) lexically.

    * penalty: ``(f + PEN * v, 0)``
    * deb: ``(v, f)`` - v == 0 for feasible, so feasible < infeasible, ties broken by f
    * epsilon: ``(v if v > eps else 0, f)``
    """
    check_method(method)
    f = jnp.where(jnp.isnan(f), jnp.inf, f)
    violation = jnp.where(jnp.isnan(violation), jnp.inf, violation)
    if method == "penalty":
        return f + penalty * violation, jnp.zeros_like(f)
    if method == "deb":
        return violation, f
    return jnp.where(violation <= epsilon, jnp.zeros_like(violation), violation), f


def better(f_a: Array, v_a: Array, f_b: Array, v_b: Array, method: str,
           epsilon: Array = 0.0, penalty: Array = 0.3) -> Array:
    """True where solution a is strictly better than solution b under ``method``."""
    pa, sa = sort_keys(f_a, v_a, method, epsilon, penalty)
    pb, sb = sort_keys(f_b, v_b, method, epsilon, penalty)
    return (pa < pb) | ((pa == pb) & (sa < sb))


def rank_order(f: Array, violation: Array, method: str, epsilon: Array = 0.0,
               penalty: Array = 0.3) -> Array:
    """Indices that sort solutions best first (stable)."""
    primary, secondary = sort_keys(f, violation, method, epsilon, penalty)
    return jnp.lexsort((secondary, primary))


def epsilon_schedule(iteration: Array, epsilon0: Array, cutoff: Array,
                     exponent: Array) -> Array:
    """Takahama & Sakai's epsilon level: eps0 * (1 - t/Tc)^cp for t < Tc, then 0."""
    t = jnp.asarray(iteration, jnp.float32)
    frac = jnp.clip(1.0 - t / jnp.maximum(cutoff, 1.0), 0.0, 1.0)
    return jnp.where(t < cutoff, epsilon0 * frac**exponent, 0.0)


def initial_epsilon(violation: Array, fraction: Array) -> Array:
    """eps(0): the violation of the solution at quantile ``fraction`` of the first colony."""
    v = jnp.sort(jnp.where(jnp.isfinite(violation), violation, jnp.inf))
    i = jnp.clip(jnp.floor(fraction * (v.shape[0] - 1)).astype(jnp.int32), 0, v.shape[0] - 1)
    finite_max = jnp.max(jnp.where(jnp.isfinite(v), v, 0.0))
    return jnp.where(jnp.isfinite(v[i]), v[i], finite_max)


# --------------------------------------------------------------------------- gradient repair
def min_norm_solve(jac: Array, c: Array, ridge: float = 1e-12) -> Array:
    """Minimum-norm d with ``jac @ d = c`` (zero rows ignored): J^T (J J^T + ridge I)^-1 c.

    Rows are normalised first (the min-norm solution does not change for full row rank), so
    the tiny ridge only matters for dependent rows. An LU solve of the small (rows x rows)
    system compiles far faster than the SVD behind ``pinv``.
    """
    norms = jnp.linalg.norm(jac, axis=1)
    inv = jnp.where(norms > 0, 1.0 / jnp.where(norms > 0, norms, 1.0), 0.0)
    jn = jac * inv[:, None]
    gram = jn @ jn.T + ridge * jnp.eye(jac.shape[0], dtype=jac.dtype)
    gram = gram + jnp.diag(jnp.where(norms > 0, 0.0, 1.0))
    return jn.T @ jnp.linalg.solve(gram, c * inv)


def repair_step(problem: object, x: Array, margin: Array) -> Array:
    """One Newton step towards the violated constraints' boundary (min-norm, pseudo-inverse).

    The rows are the violated inequalities (target g_i = -margin * |grad g_i|, a hair inside,
    so a converged ant is feasible, not 1e-12 outside) and all equalities (target h = 0):
    ``x + J^+ (target - c)``, clipped to the box. This is the gradient-based mutation of the
    epsilon-DE (Takahama & Sakai 2006) with the Jacobian from ``jax.jacobian`` instead of
    finite differences.
    """
    g, h = problem.constraints(x)
    jg, jh = jax.jacobian(problem.constraints)(x)
    norm_g = jnp.linalg.norm(jg, axis=1)
    resid_g = g + margin * norm_g
    rows_g = resid_g > 0
    c = jnp.concatenate([jnp.where(rows_g, resid_g, 0.0), h])
    jac = jnp.concatenate([jnp.where(rows_g[:, None], jg, 0.0), jh], axis=0)
    step = -min_norm_solve(jac, c)
    step = jnp.where(jnp.all(jnp.isfinite(step)), step, 0.0)
    return jnp.clip(x + step, problem.lower, problem.upper)


def gradient_repair(problem: object, x: Array, steps: int, margin: Array,
                    enabled: Array = True) -> tuple[Array, Array]:
    """Up to ``steps`` repair steps on one ant while it is infeasible.

    Returns the repaired ant and the number of steps taken (each evaluates the constraints and
    their Jacobian at a new point; the strategy charges one evaluation per step).
    """
    if problem.num_inequality + problem.num_equality == 0 or steps <= 0:
        return x, jnp.zeros((), jnp.int32)

    def body(_: int, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        y, n = carry
        todo = enabled & (problem.violation_one(y) > 0)
        y = jnp.where(todo, repair_step(problem, y, margin), y)
        return y, n + todo.astype(jnp.int32)

    return jax.lax.fori_loop(0, steps, body, (x, jnp.zeros((), jnp.int32)))


# --------------------------------------------------------------------------- SQP refinement
def sqp_direction(problem: object, x: Array, active_frac: Array,
                  margin_frac: Array) -> Array:
    """Newton (SQP) step on the KKT conditions of the constraints active at ``x``.

    Active set: all equalities, inequalities and box bounds within ``active_frac`` of the mean
    box width (first-order distance |c| / |grad c|), minus inequalities whose least-squares
    multiplier is negative. With ``J`` their Jacobian, ``P`` the projector on its null space and
    ``H`` the Lagrangian Hessian, the step is ``d = d_r + P z`` where ``d_r = -J^+ c`` restores
    the active constraints (min-norm, via the row-normalised normal equations) and ``z``
    solves the reduced Newton system ``P H P z = -P (grad f + H d_r)`` with negative curvature
    flipped (|eigenvalues|) so it is a descent step.
    """
    n = problem.dim
    dtype = x.dtype
    eye = jnp.eye(n, dtype=dtype)
    lo, hi = problem.lower, problem.upper
    scale = jnp.mean(hi - lo)
    gf = jax.grad(lambda y: jnp.asarray(problem.objective(y), dtype).reshape(()))(x)
    hf = jax.hessian(lambda y: jnp.asarray(problem.objective(y), dtype).reshape(()))(x)
    g, h = problem.constraints(x)
    jg, jh = jax.jacobian(problem.constraints)(x)
    hg, hh = jax.hessian(problem.constraints)(x)
    ng = jnp.linalg.norm(jg, axis=1)
    p, q = problem.num_inequality, problem.num_equality
    c = jnp.concatenate([g + margin_frac * scale * ng, h, x - hi, lo - x])
    jac = jnp.concatenate([jg, jh, eye, -eye], axis=0)
    raw = jnp.concatenate([g, h, x - hi, lo - x])
    norms = jnp.linalg.norm(jac, axis=1)
    is_eq = jnp.concatenate([jnp.zeros(p, bool), jnp.ones(q, bool), jnp.zeros(2 * n, bool)])
    near = raw >= -active_frac * scale * jnp.maximum(norms, 1e-30)
    near = near & (norms > 0)
    # a variable cannot sit on both bounds: keep the nearer one (fixed variables have lo == hi)
    up_closer = (hi - x) <= (x - lo)
    near = near.at[p + q: p + q + n].set(near[p + q: p + q + n] & up_closer)
    near = near.at[p + q + n:].set(near[p + q + n:] & ~up_closer)
    active0 = is_eq | near

    def normal_matrix(active: Array) -> tuple[Array, Array, Array]:
        """Row-normalised active Jacobian ``jn``, the row scales, and (jn jn^T + ridge)^-1."""
        inv = jnp.where(active, 1.0 / jnp.maximum(norms, 1e-300), 0.0)
        jn = jac * inv[:, None]
        gram = jn @ jn.T + 1e-12 * jnp.eye(jac.shape[0], dtype=dtype)
        gram = gram + jnp.diag(jnp.where(active, 0.0, 1.0))
        return jn, inv, jnp.linalg.inv(gram)

    # least-squares multipliers: grad f + J^T lam = 0  ->  lam = -(J J^T)^-1 J grad f
    jn, inv, ginv = normal_matrix(active0)
    lam0 = -(ginv @ (jn @ gf)) * inv
    active = active0 & (is_eq | (lam0 >= 0))
    jn, inv, ginv = normal_matrix(active)
    lam = jnp.where(active, -(ginv @ (jn @ gf)) * inv, 0.0)
    hl = hf
    if p:
        hl = hl + jnp.einsum("i,ijk->jk", lam[:p], hg)
    if q:
        hl = hl + jnp.einsum("i,ijk->jk", lam[p:p + q], hh)
    proj = eye - jn.T @ ginv @ jn
    d_r = -jn.T @ (ginv @ (c * inv))
    rhs = -proj @ (gf + hl @ d_r)
    mat = proj @ hl @ proj + (eye - proj)
    mat = 0.5 * (mat + mat.T)
    w, vecs = jnp.linalg.eigh(mat)
    floor = 1e-10 * jnp.max(jnp.abs(w)) + jnp.finfo(dtype).tiny
    z = vecs @ ((vecs.T @ rhs) / jnp.maximum(jnp.abs(w), floor))
    d = d_r + proj @ z
    return jnp.where(jnp.all(jnp.isfinite(d)), d, jnp.zeros_like(d))

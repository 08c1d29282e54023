"""External peers at equal evaluations: evosax's CMA-ES, DE and PSO on G1-G4 (issue 14).

A benchmark extra, not a dependency of the library: ``pip install evosax`` (0.3.2 measured).
Each peer gets the same problems (``eaco_jax.problems.cec2006``, float64), the same budget of
evaluations, 25 seeds vmapped, and a constraint handling in the spirit of ours: Deb's
feasibility rule as a scalar per generation (a feasible point scores f, an infeasible one the
worst feasible f of its generation plus its violation, so it ranks below every feasible one;
equalities count as met at |h| <= 1e-4, as in CEC2006). evosax searches without bounds:
points are mapped into the box by clipping (CMA-ES searches the unit cube, mean 0.5, step
0.3). Success = feasible and f - f* <= 1e-4 within the budget. Beside them: derivative-free
ContinuousEACO at the same budget and seeds (``results/ablation_constrained.json``, cell
"default (derivative-free)").

    python experiments/evosax_peers.py                    # 25 seeds, 100,000 evaluations
    python experiments/evosax_peers.py --seeds 4 --budget 4000 --problems g01   # smoke

Writes ``results/evosax_peers.{json,csv}``.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import common as st
import jax
import jax.numpy as jnp
import numpy as np

import eaco_jax as ea  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
PAPER_NAME = {"g01": "G1", "g10": "G2", "g09": "G3", "g13": "G4"}


def deb_scalar(f: jax.Array, v: jax.Array) -> jax.Array:
    """Deb's rule as one number per point of a generation (lower is better)."""
    feasible = v <= 0
    worst = jnp.where(feasible.any(), jnp.max(jnp.where(feasible, f, -jnp.inf)), jnp.max(f))
    return jnp.where(feasible, f, worst + v)


def run_peer(name: str, problem, seeds: list[int], budget: int, pop: int) -> dict:
    """All seeds of one peer on one problem as one jitted, vmapped scan."""
    from evosax.algorithms import CMA_ES, PSO, DifferentialEvolution

    lo, hi = jnp.asarray(problem.lower), jnp.asarray(problem.upper)
    n = lo.shape[0]
    gens = budget // pop
    f_star = problem.f_star

    def to_box(z):  # CMA-ES searches the unit cube; the others the box itself
        return lo + (hi - lo) * jnp.clip(z, 0.0, 1.0) if name == "cma_es" else jnp.clip(z, lo, hi)

    def evaluate(z):
        e = problem.evaluate(to_box(z))  # the library's own evaluation (f, total violation)
        return e.f, e.violation

    dummy = jnp.zeros(n)
    if name == "cma_es":
        es = CMA_ES(population_size=pop, solution=dummy)
    elif name == "de":
        es = DifferentialEvolution(population_size=pop, solution=dummy)
    else:
        es = PSO(population_size=pop, solution=dummy)
    params = es.default_params
    if name == "cma_es":
        params = params.replace(std_init=0.3)

    def one(key):
        k0, k1, key = jax.random.split(key, 3)
        if name == "cma_es":
            state = es.init(k0, jnp.full((n,), 0.5), params)
            used = 0
            best = (jnp.inf, jnp.inf)
        else:
            x0 = lo + (hi - lo) * jax.random.uniform(k1, (pop, n), lo.dtype)
            f0, v0 = evaluate(x0)
            state = es.init(k0, x0, deb_scalar(f0, v0), params)
            used = pop
            ok = v0 <= 0
            best = (jnp.min(jnp.where(ok, f0, jnp.inf)), jnp.min(v0))
        hit0 = jnp.where(best[0] - f_star <= 1e-4, used, -1)

        def gen(carry, k):
            state, best_f, best_v, hit, used = carry
            ka, kt = jax.random.split(k)
            x, state = es.ask(ka, state, params)
            f, v = evaluate(x)
            state, _ = es.tell(kt, x, deb_scalar(f, v), state, params)
            used = used + pop
            best_f = jnp.minimum(best_f, jnp.min(jnp.where(v <= 0, f, jnp.inf)))
            best_v = jnp.minimum(best_v, jnp.min(v))
            hit = jnp.where((hit < 0) & (best_f - f_star <= 1e-4), used, hit)
            return (state, best_f, best_v, hit, used), None

        n_gens = gens - (0 if name == "cma_es" else 1)
        carry = (state, best[0], best[1], hit0, jnp.int32(used))
        (state, best_f, best_v, hit, used), _ = jax.lax.scan(
            gen, carry, jax.random.split(key, n_gens))
        return best_f, best_v, hit

    keys = jnp.stack([jax.random.key(s) for s in seeds])
    t0 = time.perf_counter()
    best_f, best_v, hit = jax.jit(jax.vmap(one))(keys)
    best_f, best_v, hit = (np.asarray(a) for a in (best_f, best_v, hit))
    seconds = time.perf_counter() - t0
    err = np.where(np.isfinite(best_f), np.maximum(best_f - f_star, 0.0), np.inf)
    ok = hit >= 0
    return dict(peer=name, population=pop, budget=budget, seeds=len(seeds),
                success_rate=float(ok.mean()),
                success_performance=st.success_performance(np.where(ok, hit, -1)),
                feasible_rate=float(np.mean(np.isfinite(best_f))),
                **{f"error_{k}": v for k, v in st.summary(err).items()},
                seconds_with_compile=seconds, final_errors=[
                    float(e) if np.isfinite(e) else None for e in err])


def eaco_row(problem: str) -> dict | None:
    path = RESULTS / "ablation_constrained.json"
    if not path.exists():
        return None
    for r in json.loads(path.read_text())["rows"]:
        if r["problem"] == problem and r["cell"] == "default (derivative-free)":
            return r
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="g01,g09,g10,g13")
    ap.add_argument("--peers", default="cma_es,de,pso")
    ap.add_argument("--seeds", type=int, default=25)
    ap.add_argument("--budget", type=int, default=100_000)
    ap.add_argument("--population", type=int, default=40)
    ap.add_argument("--out", type=Path, default=RESULTS / "evosax_peers.json")
    args = ap.parse_args()
    import evosax  # noqa: F401 - fail early with a clear message if it is missing

    seeds = list(range(args.seeds))
    rows = []
    print(f"{'problem':>8} {'peer':>8} {'success':>8} {'SP':>10} {'error mean':>12} "
          f"{'feasible':>8} {'s':>6}")
    for name in args.problems.split(","):
        with ea.problems.float64():
            problem = ea.problems.cec2006(name)
            for peer in args.peers.split(","):
                r = run_peer(peer, problem, seeds, args.budget, args.population)
                r.update(problem=name, paper_name=PAPER_NAME.get(name))
                e = eaco_row(name)
                if e is not None and e.get("budget") == args.budget:
                    ours = [x if x is not None else np.inf for x in e["final_errors"]]
                    theirs = [x if x is not None else np.inf for x in r["final_errors"]]
                    n = min(len(ours), len(theirs))
                    r["eaco_df_success_rate"] = e["success_rate"]
                    r["eaco_df_error_mean"] = e["error_mean"]
                    r["p_vs_eaco_df"] = st.paired_test(theirs[:n], ours[:n])
                rows.append(r)
                print(f"{name:>8} {peer:>8} {r['success_rate']:8.2f} "
                      f"{r['success_performance'] or float('nan'):10.0f} "
                      f"{r['error_mean']:12.4g} {r['feasible_rate']:8.2f} "
                      f"{r['seconds_with_compile']:6.1f}", flush=True)
    meta = dict(vars(args), out=str(args.out), device=str(jax.devices()[0]),
                jax=jax.__version__, evosax=__import__("importlib.metadata").metadata
                .version("evosax"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1, default=float) + "\n")
    keys = [k for k in rows[0] if k != "final_errors"]
    with args.out.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

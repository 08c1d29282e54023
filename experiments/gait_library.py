"""A NAO gait library by MAP-Elites, against QDax's MAP-Elites at equal evaluations.

Two parts, each 10 optimisation seeds (0-9 by default) per arm, every arm the same batch size,
iterations, grid and evaluations (QDax's initial population counts: its ``init`` evaluates one
batch, then ``iterations - 1`` updates; ours starts from an empty archive whose first batch is
uniform, then ``iterations - 1`` more):

* ``toy``: Rastrigin-proj (``eaco_jax.problems.qd``, 8-D, 2-D folded descriptor, grid 20 x 20),
  arms ``eaco`` (``map-elites-eaco``: the colony's kernel), ``isoline`` (``map-elites``: our
  Iso+LineDD) and ``qdax`` (QDax 0.5.0 ``MAPElites`` + ``MixingEmitter`` with
  ``isoline_variation``, the same iso/line widths). Cheap; it checks that our iso-line matches
  QDax's, and what the kernel adds.
* ``gait``: the gait-library problem (``eaco_jax.problems.gait_library``): the NAO walk engine's
  14 parameters; fitness = fraction of the ``--worlds`` optimisation-stream worlds without a
  fall, + the forward speed if none fell; descriptors = measured forward speed (m/s) and yaw
  rate (deg/s) on a ``--grid`` over ``--speed-range`` x ``--yaw-range``. Arms ``eaco`` and
  ``qdax`` (``--gait-arms`` adds ``isoline``). Then every filled cell's gait of every run walks
  ``--test-worlds`` randomised worlds of the TEST stream of its seed (nothing in the search saw
  them): per-cell fall rates, and where the gait's measured behaviour lands on the grid again.

Both methods evaluate through the same ``problem.evaluate`` (QDax's genotype is the box
normalised to [0, 1], its scoring function maps it back); QDax's evaluations draw their worlds
from the same optimisation stream (``optimisation_key``) of its seed. Coverage and QD score are
computed by the same function on both archives; QDax's own metrics are recorded beside as a
check. Means with 95 % bootstrap CIs (``common.summary``) and Wilcoxon signed-rank p-values
between arms (seed-paired).

CPU (the default): about 20 min of one core (native MuJoCo with the motor limits in the
physics; 3 s horizon, 2 worlds, 16 x 24 evaluations per run, 6 test worlds per cell). A GPU:
``--device-scale 8`` multiplies the batch and the test worlds (and ``--backend mjx``,
``--iterations``, ``--worlds``, ``--horizon`` as wished).

    .venv/bin/pip install --no-deps --target .qdax qdax==0.5.0 scikit-learn joblib \\
        threadpoolctl cloudpickle narwhals          # QDax beside the venv, nothing else touched
    python experiments/gait_library.py                          # toy + gait, seeds 0-9
    python experiments/gait_library.py --parts toy --seeds 100-104 --rho 1.0   # selection

Writes ``results/gait_library/gait_library.json`` (rows, tables), ``library_seed0.json`` (the
eaco arm's seed-0 library: each cell's gait, measures and test fall rate) and
``gait_library_map.png`` / ``toy_coverage.png``.
"""

from __future__ import annotations

import argparse
import datetime
import functools
import json
import sys
import time
from pathlib import Path

import common as st
import jax
import jax.numpy as jnp
import numpy as np

import eaco_jax as ea
from eaco_jax.gait.steer import Steering
from eaco_jax.gait.worlds import RobustConfig
from eaco_jax.problems.gait_library import make_gait_library_problem, validate
from eaco_jax.problems.qd import rastrigin_proj
from eaco_jax.strategies.map_elites import MAPElites, MAPElitesParams, archive_metrics

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results" / "gait_library"
QDAX_DIR = ROOT / ".qdax"


def parse_seeds(text: str) -> list[int]:
    """``"0-9"`` or ``"1,2,5"``."""
    if "-" in text and "," not in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def import_qdax():
    """QDax's MAP-Elites pieces: ``pip install '.[qd]'``, or QDax installed with --no-deps in
    ``.qdax`` and that folder on ``PYTHONPATH`` (``PYTHONPATH=.qdax python ...``)."""
    try:
        import qdax
        from qdax.core.containers.mapelites_repertoire import compute_euclidean_centroids
        from qdax.core.emitters.mutation_operators import isoline_variation
        from qdax.core.emitters.standard_emitters import MixingEmitter
        from qdax.core.map_elites import MAPElites as QDaxMAPElites
        from qdax.utils.metrics import default_qd_metrics
    except ImportError as err:
        raise SystemExit(f"QDax does not import ({err}): pip install '.[qd]', or install it "
                         "beside the venv (.venv/bin/pip install --no-deps --target .qdax "
                         "qdax==0.5.0 scikit-learn joblib threadpoolctl cloudpickle narwhals) "
                         "and run with PYTHONPATH=.qdax") from None
    return dict(version=qdax.__version__ if hasattr(qdax, "__version__") else "0.5.0",
                centroids=compute_euclidean_centroids, isoline=isoline_variation,
                emitter=MixingEmitter, MAPElites=QDaxMAPElites, metrics=default_qd_metrics)


# --------------------------------------------------------------------------- runs
def run_ours(problem, variation: str, grid, ants: int, iterations: int, seeds: list[int],
             params: MAPElitesParams) -> tuple[list[dict], object, MAPElites]:
    """All seeds vmapped through ``ea.minimize``; per seed the archive's metrics."""
    s = MAPElites(num_ants=ants, grid=tuple(grid), variation=variation)
    t0 = time.perf_counter()
    res = ea.minimize(problem, s, seed=seeds, iterations=iterations, params=params)
    wall = time.perf_counter() - t0
    state = res.state
    if len(seeds) == 1:  # minimize returns one seed's state unbatched
        state = jax.tree.map(lambda a: a[None], state)
    cost, evals = np.asarray(state.archive_cost), np.asarray(state.evaluations)
    rows = []
    for i, seed in enumerate(seeds):
        m = {k: float(v) for k, v in archive_metrics(jnp.asarray(cost[i]),
                                                     float(problem.qd_offset)).items()}
        rows.append({"seed": seed, "evaluations": int(evals[i]),
                     **m, "wall_s_all_seeds": wall,
                     "compile_s": float(res.compile_seconds)})
    return rows, state, s


def run_qdax(qd, problem, grid, ants: int, iterations: int, seeds: list[int],
             params: MAPElitesParams, vmapped: bool = False) -> tuple[list[dict], list[dict]]:
    """QDax's MAP-Elites per seed (one compiled scan, reused): genotypes in [0, 1]^n, the
    problem's evaluate on the box point; per seed the archive's metrics (ours and QDax's).
    ``vmapped``: all seeds in one vmapped call, as ``minimize`` runs ours (a GPU would
    otherwise run QDax's seeds one small batch at a time); the same keys, so the same runs."""
    vmapped = vmapped and len(seeds) > 1
    if vmapped and hasattr(problem, "for_rows"):
        problem = problem.for_rows(len(seeds))
    lo, hi = problem.lower, problem.upper
    stochastic = getattr(problem, "stochastic", False)

    def scoring(genotypes, key):
        x = lo + genotypes * (hi - lo)
        if stochastic:
            ev = problem.evaluate(x, key=key)
        else:
            ev = problem.evaluate(x)
        fit = jnp.where(jnp.isfinite(ev.f), -ev.f, -jnp.inf)
        return fit, ev.descriptors, {}

    variation = functools.partial(qd["isoline"], iso_sigma=float(params.iso_sigma),
                                  line_sigma=float(params.line_sigma), minval=0.0, maxval=1.0)
    emitter = qd["emitter"](mutation_fn=None, variation_fn=variation, variation_percentage=1.0,
                            batch_size=ants)
    offset = float(problem.qd_offset)
    algo = qd["MAPElites"](scoring_function=scoring, emitter=emitter,
                           metrics_function=functools.partial(qd["metrics"], qd_offset=offset))
    centroids = qd["centroids"](grid_shape=tuple(grid),
                                minval=[float(v) for v in problem.descriptor_lower],
                                maxval=[float(v) for v in problem.descriptor_upper])

    @jax.jit
    def run(key):
        k_init, k_pop, k_loop = jax.random.split(key, 3)
        pop = jax.random.uniform(k_pop, (ants, problem.dim), problem.dtype)
        rep, est, _ = algo.init(pop, centroids, k_init)
        (rep, est, _), _ = jax.lax.scan(algo.scan_update, (rep, est, k_loop), None,
                                        length=iterations - 1)
        return rep

    rows, reps = [], []
    t0 = time.perf_counter()
    # the worlds come from the optimisation stream of the problem's seed, folded with QDax's
    # per-call key (problem.evaluate), as the driver's key picks ours
    if vmapped:
        keys = jnp.stack([jax.random.PRNGKey(seed) for seed in seeds])
        batch = jax.jit(jax.vmap(run))(keys)
        per_seed = [jax.tree.map(lambda a, i=i: a[i], batch) for i in range(len(seeds))]
    else:
        per_seed = (run(jax.random.PRNGKey(seed)) for seed in seeds)
    for seed, rep in zip(seeds, per_seed, strict=True):
        fit = np.asarray(rep.fitnesses).reshape(-1)
        cost = np.where(np.isfinite(fit), -fit, np.inf)
        m = {k: float(v) for k, v in archive_metrics(jnp.asarray(cost), offset).items()}
        qm = qd["metrics"](rep, offset)
        x = lo + np.asarray(rep.genotypes) * (hi - lo)
        rows.append({"seed": seed, "evaluations": ants * iterations, **m,
                     "qdax_coverage_percent": float(qm["coverage"]),
                     "qdax_qd_score": float(qm["qd_score"])})
        reps.append({"cost": cost, "x": np.asarray(x),
                     "descriptor": np.asarray(rep.descriptors),
                     "centroids": np.asarray(centroids)})
    wall = time.perf_counter() - t0
    for r in rows:
        r["wall_s_all_seeds"] = wall
    return rows, reps


def compare(rows: dict[str, list[dict]], metrics=("coverage", "qd_score", "max_fitness")
            ) -> dict:
    """Per arm and metric: summary (mean, 95 % CI, ...); p-values of eaco vs every other arm."""
    out: dict = {}
    for arm, rs in rows.items():
        out[arm] = {k: st.summary([r[k] for r in rs]) for k in metrics}
    if "eaco" in rows:
        for arm in rows:
            if arm == "eaco":
                continue
            out[f"eaco_vs_{arm}_p"] = {k: st.paired_test([r[k] for r in rows["eaco"]],
                                                         [r[k] for r in rows[arm]])
                                       for k in metrics}
    return out


def table(title: str, cmp: dict, arms) -> str:
    lines = [title, f"{'arm':10s} {'coverage':>22s} {'QD score':>30s} {'max fitness':>12s}"]
    for arm in arms:
        c, q, f = (cmp[arm][k] for k in ("coverage", "qd_score", "max_fitness"))
        lines.append(f"{arm:10s} {c['mean']:8.3f} [{c['ci_low']:.3f}, {c['ci_high']:.3f}] "
                     f"{q['mean']:12.2f} [{q['ci_low']:.1f}, {q['ci_high']:.1f}] "
                     f"{f['mean']:12.3f}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- parts
def part_toy(args, qd, params) -> dict:
    prob = rastrigin_proj(args.toy_dim)
    grid = (args.toy_grid, args.toy_grid)
    rows: dict[str, list[dict]] = {}
    for arm in ("eaco", "isoline"):
        rows[arm], _, _ = run_ours(prob, arm, grid, args.toy_ants, args.toy_iterations,
                                   args.seeds, params)
    rows["qdax"], _ = run_qdax(qd, prob, grid, args.toy_ants, args.toy_iterations, args.seeds,
                               params, vmapped=args.qdax_vmap)
    cmp = compare(rows)
    print(table(f"toy: rastrigin-proj {args.toy_dim}-D, grid {grid}, "
                f"{args.toy_ants * args.toy_iterations} evaluations, seeds {args.seeds}",
                cmp, rows))
    return {"problem": "rastrigin-proj", "dim": args.toy_dim, "grid": list(grid),
            "ants": args.toy_ants, "iterations": args.toy_iterations,
            "evaluations": args.toy_ants * args.toy_iterations, "rows": rows, "summary": cmp}


def cell_of(desc: np.ndarray, lo: np.ndarray, hi: np.ndarray, grid) -> np.ndarray:
    """Grid coordinates ``(k, d)`` of descriptors (outside: the border), as MAPElites does."""
    u = np.where(np.isfinite(desc), (desc - lo) / (hi - lo), 0.0)
    return np.clip(np.floor(u * np.asarray(grid)).astype(int), 0, np.asarray(grid) - 1)


def library_problem(args):
    """The gait-library problem of the flags: ``--constrained`` under the motor constraints;
    ``--init GAIT`` narrows the box around a stored gait (``eaco gait --init``'s +/-15 % of
    each range) except the ``--free`` parameters, which keep their whole range (the commands
    a cell asks for: step length, direction, turn rate)."""
    robust = None
    if args.target_noise is not None and args.worlds > 0:
        robust = RobustConfig(R=args.worlds, aggregate="mean", seed=0,
                              target_noise=args.target_noise)
    prob = make_gait_library_problem(
        backend=args.backend, horizon=args.horizon, worlds=args.worlds, seed=0,
        speed_range=tuple(args.speed_range), yaw_range=tuple(args.yaw_range),
        constrained=args.constrained, robust=robust,
        steering=Steering(track_turn=True) if args.track_turn else None)
    if args.init is None:
        return prob
    from eaco_jax.runs.gait import narrowed_around

    narrow, _ = narrowed_around(prob.gait, args.init)
    names = prob.gait.param_names
    unknown = [n for n in args.free if n not in names]
    if unknown:
        raise SystemExit(f"--free {' '.join(unknown)}: not a parameter of the walk engine "
                         f"({', '.join(names)})")
    keep = np.asarray([n in args.free for n in names])
    lo = np.where(keep, np.asarray(prob.gait.lower), np.asarray(narrow.lower))
    hi = np.where(keep, np.asarray(prob.gait.upper), np.asarray(narrow.upper))
    return prob.replace(gait=prob.gait.replace(lower=jnp.asarray(lo, jnp.float32),
                                               upper=jnp.asarray(hi, jnp.float32)))


def part_gait(args, qd, params) -> tuple[dict, dict]:
    prob = library_problem(args)
    grid = tuple(args.grid)
    lo = np.asarray(prob.descriptor_lower, np.float64)
    hi = np.asarray(prob.descriptor_upper, np.float64)
    rows: dict[str, list[dict]] = {}
    archives: dict[str, list[dict]] = {}
    timings: dict[str, float] = {}
    for arm in args.gait_arms:
        t0 = time.perf_counter()
        if arm == "qdax":
            rows[arm], archives[arm] = run_qdax(qd, prob, grid, args.ants, args.iterations,
                                                args.seeds, params, vmapped=args.qdax_vmap)
        else:
            rows[arm], state, s = run_ours(prob, arm, grid, args.ants, args.iterations,
                                           args.seeds, params)
            archives[arm] = []
            for i in range(len(args.seeds)):
                one = jax.tree.map(lambda a, i=i: a[i], state)
                lib = s.library(one, prob)
                cost = np.full(s.num_cells, np.inf)
                cost[lib["cell"]] = lib["cost"]
                archives[arm].append({"cost": cost, "x": np.asarray(one.archive_x),
                                      "descriptor": np.asarray(one.archive_desc)})
        timings[arm] = time.perf_counter() - t0
        print(f"  {arm}: {timings[arm]:.0f} s", flush=True)
    cmp = compare(rows)
    print(table(f"gait library: NAO, {args.horizon:g} s, {args.worlds} worlds, grid {grid}, "
                f"{args.ants * args.iterations} evaluations, seeds {args.seeds}", cmp, rows))

    # validation on the TEST stream: every filled cell of every run
    t0 = time.perf_counter()
    per_cell: dict[str, dict] = {}
    libraries: list[dict] = []
    for arm, archs in archives.items():
        falls = np.full((len(args.seeds),) + grid, np.nan)
        speed = np.full((len(args.seeds),) + grid, np.nan)
        same_cell, n_cells = 0, 0
        for i, (seed, a) in enumerate(zip(args.seeds, archs, strict=True)):
            filled = np.flatnonzero(np.isfinite(a["cost"]))
            if filled.size == 0:
                continue
            # the cell an elite sits in: its own descriptor's (QDax keeps centroid order)
            home = cell_of(a["descriptor"][filled], lo, hi, grid)
            v = validate(prob, a["x"][filled], trials=args.test_worlds, seed=seed,
                         chunk=args.validate_chunk)
            test_desc = np.stack([v["forward_mps"], v["turn_deg_s"]], -1)
            again = cell_of(test_desc, lo, hi, grid)
            same_cell += int(np.sum(np.all(again == home, axis=1)))
            n_cells += filled.size
            idx = tuple(home.T)
            falls[(i,) + idx] = v["fall_rate"]
            speed[(i,) + idx] = v["forward_mps"]
            rows[arm][i]["test_fall_rate_mean"] = float(np.mean(v["fall_rate"]))
            rows[arm][i]["test_cells_never_fell"] = int(np.sum(v["fall_rate"] == 0))
            if prob.constrained:
                rows[arm][i]["test_cells_feasible"] = int(np.sum(v["violation"] <= 0))
            if arm == "eaco":  # every run's library, for a controller to draw on
                libraries.append({"seed": seed, "cells": [
                    {"coords": home[j].tolist(), "params": prob.gait.params_dict(a["x"][f]),
                     "fitness": float(-a["cost"][f]),
                     "search_descriptor": a["descriptor"][f].tolist(),
                     "test_fall_rate": float(v["fall_rate"][j]),
                     "test_forward_mps": float(v["forward_mps"][j]),
                     "test_turn_deg_s": float(v["turn_deg_s"][j]),
                     "test_lateral_mps": float(v["lateral_mps"][j]),
                     **({"test_violation": float(v["violation"][j]),
                         **{f"test_{k}_worst": float(v[f"{k}_worst"][j])
                            for k in prob.constraint_names}} if prob.constrained else {})}
                    for j, f in enumerate(filled)]})
        with np.errstate(all="ignore"):
            pooled = np.nanmean(falls, axis=0)
            filled_by = np.sum(np.isfinite(falls), axis=0)
        per_cell[arm] = {"fall_rate_mean_over_seeds": np.where(filled_by > 0, pooled,
                                                               np.nan).tolist(),
                         "seeds_filling": filled_by.tolist(),
                         "test_speed_seed0": speed[0].tolist(),
                         "test_fall_rate_seed0": falls[0].tolist(),
                         "cells_validated": n_cells,
                         "same_cell_in_test_worlds": same_cell / max(n_cells, 1)}
        print(f"  {arm}: {n_cells} cells on {args.test_worlds} test worlds each: mean fall "
              f"rate {np.nanmean(falls):.3f}, never fell "
              f"{np.mean([r['test_cells_never_fell'] for r in rows[arm]]):.1f} cells/run, "
              f"same cell in the test worlds {per_cell[arm]['same_cell_in_test_worlds']:.2f}",
              flush=True)
    timings["validation"] = time.perf_counter() - t0
    for arm in rows:
        cmp[arm]["test_fall_rate_mean"] = st.summary(
            [r.get("test_fall_rate_mean", np.nan) for r in rows[arm]])
        cmp[arm]["test_cells_never_fell"] = st.summary(
            [r.get("test_cells_never_fell", np.nan) for r in rows[arm]])
        if prob.constrained:
            cmp[arm]["test_cells_feasible"] = st.summary(
                [r.get("test_cells_feasible", np.nan) for r in rows[arm]])
    out = {"problem": prob.name, "backend": prob.gait.backend, "horizon_s": args.horizon,
           "constrained": prob.constrained, "init": None if args.init is None else str(args.init),
           "steering": (prob.gait.steering.record() if prob.gait.steering is not None
                        else None),
           "target_noise": (prob.gait.robust.target_noise if prob.gait.robust is not None
                            else None),
           "free": list(args.free) if args.init is not None else None,
           "worlds": args.worlds, "test_worlds": args.test_worlds, "grid": list(grid),
           "speed_range": list(args.speed_range), "yaw_range": list(args.yaw_range),
           "ants": args.ants, "iterations": args.iterations,
           "evaluations": args.ants * args.iterations,
           "rollouts_per_run": args.ants * args.iterations * max(args.worlds, 1),
           "rows": rows, "summary": cmp, "per_cell": per_cell, "seconds": timings}
    return out, libraries


def plot_maps(gait: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    arms = list(gait["per_cell"])
    fig, axes = plt.subplots(len(arms), 2, figsize=(10, 3.6 * len(arms)), squeeze=False)
    s_lo, s_hi = gait["speed_range"]
    y_lo, y_hi = gait["yaw_range"]
    ext = (y_lo, y_hi, s_lo, s_hi)
    for r, arm in enumerate(arms):
        pc = gait["per_cell"][arm]
        for c, (key, label, cmap, vmin, vmax) in enumerate((
                ("test_speed_seed0", "forward speed in test worlds [m/s]", "viridis", s_lo,
                 s_hi),
                ("test_fall_rate_seed0", "fall rate in test worlds", "Reds", 0.0, 1.0))):
            ax = axes[r, c]
            im = ax.imshow(np.asarray(pc[key], float), origin="lower", aspect="auto",
                           extent=ext, cmap=cmap, vmin=vmin, vmax=vmax)
            fig.colorbar(im, ax=ax, label=label)
            ax.set_xlabel("yaw rate [deg/s] (cell)")
            ax.set_ylabel("forward speed [m/s] (cell)")
            ax.set_title(f"{arm}, seed {gait['rows'][arm][0]['seed']}: "
                         f"{np.isfinite(np.asarray(pc[key], float)).sum()} cells")
    fig.suptitle(f"NAO gait library: {gait['evaluations']} evaluations, "
                 f"{gait['test_worlds']} test-stream worlds per cell")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--parts", nargs="+", choices=("toy", "gait"), default=["toy", "gait"])
    ap.add_argument("--seeds", type=parse_seeds, default=list(range(10)),
                    help="optimisation seeds (default 0-9)")
    ap.add_argument("--rho", type=float, default=MAPElitesParams.rho)
    ap.add_argument("--iso-sigma", type=float, default=MAPElitesParams.iso_sigma)
    ap.add_argument("--line-sigma", type=float, default=MAPElitesParams.line_sigma)
    ap.add_argument("--toy-dim", type=int, default=8)
    ap.add_argument("--toy-grid", type=int, default=20)
    ap.add_argument("--toy-ants", type=int, default=64)
    ap.add_argument("--toy-iterations", type=int, default=100)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--horizon", type=float, default=3.0)
    ap.add_argument("--worlds", type=int, default=2)
    ap.add_argument("--test-worlds", type=int, default=6)
    ap.add_argument("--grid", type=int, nargs=2, default=[8, 12],
                    help="cells over forward speed, yaw rate")
    ap.add_argument("--speed-range", type=float, nargs=2, default=[-0.1, 0.3])
    ap.add_argument("--yaw-range", type=float, nargs=2, default=[-30.0, 30.0])
    ap.add_argument("--ants", type=int, default=16)
    ap.add_argument("--iterations", type=int, default=24)
    ap.add_argument("--gait-arms", nargs="+", default=["eaco", "qdax"],
                    choices=("eaco", "isoline", "qdax"))
    ap.add_argument("--track-turn", action="store_true",
                    help="close each cell's heading loop on its commanded turn rate "
                    "(Steering(track_turn=True); experiments/track_turn.py measures it)")
    ap.add_argument("--qdax-vmap", action="store_true",
                    help="run QDax's seeds as one vmapped call, as ours run (for a GPU: its "
                    "seeds one at a time leave it mostly idle)")
    ap.add_argument("--constrained", action="store_true",
                    help="fill the library under the motor constraints (endurance, current, "
                    "slip, falls; needs a horizon long enough for them: see docs)")
    ap.add_argument("--target-noise", type=float, default=None,
                    help="joint-target noise std of the worlds, rad (default RobustConfig's; "
                    "the encoders' quantisation: 0.000443)")
    ap.add_argument("--init", type=Path, default=None,
                    help="narrow the box to +/-15%% of each range around this stored gait")
    ap.add_argument("--free", nargs="+", default=["step_length", "direction", "turn_rate"],
                    help="with --init: parameters that keep their whole range")
    ap.add_argument("--validate-chunk", type=int, default=64)
    ap.add_argument("--device-scale", type=int, default=1,
                    help="multiply the gait batch (--ants) and --test-worlds (a GPU: 8 or more)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    args.ants *= args.device_scale
    args.test_worlds *= args.device_scale
    params = MAPElitesParams(iso_sigma=args.iso_sigma, line_sigma=args.line_sigma,
                             rho=args.rho)
    # QDax only where an arm needs it (the toy part always runs it)
    qd = import_qdax() if "toy" in args.parts or "qdax" in args.gait_arms else None
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    doc = {"date": datetime.date.today().isoformat(),
           "command": "python experiments/gait_library.py " + " ".join(sys.argv[1:]),
           "versions": {"jax": jax.__version__, "eaco_jax": ea.__version__,
                        "qdax": qd["version"] if qd else None},
           "report_seeds": args.seeds, "seed_role": "optimisation seeds (searches); the "
           "gait part's validation worlds are the test stream of each seed",
           "params": {"rho": args.rho, "iso_sigma": args.iso_sigma,
                      "line_sigma": args.line_sigma}}
    if "toy" in args.parts:
        doc["toy"] = part_toy(args, qd, params)
    if "gait" in args.parts:
        doc["gait"], libraries = part_gait(args, qd, params)
        plot_maps(doc["gait"], args.out / "gait_library_map.png")
        for library in libraries:  # library_seed<run seed>.json: cells measured on its tests
            (args.out / f"library_seed{library['seed']}.json").write_text(json.dumps(
                {"problem": doc["gait"]["problem"], "grid": doc["gait"]["grid"],
                 "speed_range": doc["gait"]["speed_range"],
                 "yaw_range": doc["gait"]["yaw_range"], "horizon_s": args.horizon,
                 **library}, indent=1) + "\n")
    doc["seconds_total"] = time.perf_counter() - t0
    doc["cpu_seconds_total"] = time.process_time()
    st.write_results(args.out / "gait_library.json", [], **doc)
    print(f"wrote {args.out / 'gait_library.json'} ({doc['seconds_total']:.0f} s)")


if __name__ == "__main__":
    main()

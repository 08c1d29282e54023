"""The ``gait-front`` run: the Pareto front of walking speed against endurance or electrical CoT.

``eaco gait-front`` searches :func:`~eaco_jax.problems.gait_mo.make_gait_mo_problem`'s
two-objective gait problem with the multi-objective colony
(:class:`~eaco_jax.strategies.MOEACO`): speed against the minutes of continuous walking until
the first winding reaches the firmware limit (``--second endurance``), or against the
electrical cost of transport (``--second cot``). The current, slip, drift and fall constraints
hold in every one of the ``--robust`` randomised worlds of the optimisation stream (Deb's
constrained domination ranks the archive). Outputs in ``out``: ``front.json`` (this record),
``front.csv`` (one row per gait of the feasible first front, its objectives and parameters),
``front.png`` and ``hypervolume.png``. Where no gait meets every constraint the front is
empty, and the record names the archive's least-violating gait and its violation instead.
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.gait.render import ensure_headless_gl
from eaco_jax.runs.base import (
    Built,
    RunKind,
    budget_of,
    check_out,
    check_settings,
    entered,
    params_from,
    setting,
)
from eaco_jax.runs.gait import (
    BACKENDS,
    IK_CHOICES,
    IMPLS,
    ROBOT_HELP,
    check_noise,
    narrowed_around,
    steering_of,
    world_ranges,
)
from eaco_jax.runs.tsp import PARAMS_HELP

ensure_headless_gl()

#: the iteration budget of a run given neither --iterations, --max-evaluations nor --max-seconds
ITERATIONS = 20
SECONDS = ("endurance", "cot")
#: what each objective column is, as the record and the plots name it (speed first)
LABELS = {"endurance": ("speed [m/s]", "endurance [min]"),
          "cot": ("speed [m/s]", "electrical CoT")}


@dataclasses.dataclass(frozen=True)
class GaitFrontSettings:
    robot: str = setting("nao", ROBOT_HELP)
    second: str = setting("endurance", "the objective against speed: endurance (minutes of "
                          "continuous walking until a winding reaches the firmware limit) or "
                          "cot (electrical cost of transport)", choices=SECONDS)
    backend: str = setting("auto", "physics: native (MuJoCo C, CPU default), mjx (GPU default) "
                           "or auto", choices=BACKENDS)
    impl: str = setting("auto", "MJX implementation: warp (MuJoCo Warp, CUDA), jax, or auto",
                        choices=IMPLS)
    ants: int = setting(32, "gaits simulated per iteration (and the archive's size)")
    iterations: int | None = setting(None, f"colony iterations (default {ITERATIONS}; with "
                                     "--max-seconds alone, no cap: time ends the run)")
    horizon: float = setting(4.0, "seconds simulated per gait")
    robust: int = setting(4, "randomised worlds per gait (friction, masses, motors, latency, "
                          "pushes); every constraint holds in each")
    seed: int = setting(0, "random seed (colony and the worlds' optimisation stream)")
    ik: str = setting("auto", "biped leg IK: analytic, generic or auto", choices=IK_CHOICES)
    init: str | None = setting(None, "warm start: search +/-15% of each range around this "
                               "stored gait (a best_gait.json)")
    max_evaluations: int | None = setting(None, "evaluation budget (a hard cap; replaces "
                                          "--iterations)")
    max_seconds: float | None = setting(None, "stop after this many compute seconds")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting("out/gait-front", "folder for front.json, front.csv and plots")
    steer: bool = setting(False, "close the heading loop (eaco_jax.gait.steer defaults), as "
                          "eaco gait --steer")
    target_noise: float | None = setting(None, "joint-target noise std of the worlds, rad "
                                         "(default 0.005; the encoders' quantisation: 0.000443)")

    def __post_init__(self) -> None:
        check_settings(self, "ants", "iterations", "max_evaluations")
        check_noise(self.target_noise)
        if self.ants < 2:
            raise ConfigError(f"ants must be >= 2 (the archive ranks them), got {self.ants}; "
                              "e.g. --ants 32")
        if self.robust < 0:
            raise ConfigError(f"robust must be >= 0 (0: the nominal world only), got "
                              f"{self.robust}; e.g. --robust 4")


def build(s: GaitFrontSettings) -> Built:
    from eaco_jax.problems.gait_mo import make_gait_mo_problem
    from eaco_jax.strategies.mo_eaco import MOEACO

    robust = world_ranges(s.seed, s.target_noise, R=int(s.robust)) if s.robust else None
    problem = make_gait_mo_problem(s.robot, s.second, backend=s.backend, impl=s.impl,
                                   horizon=float(s.horizon), robust=robust, ik=s.ik,
                                   steering=steering_of(s.steer))
    if s.init is not None:  # the box narrowed around the stored gait, as eaco gait --init
        problem, _ = narrowed_around(problem, s.init)
    strategy = MOEACO(num_ants=int(s.ants), archive_size=int(s.ants))
    params = params_from(strategy, problem, s.params, command="eaco gait-front")
    return Built(problem, strategy, params,
                 budget_of(s, s.iterations, {"iterations": ITERATIONS}))


def front_rows(problem: Any, front: dict[str, np.ndarray]) -> list[dict[str, Any]]:
    """One row per gait of the front: speed, the second objective (its own sign) and the
    gait's parameters by name."""
    rows = []
    for x, f in zip(front["x"], front["f"], strict=True):
        second = -float(f[1]) if problem.second == "endurance" else float(f[1])
        rows.append({"speed_mps": -float(f[0]),
                     ("endurance_min" if problem.second == "endurance" else "electrical_cot"):
                         second,
                     "params": problem.params_dict(x)})
    return rows


def run(s: GaitFrontSettings, *, progress: bool = False,
        checkpointing: Any = None) -> dict[str, Any]:
    """Search the front; returns the JSON record and writes ``s.out`` if set."""
    from eaco_jax.driver.minimize import minimize
    from eaco_jax.strategies.mo_eaco import MOEACO

    check_out(s.out)
    built = build(s)
    problem = built.problem
    with entered(built):
        result = minimize(problem, built.strategy, seed=int(s.seed), progress=progress,
                          checkpointing=checkpointing, params=built.params, **built.budget)
    front = MOEACO.front(result.state)
    hv = np.asarray(result.history.get("hypervolume", []), dtype=float)
    record: dict[str, Any] = {
        "robot": problem.spec.name, "second": s.second, "backend": problem.backend,
        "horizon": float(s.horizon), "robust": int(s.robust), "seed": int(s.seed),
        "target_noise": float(problem.robust.target_noise) if problem.robust else None,
        **({"steering": problem.steering.record()} if problem.steering else {}),
        "ants": int(s.ants), "stream": "optimisation",
        "objectives": list(LABELS[s.second]),
        "constraints": list(problem.constraint_names),
        "front_size": int(len(front["f"])),
        "front": front_rows(problem, front),
        "hypervolume": float(hv[-1]) if hv.size else 0.0,
        "hypervolume_units": "m/s x min" if s.second == "endurance" else "m/s x CoT",
        "iterations": int(result.iterations), "evaluations": int(result.evaluations),
        "stop_reason": result.stop_reason, "seconds": float(result.seconds),
        "compile_seconds": float(result.compile_seconds),
        "history_hypervolume": np.where(np.isfinite(hv), hv, 0.0).tolist(),
    }
    if not record["front_size"]:  # nothing feasible: say how close the search came
        v = np.asarray(result.state.archive_v)
        i = int(np.argmin(v))
        record["least_violation"] = {"violation": float(v[i]),
                                     "f": np.asarray(result.state.archive_f)[i].tolist(),
                                     "params": problem.params_dict(
                                         np.asarray(result.state.archive_x)[i])}
    if s.out is not None:
        write_outputs(Path(s.out), record, result.history)
    return record


def write_outputs(folder: Path, record: dict[str, Any], history: Any) -> None:
    from eaco_jax import plots
    from eaco_jax.outputs import write_json

    record["out"] = str(folder)
    folder.mkdir(parents=True, exist_ok=True)
    second = "endurance_min" if record["second"] == "endurance" else "electrical_cot"
    with open(folder / "front.csv", "w", newline="") as fh:
        names = list(record["front"][0]["params"]) if record["front"] else []
        w = csv.writer(fh)
        w.writerow(["speed_mps", second, *names])
        for row in record["front"]:
            w.writerow([row["speed_mps"], row[second], *row["params"].values()])
    xlabel, ylabel = record["objectives"]
    points = np.array([[r["speed_mps"], r[second]] for r in record["front"]]).reshape(-1, 2)
    plots.pareto_front(points, folder / "front.png", xlabel=xlabel, ylabel=ylabel,
                       title=f"{record['robot']}: speed against {record['second']} "
                             f"({record['front_size']} gaits, {record['robust']} worlds each)")
    plots.convergence({"hypervolume": np.asarray(record["history_hypervolume"])},
                      folder / "hypervolume.png", keys=("hypervolume",),
                      title="hypervolume of the feasible front", ylabel=record[
                          "hypervolume_units"])
    write_json(folder / "front.json", record)


def summary(record: dict[str, Any]) -> str:
    if not record["front_size"]:
        lv = record["least_violation"]
        return (f"{record['robot']} speed x {record['second']}: no gait met every constraint "
                f"in {record['robust']} worlds (least violation {lv['violation']:.3f}); "
                f"{record['iterations']} iterations")
    speeds = [r["speed_mps"] for r in record["front"]]
    return (f"{record['robot']} speed x {record['second']}: {record['front_size']} gaits on the "
            f"front, {min(speeds):.3f}-{max(speeds):.3f} m/s, hypervolume "
            f"{record['hypervolume']:.4g} {record['hypervolume_units']}; "
            f"{record['iterations']} iterations")


KIND = RunKind("gait-front", GaitFrontSettings, build, run, None, summary)

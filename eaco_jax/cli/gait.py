"""``eaco gait`` and ``eaco gait-eval``: optimise a walking gait, or re-simulate a stored one.

``eaco gait`` lets the continuous EACO colony search the walk engine's parameters
(:mod:`eaco_jax.gait.walk_engine`): every iteration rolls the whole colony out as one batched
simulation (``--backend native``: MuJoCo's C engine on all CPU threads, the CPU default;
``--backend mjx``: MJX, the GPU default) and scores each gait by the paper's fitness (distance
walked in the desired direction within ``--horizon`` seconds; falls, no progress and drift
> 45 degrees score 0). The best gait is then re-simulated and written to ``--out``:

* ``best_gait.json``: parameters by name and as a vector, robot, horizon, direction, slope,
  backend, seed, iterations and the measured metrics (speed, distance, fall, drift, fitness);
* ``history.csv`` and ``convergence.png``: best-so-far and colony-mean fitness per iteration;
* ``joint_angles.png``: hip, knee and ankle angles of both legs against time (paper Figs. 3, 10);
* ``best_gait.mp4``: an offscreen video of the best gait (skipped, with a message on stderr, when
  no OpenGL context can be made; ``--no-video`` skips it on purpose).

``--init FILE.json`` warm-starts from a stored gait (``best_gait.json`` or
``experiments/results/nao_best_gait.json``): the colony then searches a box of +/- 15% of each
parameter's range around it instead of the full range.

``eaco gait-eval PARAMS.json`` re-simulates stored parameters (same outputs but the convergence
files); robot, horizon, direction and slope come from the file unless given.
"""

from __future__ import annotations

import csv
import json as jsonlib
import time
import warnings
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from eaco_jax.cli.common import emit_json, guarded, register_runner, write_json
from eaco_jax.gait.render import ensure_headless_gl

ensure_headless_gl()  # before anything imports mujoco: its GL backend is fixed at import

DEFAULT_OUT = "out/gait"
DEFAULT_ANTS = 16
DEFAULT_ITERATIONS = 25
DEFAULT_HORIZON = 4.0
EVAL_HORIZON = 20.0
INIT_RADIUS = 0.15
"""``--init`` search box: +/- this fraction of each parameter's range around the stored gait."""

METRIC_KEYS = ("fitness", "speed_mps", "distance_m", "fell", "drift_deg", "fall_time")
LEG_PITCH_JOINTS = ("HipPitch", "KneePitch", "AnklePitch")  # not HipYawPitch


# --------------------------------------------------------------------------- parameter files
def read_params_file(path: str | Path) -> dict[str, Any]:
    """Load a stored gait (``best_gait.json`` / ``nao_best_gait.json``); one-line errors."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"parameter file {path} does not exist")
    try:
        data = jsonlib.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:
        raise ValueError(f"parameter file {path} is not valid JSON ({err})") from None
    if not isinstance(data, dict) or not ("vector" in data or "params" in data):
        raise ValueError(
            f"parameter file {path} needs a 'vector' list or a 'params' {{name: value}} object "
            "(as written by `eaco gait`)")
    return data


def params_vector(data: dict[str, Any], problem: Any, source: str) -> np.ndarray:
    """The parameter vector of a stored gait for ``problem`` (by name if given, else vector)."""
    names = problem.param_names
    if isinstance(data.get("params"), dict):
        missing = [n for n in names if n not in data["params"]]
        if missing:
            raise ValueError(f"{source}: parameters {missing} missing for robot "
                             f"{problem.spec.name!r} (expects {', '.join(names)})")
        values = [data["params"][n] for n in names]
    else:
        values = data["vector"]
    try:
        vec = np.asarray(values, np.float32).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{source}: parameters must be numbers") from None
    if vec.shape != (len(names),):
        raise ValueError(f"{source}: robot {problem.spec.name!r} needs {len(names)} parameters, "
                         f"got {vec.size}")
    if not np.all(np.isfinite(vec)):
        raise ValueError(f"{source}: parameters must be finite")
    return vec


def _stored(data: dict[str, Any], *keys: str) -> Any:
    for k in keys:
        if data.get(k) is not None:
            return data[k]
    return None


def _check_choice(label: str, value: str, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"unknown {label} {value!r}; use one of {', '.join(choices)}")


# --------------------------------------------------------------------------- outputs
def write_trajectory_outputs(folder: Path, problem: Any, sim: dict[str, Any], video: bool,
                             title: str) -> dict[str, str | None]:
    """``joint_angles.png`` and (if ``video``) ``best_gait.mp4`` of one simulated gait."""
    from eaco_jax import plots

    folder.mkdir(parents=True, exist_ok=True)
    legs, groups = leg_joints(sim["joints"])
    files: dict[str, str | None] = {"joint_angles": str(plots.joint_trajectories(
        sim["time"], legs, folder / "joint_angles.png", title=title, groups=groups))}
    files["video"] = write_video(folder / "best_gait.mp4", problem, sim["qpos"]) if video else None
    return files


def leg_joints(joints: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """The joints the paper plots (sagittal hip, knee, ankle pitch of both legs) and their groups;
    robots without such names (the ant) get every joint, grouped by name prefix (hip, ankle)."""
    pitch = {n: a for n, a in joints.items() if n.endswith(LEG_PITCH_JOINTS)}
    if pitch:
        return pitch, ("Hip", "Knee", "Ankle")
    return dict(joints), tuple(dict.fromkeys(n.split("_")[0] for n in joints))


def write_video(path: Path, problem: Any, qpos: np.ndarray) -> str | None:
    """Render the trajectory offscreen; on a machine without OpenGL say so and return None."""
    from eaco_jax.gait.render import RenderUnavailable, render_video
    from eaco_jax.gait.rollout_native import native_model

    model = native_model(problem.spec, float(problem.slope_deg), problem.accuracy)
    try:
        with warnings.catch_warnings():  # ffmpeg runs as a subprocess (fork + exec): harmless
            warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called")
            return str(render_video(model, qpos, problem.spec.control_dt, path, fps=25.0,
                                    track_body=problem.spec.torso_body))
    except RenderUnavailable as err:
        typer.echo(f"note: video skipped, offscreen rendering is unavailable here: {err}",
                   err=True)
        return None


def write_history(path: Path, history: dict[str, np.ndarray]) -> Path:
    """Per-iteration statistics as CSV (fitness columns are ``-cost``: higher is better)."""
    keys = list(history)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["iteration", *keys])
        for i in range(len(np.asarray(history[keys[0]]))):
            writer.writerow([i + 1, *(np.asarray(history[k])[i].item() for k in keys)])
    return path


def fitness_history(history: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The driver's cost history turned into fitness (metres walked), plus the rest."""
    out = {"best_fitness": -np.asarray(history["best_cost"], np.float64),
           "iter_best_fitness": -np.asarray(history["iter_best_cost"], np.float64),
           "iter_mean_fitness": -np.asarray(history["iter_mean_cost"], np.float64)}
    for k in ("diversity", "evaluations"):
        if k in history:
            out[k] = np.asarray(history[k])
    return out


def _setting(problem: Any) -> dict[str, Any]:
    """The simulated setting shared by the gait and gait-eval records."""
    return {"robot": problem.spec.name, "backend": problem.backend, "horizon": problem.horizon,
            "direction": problem.direction_deg, "slope": problem.slope_deg}


def _metrics(sim: dict[str, Any]) -> dict[str, Any]:
    return {k: sim[k] for k in METRIC_KEYS}


# --------------------------------------------------------------------------- runners
def run_gait(
    robot: str = "nao",
    backend: str = "auto",
    ants: int = DEFAULT_ANTS,
    iterations: int = DEFAULT_ITERATIONS,
    horizon: float = DEFAULT_HORIZON,
    direction: float = 0.0,
    slope: float = 0.0,
    seed: int = 0,
    out: str | None = DEFAULT_OUT,
    json: bool = False,
    quiet: bool = False,
    checkpoint_dir: str | None = None,
    checkpoint_every: int | None = None,
    video: bool = True,
    init: str | None = None,
) -> dict[str, Any]:
    """Optimise a gait with the continuous EACO colony; write outputs to ``out``; JSON record."""
    import jax.numpy as jnp

    from eaco_jax.driver.minimize import minimize
    from eaco_jax.problems.gait import BACKENDS, make_gait_problem
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    _check_choice("backend", backend, BACKENDS)
    if ants < 1:
        raise ValueError(f"--ants must be >= 1, got {ants}")
    if iterations < 1:
        raise ValueError(f"--iterations must be >= 1, got {iterations}")
    args = dict(robot=robot, backend=backend, ants=ants, iterations=iterations, horizon=horizon,
                direction=direction, slope=slope, seed=seed, out=out, json=json, quiet=quiet,
                checkpoint_every=checkpoint_every, video=video,
                init=None if init is None else str(init))
    problem = make_gait_problem(robot, backend=backend, horizon=float(horizon),
                                direction_deg=float(direction), slope_deg=float(slope))
    search = problem
    init_vec = None
    if init is not None:
        init_vec = params_vector(read_params_file(init), problem, str(init))
        full_lo, full_hi = np.asarray(problem.lower), np.asarray(problem.upper)
        half = INIT_RADIUS * (full_hi - full_lo)
        lo = np.maximum(full_lo, init_vec - half).astype(np.float32)
        hi = np.minimum(full_hi, init_vec + half).astype(np.float32)
        search = problem.replace(lower=jnp.asarray(lo), upper=jnp.asarray(hi))
    # the simulation is not differentiable: no SQP refinement ants, no gradient repair
    strategy = ContinuousEACO(num_ants=int(ants), archive_size=max(2, (3 * int(ants)) // 2),
                              refine_ants=0, repair_steps=0)
    kwargs: dict[str, Any] = {}
    if checkpoint_dir is not None:
        kwargs.update(checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every,
                      run_info={"command": "gait", "args": args})
    elif checkpoint_every is not None:
        raise ValueError("--checkpoint-every needs --checkpoint-dir")
    t0 = time.perf_counter()
    result = minimize(search.as_constrained(), strategy, seed=int(seed),
                      iterations=int(iterations), progress=not (json or quiet), **kwargs)
    best = np.asarray(result.best_solution, np.float32)
    sim = problem.simulate(best, record=True)
    seconds = time.perf_counter() - t0
    history = fitness_history(result.history)
    record: dict[str, Any] = {
        **_setting(problem),
        "ants": int(ants),
        "seed": int(seed),
        "iterations": int(result.iterations),
        "evaluations": int(np.asarray(result.evaluations)),
        **_metrics(sim),
        "search_fitness": float(-np.asarray(result.best_cost)),
        "params": problem.params_dict(best),
        "vector": best.tolist(),
        "init": None if init is None else str(init),
        "seconds": seconds,
        "compile_seconds": float(result.compile_seconds),
        "seconds_per_iteration": float(result.seconds_per_iteration),
        "history_best": history["best_fitness"].tolist(),
        "out": None if out is None else str(out),
    }
    if init_vec is not None:
        record["init_fitness"] = problem.simulate(init_vec, record=False)["fitness"]
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        write_history(folder / "history.csv", history)
        from eaco_jax import plots

        plots.convergence(history, folder / "convergence.png",
                          keys=("best_fitness", "iter_mean_fitness"), ylabel="fitness [m]",
                          title=f"{problem.name}: fitness ({problem.horizon:g} s horizon)")
        files = write_trajectory_outputs(
            folder, problem, sim, video,
            title=f"{problem.spec.name}: best gait, {sim['speed_mps']:.2f} m/s")
        record["files"] = {"best_gait": str(folder / "best_gait.json"),
                           "history": str(folder / "history.csv"),
                           "convergence": str(folder / "convergence.png"), **files}
        write_json(folder / "best_gait.json", record)
    return record


def run_gait_eval(
    params_json: str,
    robot: str | None = None,
    backend: str = "auto",
    horizon: float | None = None,
    json: bool = False,
    out: str | None = None,
    video: bool = True,
) -> dict[str, Any]:
    """Re-simulate a stored gait; robot, horizon, direction, slope default to the file's."""
    from eaco_jax.problems.gait import BACKENDS, make_gait_problem

    _check_choice("backend", backend, BACKENDS)
    data = read_params_file(params_json)
    robot = robot or _stored(data, "robot") or "nao"
    if horizon is None:
        horizon = float(_stored(data, "horizon", "verify_horizon") or EVAL_HORIZON)
    direction = float(_stored(data, "direction", "direction_deg") or 0.0)
    slope = float(_stored(data, "slope", "slope_deg") or 0.0)
    problem = make_gait_problem(str(robot), backend=backend, horizon=float(horizon),
                                direction_deg=direction, slope_deg=slope)
    vec = params_vector(data, problem, str(params_json))
    t0 = time.perf_counter()
    sim = problem.simulate(vec, record=out is not None)
    record: dict[str, Any] = {
        **_setting(problem),
        **_metrics(sim),
        "params": problem.params_dict(vec),
        "vector": vec.tolist(),
        "source": str(params_json),
        "seconds": time.perf_counter() - t0,
        "out": None if out is None else str(out),
    }
    if out is not None:
        folder = Path(out)
        files = write_trajectory_outputs(
            folder, problem, sim, video,
            title=f"{problem.spec.name}: {Path(params_json).name}, {sim['speed_mps']:.2f} m/s")
        record["files"] = {"eval": str(folder / "gait_eval.json"), **files}
        write_json(folder / "gait_eval.json", record)
    return record


register_runner("gait", run_gait)


def _summary(record: dict[str, Any]) -> str:
    fell = f"fell at {record['fall_time']:.1f} s" if record["fell"] else "no fall"
    return (f"{record['robot']} ({record['backend']}, {record['horizon']:g} s): "
            f"speed {record['speed_mps']:.3f} m/s, distance {record['distance_m']:.3f} m, "
            f"{fell}, drift {record['drift_deg']:.1f} deg, fitness {record['fitness']:.3f}")


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def gait(
        robot: Annotated[str, typer.Option(help="robot: nao (humanoid) or ant (quadruped)")] = (
            "nao"),
        backend: Annotated[str, typer.Option(
            help="physics: native (MuJoCo C, CPU default), mjx (GPU default) or auto")] = "auto",
        ants: Annotated[int, typer.Option(help="colony size (gaits simulated per iteration)")] = (
            DEFAULT_ANTS),
        iterations: Annotated[int, typer.Option(help="colony iterations")] = DEFAULT_ITERATIONS,
        horizon: Annotated[float, typer.Option(
            help="seconds simulated per gait (the paper uses 20)")] = DEFAULT_HORIZON,
        direction: Annotated[float, typer.Option(
            help="desired walking direction in degrees, 0 = forward (+x)")] = 0.0,
        slope: Annotated[float, typer.Option(help="floor slope in degrees, uphill along +x")] = 0.0,
        seed: Annotated[int, typer.Option(help="random seed")] = 0,
        out: Annotated[Path, typer.Option(
            help="folder for best_gait.json, history.csv, plots and video")] = Path(DEFAULT_OUT),
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
        checkpoint_dir: Annotated[Path | None, typer.Option(
            help="checkpoint folder (continue with `eaco resume DIR`)")] = None,
        checkpoint_every: Annotated[int | None, typer.Option(
            help="iterations between checkpoints")] = None,
        video: Annotated[bool, typer.Option(
            "--video/--no-video", help="render best_gait.mp4 offscreen")] = True,
        init: Annotated[Path | None, typer.Option(
            help="warm start: search +/-15% of each range around this stored gait (JSON)")] = (
            None),
    ) -> None:
        """Optimise a walking gait with the EACO colony on batched physics; write its outputs."""
        record = run_gait(
            robot=robot, backend=backend, ants=ants, iterations=iterations, horizon=horizon,
            direction=direction, slope=slope, seed=seed, out=str(out), json=json_out,
            quiet=quiet, checkpoint_dir=None if checkpoint_dir is None else str(checkpoint_dir),
            checkpoint_every=checkpoint_every, video=video,
            init=None if init is None else str(init))
        if json_out:
            emit_json(record)
        else:
            typer.echo(_summary(record))
            typer.echo(f"{record['evaluations']} gaits simulated in {record['seconds']:.0f} s; "
                       f"outputs in {record['out']}")

    @app.command("gait-eval")
    @guarded
    def gait_eval(
        params_json: Annotated[Path, typer.Argument(
            metavar="PARAMS.json", help="a stored gait (best_gait.json of `eaco gait`)")],
        robot: Annotated[str | None, typer.Option(help="robot (default: the file's)")] = None,
        backend: Annotated[str, typer.Option(help="native, mjx or auto")] = "auto",
        horizon: Annotated[float | None, typer.Option(
            help="seconds to simulate (default: the file's horizon, else 20)")] = None,
        out: Annotated[Path | None, typer.Option(
            help="folder for gait_eval.json, joint_angles.png and the video")] = None,
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        video: Annotated[bool, typer.Option(
            "--video/--no-video", help="render best_gait.mp4 into --out")] = True,
    ) -> None:
        """Re-simulate stored gait parameters and report speed, distance, fall and drift."""
        record = run_gait_eval(
            str(params_json), robot=robot, backend=backend, horizon=horizon, json=json_out,
            out=None if out is None else str(out), video=video)
        if json_out:
            emit_json(record)
        else:
            typer.echo(_summary(record))


__all__ = ["read_params_file", "run_gait", "run_gait_eval"]

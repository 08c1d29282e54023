"""Rows of docs/bad_inputs.md that no behaviour test held: each message, from the route the row
names (the command line, a sweep plan, the API)."""

from __future__ import annotations

import math
import warnings

import jax
import pytest
from typer.testing import CliRunner

import eaco_jax as ea
from eaco_jax.cli import app
from eaco_jax.driver.interrupt import interrupt_message
from eaco_jax.driver.minimize import Checkpointing
from eaco_jax.strategies import GraphEACO

RUNNER = CliRunner()


def _cli(*args: str):
    res = RUNNER.invoke(app, ["--no-compile-cache", *args])
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    return res.exit_code, (lines[-1] if lines else "")


@pytest.mark.parametrize(("args", "says"), [
    (("tsp", "burma14", "--params", "q0=abc"), "q0='abc' is not a number or true/false"),
    (("tsp", "burma14", "--max-seconds", "-1"), "max_seconds must be > 0, got -1.0"),
    (("tsp", "burma14", "--checkpoint-every", "5"), "--checkpoint-every needs --checkpoint-dir"),
    (("gait-eval", "experiments/results/nao_best_gait.json", "--stream", "validation"),
     "stream='validation' is not one of test, selection, optimisation"),
])
def test_command_line_refusals_are_one_line(args, says):
    code, last = _cli(*args)
    assert code == 2 and last.startswith("error: ") and says in last, last


def test_sweep_seed_outside_the_key_range_is_refused():
    from eaco_jax.sweep.local import plan

    spec = {"command": "tsp", "args": {"instance": "burma14", "ants": 4, "iterations": 2,
                                       "local_search": "none"}, "seeds": [-1]}
    with pytest.raises(ea.ConfigError, match=r"seeds: -1 is outside the range 0\.\.4294967295"):
        plan(spec)


@pytest.mark.parametrize(("kwargs", "says"), [
    ({"chunk_size": 0}, "chunk_size=0 is outside its range"),
    ({"iterations": 0}, "iterations=0 is outside its range"),
    ({"target": math.nan}, "target must be a finite number, got nan"),
    ({"precision": "half"}, "precision='half' is not one of auto, float32, float64"),
])
def test_minimize_arguments_are_checked_before_a_run(kwargs, says):
    burma = ea.problems.get("burma14")
    with pytest.raises(ea.ConfigError, match=says.replace("(", r"\(")):
        ea.minimize(burma, GraphEACO(num_ants=4, local_search="none"), **kwargs)


def test_a_colony_whose_iteration_is_large_warns_before_it_runs():
    from eaco_jax.driver.memory import check_state_memory
    from eaco_jax.runs import tsp as run_tsp

    built = run_tsp.build(run_tsp.TspSettings(instance="pr1002", ants=200000))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_state_memory(built.strategy, built.problem, 1, built.params)
    text = " ".join(str(w.message) for w in caught)
    assert "needs ~" in text and "GiB per iteration" in text and "expect slow" in text, text


def test_constrained_must_be_a_boolean():
    from eaco_jax.problems.gait import make_gait_problem

    with pytest.raises(ea.ProblemError, match="constrained must be True or False, got 'yes'"):
        make_gait_problem("nao", backend="native", constrained="yes")


class _Result:
    best_cost = [426.0, 430.0]


def test_interrupt_lines_say_what_was_kept(tmp_path):
    assert interrupt_message("SIGINT", _Result(), 0, 3000, Checkpointing(tmp_path)).endswith(
        "after 0 of 3000 iterations; nothing to save yet (start the same command again)")
    line = interrupt_message("SIGINT", _Result(), 7, 3000, None)
    assert line == ("interrupted (SIGINT) after 7 of 3000 iterations; best so far: 426, 430 "
                    "(no checkpoint: pass --checkpoint-dir to resume)")


# ---------------------------------------------------------------- sparse TSP, walk, thermal
@pytest.mark.parametrize(("args", "says"), [
    (("tsp", "eil51", "--sparse", "maybe"), "sparse='maybe' is not one of auto, on, off"),
    (("tsp", "eil51", "--neighbors", "0"), "neighbors=0 is outside its range 1.."),
    (("tsp", "eil51", "--max-new-edges", "0"), "max_new_edges=0 is outside its range 1.."),
    (("tsp", "eil51", "--max-new-edges", "5", "--iterations", "2", "--quiet"),
     "max_new_edges (focused construction) needs the sparse path"),
    (("tsp", "eil51", "--construction", "moves", "--iterations", "2", "--quiet"),
     "construction='moves' applies max_new_edges moves per ant: give --max-new-edges N"),
    (("tsp", "eil51", "--construction", "moves", "--max-new-edges", "4", "--iterations", "2",
      "--quiet"), "construction='moves' needs the sparse path (no distance matrix): pass "
     "--sparse on to eaco tsp"),
    (("tsp", "eil51", "--chunk-seconds", "-1"),
     "chunk_seconds must be a finite number >= 0 (0: unpaced), got -1.0; e.g. --chunk-seconds "
     "0.2"),
    (("tsp", "eil51", "--chunk-seconds", "0.2", "--iterations", "5"),
     "chunk_seconds paces a run that --max-seconds alone ends; drop --iterations"),
    (("tsp", "eil51", "--ls-focus-width", "-1"),
     "ls_focus_width must be >= 0 (0: no focus), got -1; e.g. --ls-focus-width 128"),
    (("tsp", "eil51", "--merge-ants", "1"),
     "merge_ants must be 0 (off) or >= 2, got 1; e.g. --merge-ants 16"),
    (("tsp", "eil51", "--merge-ants", "4", "--iterations", "2"),
     "merge_ants merges ants that changed a few edges of the best tour: give --max-new-edges N"),
    (("walk", "nosuch.json"), "is not a file; give a scene JSON file, 'default' or "
     "'random:SEED'"),
    (("walk", "random:x"), "scene 'random:x': write random:SEED with an integer seed"),
    (("walk", "default", "--resume-deg", "200"),
     "controller resume_deg must be in [0, turn_deg=180.0), got 200.0"),
    (("gait-eval", "experiments/results/go2_cpu_gait.json", "--thermal", "--backend", "native",
      "--horizon", "1"), "robot 'go2' has no electrical motor data: no thermal walk (drop "
     "--thermal)"),
])
def test_sparse_tsp_walk_and_thermal_refusals_are_one_line(args, says):
    code, last = _cli(*args)
    assert code == 2 and last.startswith("error: ") and says in last, last


def _tsp_file(path, body: str) -> str:
    path.write_text(body)
    return str(path)


def test_tsp_files_the_sparse_path_or_the_local_search_cannot_take(tmp_path):
    """A matrix-only (EXPLICIT) instance forced sparse, coordinates whose distances pass 2**24
    forced sparse, and instances too small for the default local search: one line each,
    naming the fix, before any iteration."""
    rows = "\n".join(" ".join(str(0 if i == j else 7 * (i + j) + 3) for j in range(5))
                     for i in range(5))
    explicit = _tsp_file(tmp_path / "ex5.tsp", "NAME: ex5\nTYPE: TSP\nDIMENSION: 5\n"
                         "EDGE_WEIGHT_TYPE: EXPLICIT\nEDGE_WEIGHT_FORMAT: FULL_MATRIX\n"
                         f"EDGE_WEIGHT_SECTION\n{rows}\nEOF\n")
    code, last = _cli("tsp", explicit, "--sparse", "on")
    assert code == 2 and "EDGE_WEIGHT_TYPE EXPLICIT has no sparse path; use one of EUC_2D, " \
        "CEIL_2D, ATT or the dense path" in last, last
    code, last = _cli("tsp", explicit, "--iterations", "2", "--quiet")
    assert code == 2 and last.startswith("error: Or-opt needs at least 8 cities, got 5; use "
                                         "local_search='2opt'"), last
    three = _tsp_file(tmp_path / "t3.tsp", "NAME: t3\nTYPE: TSP\nDIMENSION: 3\n"
                      "EDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 10 0\n3 0 10\nEOF\n")
    code, last = _cli("tsp", three, "--local-search", "2opt", "--iterations", "2", "--quiet")
    assert code == 2 and last.startswith("error: local search needs at least 4 cities, got 3; "
                                         "use local_search='none'"), last
    huge = _tsp_file(tmp_path / "huge.tsp", "NAME: huge\nTYPE: TSP\nDIMENSION: 4\n"
                     "EDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3000000000000 0\n"
                     "3 3000000000000 3000000000000\n4 0 3000000000000\nEOF\n")
    code, last = _cli("tsp", huge, "--sparse", "on", "--local-search", "none")
    assert code == 2 and "give distances >= 2**24, beyond exact float32 integers; rescale " \
        "the coordinates" in last, last


def test_candidate_lists_longer_than_the_other_cities_are_cut_to_them():
    """--neighbors n or more is taken as 'every other city' (n - 1) on both paths."""
    from eaco_jax.problems import load_tsplib

    for sparse in (False, True):
        assert load_tsplib("eil51", neighbors=1000, sparse=sparse).neighbors.shape == (51, 50)


def test_walk_refuses_a_goal_walled_in_at_the_walking_clearance(tmp_path):
    """A gap of 0.7 m passes at the scene's clearance 0.3 m (eaco path) but not at the walking
    clearance 0.4 m (eaco walk): refused before any planning or walking."""
    import json

    walls = [[[8.6, 4.5], [8.8, 4.5], [8.8, 5.65], [8.6, 5.65]],
             [[8.6, 6.35], [8.8, 6.35], [8.8, 7.5], [8.6, 7.5]],
             [[8.6, 4.5], [10.5, 4.5], [10.5, 4.7], [8.6, 4.7]],
             [[8.6, 7.3], [10.5, 7.3], [10.5, 7.5], [8.6, 7.5]]]
    scene = tmp_path / "gap.json"
    scene.write_text(json.dumps({
        "name": "gap", "bounds": [0, 0, 10, 10], "start": [0.5, 5], "goal": [9.5, 6],
        "clearance": 0.3, "obstacles": [{"polygon": w, "height": 1} for w in walls],
        "ramps": []}))
    code, last = _cli("path", "--scene", str(scene), "--iterations", "2", "--ants", "4",
                      "--quiet")
    assert code == 0, last
    code, last = _cli("walk", str(scene), "--plan-iterations", "2", "--max-time", "1")
    assert code == 2 and last == ("error: gap: the goal cannot be reached from the start "
                                  "around these obstacles; move an obstacle or lower the "
                                  "clearance (eaco walk plans at --clearance 0.4 m, above the "
                                  "scene's 0.3 m: pass a smaller --clearance, not below the "
                                  "NAO's half-width 0.25 m)"), last


# ---------------------------------------------------------------- MAP-Elites and QD problems
def test_map_elites_radius_and_colony_size_are_checked():
    from eaco_jax.strategies.map_elites import MAPElites

    for radius in (0, 1.5):
        with pytest.raises(ea.ConfigError, match=f"MAPElites radius must be an int >= 1, got "
                                                 f"{radius}"):
            MAPElites(radius=radius)
    with pytest.raises(ea.ConfigError, match="MAPElites needs num_ants >= 1"):
        MAPElites(num_ants=0)


def test_map_elites_on_a_problem_of_another_kind():
    from eaco_jax.strategies.map_elites import MAPElites

    with pytest.raises(ea.ProblemError, match="MAPElites solves 'qd' problems, but 'sphere10' "
                                              "is 'continuous'"):
        ea.minimize(ea.problems.get("sphere"), MAPElites(num_ants=4, grid=(2, 2)), iterations=2)


def test_map_elites_in_islands_without_migration_only():
    """Migration would hand an archive elites without their cells: refused when the islands
    are built; independent islands (every=None) are fine."""
    from eaco_jax.strategies.islands import Islands
    from eaco_jax.strategies.map_elites import MAPElites

    with pytest.raises(ea.ConfigError, match=r"MAPElites has no island migration: pass "
                                             r"every=None \(independent islands\)"):
        Islands(MAPElites(num_ants=8, grid=(4, 4)), islands=2, every=2)
    assert Islands(MAPElites(num_ants=8, grid=(4, 4)), islands=2, every=None).num_ants == 16


def test_gait_library_and_descriptor_ranges_are_checked():
    import dataclasses

    from eaco_jax.problems.gait_library import make_gait_library_problem
    from eaco_jax.problems.qd import rastrigin_proj
    from eaco_jax.strategies.map_elites import MAPElites

    with pytest.raises(ea.ProblemError, match="robot 'go2' is a quadruped: use a biped such "
                                              "as nao or op3"):
        make_gait_library_problem("go2", backend="native", worlds=0)
    with pytest.raises(ea.ProblemError, match=r"speed_range must be two finite numbers \(low, "
                                              r"high\) with low < high, got \(0.3, 0.1\)"):
        make_gait_library_problem(backend="native", worlds=0, speed_range=(0.3, 0.1))
    p = rastrigin_proj()
    flipped = dataclasses.replace(p, descriptor_lower=p.descriptor_upper,
                                  descriptor_upper=p.descriptor_lower)
    with pytest.raises(ea.ProblemError, match="descriptor bounds must be finite 1-D vectors of "
                                              "one length with lower < upper"):
        MAPElites(num_ants=4, grid=(2, 2)).init(jax.random.key(0), flipped)

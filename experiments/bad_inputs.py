"""Try every bad input and fault we know of; write the message each gets to docs/bad_inputs.md.

    python experiments/bad_inputs.py            # about two minutes on a CPU

Each row: what was tried, how (API / CLI / file / script), the first line the user sees (the
error's message, a warning, or the relevant result fields for faults that are not errors),
and the test(s) in tests/ that fail if that behaviour regresses (``none`` where none does).
"""

from __future__ import annotations

import dataclasses
import json
import os
import pickle
import shutil
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from typer.testing import CliRunner

import eaco_jax as ea
from eaco_jax.cli import app
from eaco_jax.problems import TSP, ConstrainedProblem, load_tsplib
from eaco_jax.strategies import GraphEACO

ROWS: list[tuple[str, str, str, str]] = []
TMP = Path(tempfile.mkdtemp())
RUNNER = CliRunner()


def held_by(test: str | tuple[str, ...]) -> str:
    """The "held by" cell: pytest node ids in backticks, or ``none``."""
    tests = (test,) if isinstance(test, str) else test
    if tests == ("none",):
        return "none"
    return ", ".join(f"`{t}`" for t in tests)


def record(what: str, how: str, fn: Callable[[], object], *,
           test: str | tuple[str, ...]) -> None:
    """Run ``fn``; record its exception's message, its warnings or its return value, and
    ``test``: the pytest node id(s) that hold the row ("none" where no test does)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = fn()
            text = "" if out is None else str(out)
        except BaseException as err:  # noqa: BLE001 - what the user sees is the point
            text = f"{type(err).__name__}: {err}"
    notes = [f"warning: {w.message}" for w in caught
             if issubclass(w.category, UserWarning) and "jax" not in str(w.filename).split(
                 "site-packages")[-1][:5]]
    text = " / ".join([t for t in [text, *notes[:2]] if t])
    ROWS.append((what, how, text.replace("\n", " ").replace("|", "\\|")[:400], held_by(test)))
    print(f"- {what}: {text[:160]}")


def _tsp_run_started_at(started_at: float) -> object:
    """``eaco_jax.runs.tsp.run`` on burma14 with the call clock and ``started_at``."""
    from eaco_jax.runs.tsp import TspSettings, run

    return run(TspSettings("burma14", max_seconds=5.0, clock="call", iterations=2),
               started_at=started_at)


def multiobjective_rows() -> None:
    """The multi-objective mode: a user's own problem, the strategy, tell by hand."""
    from eaco_jax.problems import MultiObjectiveProblem
    from eaco_jax.strategies import MOEACO, ContinuousEACO

    zdt1 = ea.problems.get("zdt1", dim=5)
    record("`MultiObjectiveProblem` with a `ref_point` of 1 number for 2 objectives", "API",
           lambda: MultiObjectiveProblem(lambda x: x[:2], lower=[0, 0, 0], upper=[1, 1, 1],
                                         ref_point=[1.0]),
           test="tests/test_multiobjective.py::test_bad_problem_is_one_line")
    record("`MultiObjectiveProblem` whose objectives return a scalar", "API",
           lambda: MultiObjectiveProblem(lambda x: x[0], lower=[0, 0], upper=[1, 1],
                                         ref_point=[1.0, 1.0]),
           test="tests/test_multiobjective.py::test_bad_problem_is_one_line")
    record("`ea.minimize(problems.get('zdt1'), strategy=ContinuousEACO())`", "API",
           lambda: ea.minimize(zdt1, strategy=ContinuousEACO(), iterations=2),
           test="tests/test_multiobjective.py::test_wrong_inputs_are_one_line")
    record("`MOEACO` on a single-objective problem (`sphere`)", "API",
           lambda: ea.minimize(ea.problems.get("sphere", dim=3), strategy=MOEACO(),
                               iterations=2),
           test="tests/test_multiobjective.py::test_wrong_inputs_are_one_line")

    def one_objective() -> None:
        s = MOEACO(num_ants=4, archive_size=4)
        state = s.init(jax.random.key(0), zdt1)
        x, state = s.ask(jax.random.key(1), state, zdt1)
        e = zdt1.evaluate(x)
        s.tell(state, x, ea.Evaluation(f=e.f[:, 0], violation=e.violation), zdt1)
    record("`MOEACO.tell` with one objective per ant (`f` of shape (ants,))", "API",
           one_objective,
           test="tests/test_multiobjective.py::test_wrong_inputs_are_one_line")


def cli(*args: str) -> str:
    res = RUNNER.invoke(app, ["--no-compile-cache", *args])
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    return f"exit {res.exit_code}: " + (lines[-1] if lines else "")


def robot_spec_rows() -> None:
    """Robot specs of a user's own (issue 31): the ant's MJCF and spec copied outside the repo."""
    from eaco_jax.gait.robot import ROBOTS_DIR, load_robot
    from eaco_jax.problems.gait import make_gait_problem

    folder = TMP / "walker"
    folder.mkdir(exist_ok=True)

    def spec(**fields: object) -> str:
        shutil.copy(load_robot("ant").xml_path, folder / "walker.xml")
        raw = json.loads((ROBOTS_DIR / "ant.json").read_text())
        raw.update(name="walker", xml="walker.xml", **fields)
        (folder / "walker.json").write_text(json.dumps(raw))
        return str(folder / "walker.json")

    tiny = ["--backend", "native", "--ants", "4", "--iterations", "1", "--horizon", "0.5",
            "--out", str(TMP / "walker_out")]
    record("`eaco gait --robot robot.xml` (an MJCF, not a spec)", "CLI",
           lambda: cli("gait", "--robot", str(folder / "robot.xml"), *tiny),
           test="tests/test_robot_spec.py::test_bad_robot_arguments")
    record("robot spec naming a joint the MJCF lacks", "file",
           lambda: cli("gait", "--robot", spec(joint_names=["hip_9", *json.loads(
               (ROBOTS_DIR / "ant.json").read_text())["joint_names"][1:]]), *tiny),
           test="tests/test_robot_spec.py::test_bad_spec_is_one_line_naming_the_field")
    record("robot spec whose feet are above the hips (upside-down stand_root)", "file",
           lambda: cli("gait", "--robot", spec(stand_root=[0, 0, 0.55, 0, 1, 0, 0]), *tiny),
           test="tests/test_robot_spec.py::test_bad_spec_is_one_line_naming_the_field")

    def no_actuator() -> str:
        path = spec()
        xml = folder / "walker.xml"
        text = xml.read_text()
        line = next(ln for ln in text.splitlines() if "<motor" in ln and "hip_1" in ln)
        xml.write_text(text.replace(line, ""))
        return cli("gait", "--robot", path, *tiny)
    record("robot spec whose MJCF has no actuator for a joint", "file", no_actuator,
           test="tests/test_robot_spec.py::test_bad_spec_is_one_line_naming_the_field")
    record("robot spec with gait `hexapod`", "file",
           lambda: cli("gait", "--robot", spec(gait="hexapod"), *tiny),
           test=("tests/test_robot_spec.py::test_bad_spec_is_one_line_naming_the_field",
                 "tests/test_robot_spec.py::test_cli_bad_spec_is_one_error_line"))
    record("`make_gait_problem(robot=spec)` with `control_dt: \"fast\"`", "API",
           lambda: make_gait_problem(robot=spec(control_dt="fast"), backend="native"),
           test="tests/test_robot_spec.py::test_bad_spec_is_one_line_naming_the_field")

    def resume_changed() -> str:
        path, ckpt = spec(), TMP / "walker_ckpt"
        cli("gait", "--robot", path, *tiny, "--checkpoint-dir", str(ckpt),
            "--checkpoint-every", "1")
        xml = folder / "walker.xml"
        xml.write_text(xml.read_text().replace('density="5.0"', 'density="6.0"', 1))
        return cli("resume", str(ckpt))
    record("`eaco resume` after the run's robot MJCF changed", "CLI", resume_changed,
           test="tests/test_robot_spec.py::test_resume_refuses_a_changed_spec")


def write_tsp(name: str, body: str) -> str:
    path = TMP / name
    path.write_text(body)
    return str(path)


def constrained_gait_rows() -> None:
    """The constrained gait search and the world key streams (issue 30)."""
    from eaco_jax.problems.gait import make_gait_problem

    record("`eaco gait --constraint-method deb` without `--constrained`", "CLI",
           lambda: cli("gait", "--constraint-method", "deb"),
           test="tests/test_gait_constraints.py::test_constrained_settings_errors")
    record("`eaco gait --constrained --penalty cot`", "CLI",
           lambda: cli("gait", "--constrained", "--penalty", "cot"),
           test="tests/test_gait_constraints.py::test_constrained_settings_errors")
    record("`eaco gait --constrained --robot ant` (no electrical motor data)", "CLI",
           lambda: cli("gait", "--constrained", "--robot", "ant", "--backend", "native"),
           test="tests/test_gait_constraints.py::test_constrained_settings_errors")
    record("`make_gait_problem(constrained='yes')`", "API",
           lambda: make_gait_problem("nao", backend="native", constrained="yes"),
           test="tests/test_bad_input_rows.py::test_constrained_must_be_a_boolean")
    record("`eaco gait-eval G --stream validation`", "CLI",
           lambda: cli("gait-eval", "experiments/results/nao_best_gait.json", "--stream",
                       "validation"),
           test="tests/test_bad_input_rows.py::test_command_line_refusals_are_one_line")


def quality_diversity_rows() -> None:
    """MAP-Elites, QD problems and the gait library (issue 32)."""
    from eaco_jax.problems.gait_library import make_gait_library_problem
    from eaco_jax.problems.qd import rastrigin_proj
    from eaco_jax.strategies.islands import Islands
    from eaco_jax.strategies.map_elites import MAPElites

    rows = "tests/test_bad_input_rows.py::"
    held = "tests/test_map_elites.py::test_bad_configurations_get_one_line"
    toy = rastrigin_proj()
    record("`MAPElites(variation='cma')`", "API", lambda: MAPElites(variation="cma"), test=held)
    record("`MAPElites(grid=(0, 3))`", "API", lambda: MAPElites(grid=(0, 3)), test=held)
    record("`MAPElites(radius=0)`", "API", lambda: MAPElites(radius=0),
           test=rows + "test_map_elites_radius_and_colony_size_are_checked")
    record("`MAPElites(grid=(3, 3, 3))` on a problem of 2 descriptors (rastrigin_proj)", "API",
           lambda: MAPElites(grid=(3, 3, 3)).init(jax.random.key(0), toy), test=held)
    record("`MAPElites().init(key, problems.get('sphere'))` (not a QD problem)", "API",
           lambda: MAPElites().init(jax.random.key(0), ea.problems.get("sphere")), test=held)
    record("`ea.minimize(problems.get('sphere'), MAPElites())`", "API",
           lambda: ea.minimize(ea.problems.get("sphere"), MAPElites(num_ants=4, grid=(2, 2)),
                               iterations=2),
           test=rows + "test_map_elites_on_a_problem_of_another_kind")
    flipped = dataclasses.replace(toy, descriptor_lower=toy.descriptor_upper,
                                  descriptor_upper=toy.descriptor_lower)
    record("QD problem whose descriptor_lower > descriptor_upper", "API",
           lambda: MAPElites(num_ants=4, grid=(2, 2)).init(jax.random.key(0), flipped),
           test=rows + "test_gait_library_and_descriptor_ranges_are_checked")
    record("`Islands(MAPElites(), every=2)` (migration)", "API",
           lambda: Islands(MAPElites(num_ants=8, grid=(4, 4)), islands=2, every=2),
           test=rows + "test_map_elites_in_islands_without_migration_only")
    record("`make_gait_library_problem('go2')` (a quadruped)", "API",
           lambda: make_gait_library_problem("go2", backend="native", worlds=0),
           test=rows + "test_gait_library_and_descriptor_ranges_are_checked")
    record("`make_gait_library_problem(speed_range=(0.3, 0.1))`", "API",
           lambda: make_gait_library_problem(backend="native", worlds=0,
                                             speed_range=(0.3, 0.1)),
           test=rows + "test_gait_library_and_descriptor_ranges_are_checked")


def walk_rows() -> None:
    """``eaco walk`` (issue 32) and ``eaco gait-eval --thermal`` (issue 30)."""
    rows = "tests/test_bad_input_rows.py::"
    cli_test = rows + "test_sparse_tsp_walk_and_thermal_refusals_are_one_line"
    walls = [[[8.6, 4.5], [8.8, 4.5], [8.8, 5.65], [8.6, 5.65]],
             [[8.6, 6.35], [8.8, 6.35], [8.8, 7.5], [8.6, 7.5]],
             [[8.6, 4.5], [10.5, 4.5], [10.5, 4.7], [8.6, 4.7]],
             [[8.6, 7.3], [10.5, 7.3], [10.5, 7.5], [8.6, 7.5]]]
    gap = TMP / "gap.json"
    gap.write_text(json.dumps({
        "name": "gap", "bounds": [0, 0, 10, 10], "start": [0.5, 5], "goal": [9.5, 6],
        "clearance": 0.3, "obstacles": [{"polygon": w, "height": 1} for w in walls],
        "ramps": []}))
    record("`eaco walk scene.json`: goal behind a 0.7 m gap (open at the scene's clearance "
           "0.3 m, `eaco path` plans it; walled in at the 0.4 m walking clearance)", "CLI",
           lambda: cli("walk", str(gap), "--plan-iterations", "2", "--max-time", "1"),
           test=(rows + "test_walk_refuses_a_goal_walled_in_at_the_walking_clearance",
                 "tests/test_bad_input_rows_2.py::"
                 "test_walk_clearance_refusal_names_the_option_only_where_it_is_the_cause"))
    record("`eaco walk nosuch.json`", "CLI", lambda: cli("walk", "nosuch.json"),
           test=(cli_test, "tests/test_scenes.py::test_malformed_and_missing_files"))
    record("`eaco walk random:x`", "CLI", lambda: cli("walk", "random:x"), test=cli_test)
    controller = "tests/test_walk_route.py::test_bad_controller_settings_are_one_line"
    record("`eaco walk default --resume-deg 200` (above --turn-deg)", "CLI",
           lambda: cli("walk", "default", "--resume-deg", "200"), test=(cli_test, controller))
    record("`eaco walk default --turn-deg 270`", "CLI",
           lambda: cli("walk", "default", "--turn-deg", "270"), test=controller)
    record("`eaco walk default --slow-deg 130` (above --stop-deg 120)", "CLI",
           lambda: cli("walk", "default", "--slow-deg", "130"), test=controller)
    record("`eaco walk default --min-step 0`", "CLI",
           lambda: cli("walk", "default", "--min-step", "0"), test=controller)
    record("`eaco walk default --lookahead -1`", "CLI",
           lambda: cli("walk", "default", "--lookahead", "-1"), test=controller)
    record("`eaco walk default --goal-turn-deg 10` (not above --resume-deg)", "CLI",
           lambda: cli("walk", "default", "--goal-turn-deg", "10"),
           test="tests/test_walk_route.py::"
                "test_near_the_goal_the_controller_turns_on_the_spot_above_goal_turn_deg")
    record("`eaco gait-eval G --thermal` for the Go2 (no electrical motor data)", "CLI",
           lambda: cli("gait-eval", "experiments/results/go2_cpu_gait.json", "--thermal",
                       "--backend", "native", "--horizon", "1"),
           test=("tests/test_thermal_walk.py::test_thermal_needs_electrical_motor_data",
                 cli_test))


def sparse_tsp_rows() -> None:
    """``eaco tsp`` on the sparse path (issue 33) and instances too small for local search."""
    rows = "tests/test_bad_input_rows.py::"
    cli_test = rows + "test_sparse_tsp_walk_and_thermal_refusals_are_one_line"
    files = rows + "test_tsp_files_the_sparse_path_or_the_local_search_cannot_take"
    record("`eaco tsp eil51 --sparse maybe`", "CLI",
           lambda: cli("tsp", "eil51", "--sparse", "maybe"), test=cli_test)
    record("`eaco tsp eil51 --neighbors 0`", "CLI",
           lambda: cli("tsp", "eil51", "--neighbors", "0"), test=cli_test)

    def long_lists() -> str:
        dense = load_tsplib("eil51", neighbors=1000, sparse=False).neighbors.shape
        sparse = load_tsplib("eil51", neighbors=1000, sparse=True).neighbors.shape
        return f"accepted: candidate lists of every other city, {dense} dense, {sparse} sparse"
    record("`--neighbors 1000` on eil51 (51 cities)", "API", long_lists,
           test=rows + "test_candidate_lists_longer_than_the_other_cities_are_cut_to_them")
    record("`eaco tsp eil51 --max-new-edges 0`", "CLI",
           lambda: cli("tsp", "eil51", "--max-new-edges", "0"), test=cli_test)
    record("`eaco tsp eil51 --max-new-edges 5` (dense path)", "CLI",
           lambda: cli("tsp", "eil51", "--max-new-edges", "5", "--iterations", "2", "--quiet"),
           test=(cli_test, "tests/test_bad_input_rows_2.py::"
                 "test_max_new_edges_on_the_dense_path_names_the_cli_and_the_library_fix"))
    record("`eaco tsp eil51 --construction moves` (no --max-new-edges)", "CLI",
           lambda: cli("tsp", "eil51", "--construction", "moves", "--iterations", "2",
                       "--quiet"), test=cli_test)
    record("`eaco tsp eil51 --construction moves --max-new-edges 4` (dense path)", "CLI",
           lambda: cli("tsp", "eil51", "--construction", "moves", "--max-new-edges", "4",
                       "--iterations", "2", "--quiet"), test=cli_test)
    for args in (("--ls-focus-width", "-1"), ("--merge-ants", "1"),
                 ("--merge-ants", "4", "--iterations", "2"), ("--chunk-seconds", "-1"),
                 ("--chunk-seconds", "0.2", "--iterations", "5")):
        record(f"`eaco tsp eil51 {' '.join(args)}`", "CLI",
               lambda args=args: cli("tsp", "eil51", *args), test=cli_test)
    front = "tests/test_gait_front.py::test_bad_settings_are_one_line"
    record("`eaco gait-front --ants 1`", "CLI", lambda: cli("gait-front", "--ants", "1"),
           test=front)
    record("`eaco gait-front --robust -1`", "CLI", lambda: cli("gait-front", "--robust", "-1"),
           test=front)
    matrix = "\n".join(" ".join(str(0 if i == j else 7 * (i + j) + 3) for j in range(5))
                       for i in range(5))
    explicit = write_tsp("ex5.tsp", "NAME: ex5\nTYPE: TSP\nDIMENSION: 5\nEDGE_WEIGHT_TYPE: "
                         "EXPLICIT\nEDGE_WEIGHT_FORMAT: FULL_MATRIX\nEDGE_WEIGHT_SECTION\n"
                         f"{matrix}\nEOF\n")
    record("`eaco tsp ex5.tsp --sparse on` (EXPLICIT: a matrix, no coordinates)", "CLI",
           lambda: cli("tsp", explicit, "--sparse", "on"), test=files)
    record("`eaco tsp ex5.tsp` (5 cities, default local search or-2opt)", "CLI",
           lambda: cli("tsp", explicit, "--iterations", "2", "--quiet"), test=files)
    three = write_tsp("t3.tsp", "NAME: t3\nTYPE: TSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: EUC_2D\n"
                      "NODE_COORD_SECTION\n1 0 0\n2 10 0\n3 0 10\nEOF\n")
    record("`eaco tsp t3.tsp --local-search 2opt` (3 cities)", "CLI",
           lambda: cli("tsp", three, "--local-search", "2opt", "--iterations", "2", "--quiet"),
           test=files)
    huge = write_tsp("huge_xy.tsp", "NAME: huge\nTYPE: TSP\nDIMENSION: 4\nEDGE_WEIGHT_TYPE: "
                     "EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3000000000000 0\n"
                     "3 3000000000000 3000000000000\n4 0 3000000000000\nEOF\n")
    record("`eaco tsp huge.tsp --sparse on`: coordinates up to 3e12 (edges past 2**24)",
           "CLI",
           lambda: cli("tsp", huge, "--sparse", "on", "--local-search", "none"), test=files)


#: Interrupts and concurrent command-line runs (exercised in tests/test_interrupt.py, not
#: here): what was tried, what it gets, the test(s) holding it.
INTERRUPT_ROWS: list[tuple[str, str, str | tuple[str, ...]]] = [
    ("Ctrl-C while `eaco` still imports (jax, typer: the first second)", "exit 130: interrupted",
     "tests/test_interrupt.py::test_ctrl_c_while_the_command_imports_is_one_line"),
    ("Ctrl-C during compilation (`eaco tsp ... --checkpoint-dir D`)",
     "exit 130: interrupted (SIGINT) after 0 of 3000 iterations; nothing to save yet (start the "
     "same command again)", "tests/test_bad_input_rows.py::test_interrupt_lines_say_what_was_kept"),
    ("Ctrl-C / SIGTERM during a checkpointed run",
     "exit 130: interrupted (SIGINT) after 20 of 3000 iterations; checkpoint saved at step 20 in "
     "D; continue with: eaco resume D",
     "tests/test_interrupt.py::test_checkpointed_run_saves_and_says_how_to_resume"),
    ("Ctrl-C without checkpointing",
     "exit 130: interrupted (SIGINT) after N of M iterations; best so far: L (no checkpoint: "
     "pass --checkpoint-dir to resume)",
     "tests/test_bad_input_rows.py::test_interrupt_lines_say_what_was_kept"),
    ("the first SIGTERM (or Ctrl-C) during a long chunk",
     "at once: SIGTERM: stopping after the current chunk (iteration X); send again to stop now; "
     "at the chunk's end: exit 130: interrupted (SIGTERM) after X of M iterations; checkpoint "
     "saved ...",
     ("tests/test_interrupt.py::test_first_sigterm_during_a_long_chunk_says_so_at_once",
      "tests/test_interrupt.py::test_checkpointed_run_saves_and_says_how_to_resume")),
    ("a second `eaco tsp --checkpoint-dir D` while the first runs",
     "exit 2: error: checkpoint folder D is in use by another run (pid P since T); wait for it "
     "to finish or use another --checkpoint-dir",
     "tests/test_interrupt.py::test_second_run_on_the_same_folder_is_refused"),
]


def main() -> None:
    eil51 = load_tsplib("eil51")
    burma = load_tsplib("burma14")
    g = GraphEACO(num_ants=4, local_search="none")

    # ------------------------------------------------------------ budgets and reported numbers
    def budget(name: str, n: int) -> str:
        r = ea.minimize(ea.problems.cec2006(name), max_evaluations=n, seed=0)
        return f"charged {int(r.evaluations)} <= {n}; stop_reason={r.stop_reason}"
    record("`minimize(cec2006('g06'), max_evaluations=5000)`", "API", lambda: budget("g06", 5000),
           test="tests/test_trust.py::test_max_evaluations_is_a_hard_cap_with_repair_and_refinement")
    record("`max_evaluations=50` (below one iteration's charge)", "API",
           lambda: ea.minimize(ea.problems.cec2006("g06"), max_evaluations=50),
           test="tests/test_trust.py::test_budget_below_one_iteration_names_the_charge")

    def unit_square() -> str:
        xy = np.random.default_rng(0).uniform(0, 1, (200, 2))
        r = ea.minimize(TSP.from_coords(xy), GraphEACO(num_ants=10), seed=0, iterations=20)
        return f"best_cost {float(r.best_cost):.3f} (real distances; was 0 with EUC_2D rounding)"
    record("`TSP.from_coords` on 200 points in the unit square", "API", unit_square,
           test="tests/test_trust.py::test_from_coords_keeps_real_distances_unless_a_rule_is_named")

    def long_tours() -> str:
        rng = np.random.default_rng(1)
        d = np.triu(rng.integers(500_000, 1_000_000, (60, 60)), 1)
        d = d + d.T
        p = TSP.from_distance_matrix(d)
        tours = np.stack([rng.permutation(60) for _ in range(200)])
        exact = np.array([d[t, np.roll(t, -1)].sum() for t in tours])
        return f"{int((p.evaluate(tours) != exact).sum())} of 200 tour lengths > 2**24 off"
    record("tours longer than 2**24 (integer distances)", "API", long_tours,
           test="tests/test_trust.py::test_long_integer_tours_are_exact")
    record("`TSP.evaluate` with a tour of 50 cities on eil51", "API",
           lambda: eil51.evaluate(np.arange(50)[None]),
           test="tests/test_trust.py::test_host_evaluate_refuses_non_tours")
    record("`TSP.evaluate` with city id 51 on eil51", "API",
           lambda: eil51.evaluate(np.r_[np.arange(50), 51][None]),
           test="tests/test_trust.py::test_host_evaluate_refuses_non_tours")
    record("distance matrix with integers >= 2**24", "API",
           lambda: TSP.from_distance_matrix(np.array([[0, 2**25, 1], [2**25, 0, 1], [1, 1, 0]])),
           test="tests/test_trust.py::test_host_evaluate_refuses_non_tours")

    def vessel():
        def f(x):
            return (0.6224 * x[0] * x[2] * x[3] + 1.7781 * x[1] * x[2] ** 2
                    + 3.1661 * x[0] ** 2 * x[3] + 19.84 * x[0] ** 2 * x[2])

        def gg(x):
            return jnp.stack([-x[0] + 0.0193 * x[2], -x[1] + 0.00954 * x[2],
                              -jnp.pi * x[2] ** 2 * x[3] - 4 / 3 * jnp.pi * x[2] ** 3 + 1296000.0,
                              x[3] - 240.0])
        return ConstrainedProblem(f, gg, lower=[0.0625, 0.0625, 10, 10],
                                  upper=[6.1875, 6.1875, 200, 200], name="vessel")

    def vessel32() -> str:
        r = ea.minimize(vessel(), seed=0, max_evaluations=20_000, precision="float32")
        return (f"f={float(r.f):.4f} violation={float(r.violation):.3g} "
                f"feasible={bool(r.feasible)}")
    record("pressure vessel in float32 (`precision='float32'`)", "API", vessel32,
           test=("tests/test_trust.py::test_feasibility_is_rechecked_in_float64",
                 "tests/test_trust.py::test_recheck_refutes_a_point_feasible_only_in_float32"))

    def vessel_auto() -> str:
        r = ea.minimize(vessel(), seed=0, max_evaluations=20_000)
        return (f"precision={r.precision} f={float(r.f):.4f} violation={float(r.violation):.3g} "
                f"feasible={bool(r.feasible)}")
    record("pressure vessel, default precision", "API", vessel_auto,
           test="tests/test_trust.py::test_feasibility_is_rechecked_in_float64")

    def mixed() -> object:
        with ea.problems.float64():
            p = ea.problems.cec2006("g06")
        return ea.minimize(p, seed=0, max_evaluations=500, precision="float32")
    record("problem built in `float64()`, run with `precision='float32'`", "API", mixed,
           test="tests/test_trust.py::test_float64_problem_keeps_float64_outside_the_scope")

    def outside64() -> str:
        with ea.problems.float64():
            p = ea.problems.cec2006("g06")
        r = ea.minimize(p, seed=0, max_evaluations=500)
        return f"precision={r.precision} (kept float64 outside the scope)"
    record("problem built in `float64()`, run outside it", "API", outside64,
           test="tests/test_trust.py::test_float64_problem_keeps_float64_outside_the_scope")
    record("objective NaN everywhere", "API", lambda: ea.minimize(ConstrainedProblem(
        lambda x: jnp.nan * x[0], lower=[0.0, 0.0], upper=[1.0, 1.0], name="broken"),
        seed=0, iterations=4),
           test="tests/test_trust.py::test_all_nan_objective_is_an_error_naming_it")

    # ------------------------------------------------------------ hyper-parameters
    for field, value in (("rho", 1.5), ("q0", 1.5), ("alpha", -1.0), ("beta", float("nan"))):
        record(f"`GraphEACO` with `{field}={value}`", "API", lambda f=field, v=value: ea.minimize(
            burma, g, params=g.default_params(burma).replace(**{f: v}), iterations=2),
               test="tests/test_trust.py::test_graph_params_outside_their_range_are_one_line")
    record("`--params q0=1.5`", "CLI", lambda: cli("tsp", "burma14", "--params", "q0=1.5"),
           test="tests/test_trust.py::test_cli_version_info_params_and_budget_flags")
    record("`--params bogus=1`", "CLI", lambda: cli("tsp", "burma14", "--params", "bogus=1"),
           test="tests/test_cli_first_hour.py::test_gait_params_are_checked")
    record("`--params q0=abc`", "CLI", lambda: cli("tsp", "burma14", "--params", "q0=abc"),
           test="tests/test_bad_input_rows.py::test_command_line_refusals_are_one_line")
    record("`--params rho=0.1` (no LS defaults: rho unused)", "CLI",
           lambda: cli("tsp", "burma14", "--local-search", "none", "--iterations", "3",
                       "--quiet", "--params", "rho=0.1"),
           test="tests/test_cli_first_hour.py::test_params_without_effect_are_refused_by_single_runs")
    from eaco_jax.sweep import plan
    base = {"command": "tsp", "args": {"instance": "burma14", "ants": 4, "iterations": 2,
                                       "local_search": "none"}, "seeds": 1}
    record("sweep cell `{q0: 1.5}`", "sweep", lambda: plan({**base, "cells": [{"q0": 1.5}]}),
           test="tests/test_trust.py::test_sweep_cells_checked_against_ranges_naming_the_cell")
    record("sweep cell `{bogus_key: 1}`", "sweep",
           lambda: plan({**base, "cells": [{"bogus_key": 1}]}),
           test="tests/test_trust.py::test_sweep_cells_checked_against_ranges_naming_the_cell")
    record("sweep cell `{q0: abc}`", "sweep", lambda: plan({**base, "cells": [{"q0": "abc"}]}),
           test="tests/test_trust.py::test_sweep_cells_checked_against_ranges_naming_the_cell")
    record("sweep cell `{ants: abc}`", "sweep",
           lambda: plan({**base, "cells": [{"ants": "abc"}]}),
           test="tests/test_trust.py::test_sweep_cells_checked_against_ranges_naming_the_cell")
    record("sweep `rho` over 0.05/0.2/0.5 with default switches", "sweep",
           lambda: plan({**base, "grid": {"rho": [0.05, 0.2, 0.5]}}),
           test="tests/test_trust.py::test_sweeping_an_unused_param_is_refused_naming_the_switch")
    record("sweep seeds `[-1]`", "sweep", lambda: plan({**base, "seeds": [-1]}),
           test="tests/test_bad_input_rows.py::test_sweep_seed_outside_the_key_range_is_refused")

    # ------------------------------------------------------------ command line values
    record("`--seed 99999999999999999999`", "CLI",
           lambda: cli("tsp", "burma14", "--seed", "99999999999999999999"),
           test="tests/test_trust.py::test_cli_version_info_params_and_budget_flags")
    record("`--ants 1000000000`", "CLI", lambda: cli("tsp", "eil51", "--ants", "1000000000"),
           test="tests/test_trust.py::test_cli_version_info_params_and_budget_flags")
    record("`--ants 0`", "CLI", lambda: cli("tsp", "burma14", "--ants", "0"),
           test="tests/test_cli_gait.py::test_bad_input_is_a_one_line_error")
    record("`--max-seconds -1`", "CLI", lambda: cli("tsp", "burma14", "--max-seconds", "-1"),
           test="tests/test_bad_input_rows.py::test_command_line_refusals_are_one_line")
    clock = "tests/test_tsp_clock.py::"
    record("`eaco tsp --clock call` without `--max-seconds`", "CLI",
           lambda: cli("tsp", "burma14", "--clock", "call"),
           test=clock + "test_the_command_refuses_a_call_clock_without_budget_in_one_line")
    record("`minimize(..., deadline=nan)`", "API",
           lambda: ea.minimize(ea.problems.get("burma14"), iterations=2, deadline=float("nan")),
           test=clock + "test_bad_deadlines_are_refused")
    record("`runs.tsp.run(..., started_at=nan)` with `clock='call'`", "API",
           lambda: _tsp_run_started_at(float("nan")),
           test=clock + "test_bad_started_at_is_refused")
    record("`--max-evaluations 2` on tsp", "CLI",
           lambda: cli("tsp", "burma14", "--max-evaluations", "2"),
           test="tests/test_trust.py::test_budget_below_one_iteration_names_the_charge")
    outfile = TMP / "result.json"
    outfile.write_text("{}")
    record("`--out` pointing at an existing file", "CLI",
           lambda: cli("tsp", "burma14", "--out", str(outfile)),
           test="tests/test_interrupt.py::test_out_pointing_at_a_file_is_refused_before_the_run")
    record("`--checkpoint-every 5` without `--checkpoint-dir`", "CLI",
           lambda: cli("tsp", "burma14", "--checkpoint-every", "5"),
           test="tests/test_bad_input_rows.py::test_command_line_refusals_are_one_line")
    record("`eaco --version`", "CLI", lambda: cli("--version"),
           test="tests/test_trust.py::test_cli_version_info_params_and_budget_flags")
    record("`eaco resume /nonexistent`", "CLI", lambda: cli("resume", "/nonexistent"),
           test="tests/test_checkpoint.py::test_eaco_resume_cli_continues_stored_run")
    record("`minimize(chunk_size=0)`", "API", lambda: ea.minimize(burma, g, chunk_size=0),
           test="tests/test_bad_input_rows.py::test_minimize_arguments_are_checked_before_a_run")
    record("`minimize(iterations=0)`", "API", lambda: ea.minimize(burma, g, iterations=0),
           test="tests/test_bad_input_rows.py::test_minimize_arguments_are_checked_before_a_run")
    record("`minimize(target=nan)`", "API", lambda: ea.minimize(burma, g, target=float("nan")),
           test="tests/test_bad_input_rows.py::test_minimize_arguments_are_checked_before_a_run")
    record("`minimize(precision='half')`", "API", lambda: ea.minimize(burma, g, precision="half"),
           test="tests/test_bad_input_rows.py::test_minimize_arguments_are_checked_before_a_run")

    # ------------------------------------------------------------ files
    record("TSPLIB `DIMENSION: 2000000000`", "file", lambda: load_tsplib(write_tsp(
        "huge.tsp", "NAME: huge\nDIMENSION: 2000000000\nEDGE_WEIGHT_TYPE: EUC_2D\n"
        "NODE_COORD_SECTION\n1 0 0\n2 1 1\n3 2 2\nEOF\n")),
           test="tests/test_trust.py::test_huge_dimension_refused_before_allocating")
    record("TSPLIB `DIMENSION: 2e9`", "file", lambda: load_tsplib(write_tsp(
        "huge2.tsp", "NAME: h\nDIMENSION: 2e9\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n"
        "1 0 0\nEOF\n")),
           test="tests/test_tsplib.py::test_malformed_files_raise_one_line_errors")
    record("TSPLIB with fewer rows than DIMENSION", "file", lambda: load_tsplib(write_tsp(
        "short.tsp", "NAME: s\nDIMENSION: 5\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n"
        "1 0 0\n2 1 1\n3 2 2\nEOF\n")),
           test="tests/test_tsplib.py::test_malformed_files_raise_one_line_errors")
    folder = TMP / "folder.tsp"
    folder.mkdir()
    record("a directory given as a `.tsp` file", "CLI", lambda: cli("tsp", str(folder)),
           test="tests/test_trust.py::test_huge_dimension_refused_before_allocating")
    record("a missing `.tsp` file", "CLI", lambda: cli("tsp", str(TMP / "missing.tsp")),
           test=("tests/test_cli_tsp.py::test_malformed_and_missing_files_are_one_line_errors",
                 "tests/test_tsplib.py::test_missing_file"))
    gait_file = TMP / "gait.json"

    def bad_gait() -> str:
        from eaco_jax.problems.gait import make_gait_problem
        p = make_gait_problem("nao", backend="native", horizon=0.5)
        params = {n: float(v) for n, v in zip(p.param_names, np.asarray(
            (p.lower + p.upper) / 2), strict=True)}
        params["step_length"] = 50.0
        gait_file.write_text(json.dumps({"robot": "nao", "params": params}))
        return cli("gait-eval", str(gait_file), "--horizon", "0.5", "--quiet")
    record("gait file with `step_length: 50.0`", "CLI", bad_gait,
           test="tests/test_cli_gait.py::test_bad_input_is_a_one_line_error")

    # ------------------------------------------------------------ checkpoints
    ck = TMP / "ck"

    def run_ck(**kw):
        return ea.minimize(burma, g, seed=0, iterations=20, chunk_size=5,
                           checkpointing=ea.Checkpointing(ck, **kw))
    run_ck(every=5, keep=5)
    record("resume with another `every` (10 instead of 5)", "API",
           lambda: f"accepted; stop_reason={run_ck(every=10).stop_reason}",
           test="tests/test_checkpoint.py::test_save_frequency_is_not_identity_and_saves_land_on_multiples")
    record("resume with another problem", "API", lambda: ea.minimize(
        load_tsplib("ulysses22"), g, seed=0, iterations=20,
        checkpointing=ea.Checkpointing(ck, every=5)),
           test="tests/test_checkpoint.py::test_foreign_checkpoint_refused_and_untouched")

    def flip() -> str:
        shutil.rmtree(ck / "20")
        # the step's merged array data (state/d/*; the per-process copies are not read)
        arrays = sorted(p for p in (ck / "15" / "state" / "d").iterdir() if p.is_file())
        data = bytearray(arrays[0].read_bytes())
        data[len(data) // 2] ^= 1
        arrays[0].write_bytes(bytes(data))
        r = run_ck(every=5, keep=5)
        moved = [p.name for p in (ck / "corrupt").iterdir()] if (ck / "corrupt").exists() else []
        return f"iterations={r.iterations}; moved aside: {moved}"
    record("one flipped byte in the newest checkpoint", "API", flip,
           test="tests/test_checkpoint.py::test_corrupt_step_moved_aside_and_resume_falls_back")

    def flip_history() -> str:
        shutil.rmtree(ck / "20")
        seg = sorted((ck / "history").glob("*.npz"))[-2]  # the segment step 15 ends with
        data = bytearray(seg.read_bytes())
        data[len(data) // 2] ^= 1
        seg.write_bytes(bytes(data))
        r = run_ck(every=5, keep=5)
        moved = sorted(p.name for p in (ck / "corrupt").iterdir())
        return f"iterations={r.iterations}; moved aside: {moved}"
    record("one flipped byte in the history log (`history/*.npz`)", "API", flip_history,
           test="tests/test_checkpoint.py::test_corrupt_history_segment_moved_aside_with_its_step")

    def locked() -> object:
        from eaco_jax.driver.checkpoint import _Lock
        lock = _Lock(ck)
        lock.acquire()
        try:
            return run_ck(every=5)
        finally:
            lock.release()
    record("a second run on the same checkpoint folder", "API", locked,
           test="tests/test_checkpoint.py::test_second_run_on_one_folder_is_refused")
    afile = TMP / "afile"
    afile.write_text("x")
    record("checkpoint folder that is a file", "API",
           lambda: ea.minimize(burma, g, checkpointing=ea.Checkpointing(afile)),
           test="tests/test_checkpoint.py::test_unwritable_checkpoint_folder_is_one_line")
    ro = TMP / "ro"
    ro.mkdir()
    os.chmod(ro, 0o500)
    note = "" if not os.access(ro, os.W_OK) else " (run as root: writable, not tested here)"
    record(f"read-only checkpoint folder{note}", "API",
           lambda: ea.minimize(burma, g, checkpointing=ea.Checkpointing(ro / "ck")).stop_reason,
           test="tests/test_checkpoint.py::test_unwritable_checkpoint_folder_is_one_line")

    # ------------------------------------------------------------ sweeps: sizes and types
    def sweep_file(name: str, body: str) -> str:
        path = TMP / name
        path.write_text(body)
        return str(path)

    record("sweep cell `{q0: [0.5, 0.6]}` (a list value)", "sweep", lambda: cli(
        "sweep", sweep_file("list.yaml", "command: tsp\nargs: {instance: burma14}\n"
                            "cells: [{q0: [0.5, 0.6]}]\n")),
           test="tests/test_sweep.py::test_list_valued_cell_refused_before_anything_is_built")
    record("sweep file of nested YAML aliases (602 bytes, 10**10 leaves)", "sweep", lambda: cli(
        "sweep", sweep_file("bomb.yaml", "command: tsp\n" + "".join(
            f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else '0'] * 10)}]\n"
            for i in range(10)) + "cells: [{q0: *l9}]\n")),
           test="tests/test_sweep.py::test_yaml_alias_bomb_refused_fast_in_little_memory")
    record("sweep grid of 9 keys x 10 values (10**9 cells)", "sweep", lambda: cli(
        "sweep", sweep_file("grid.yaml", "command: tsp\nargs: {instance: burma14}\ngrid: {"
                            + ", ".join(f"k{i}: [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]" for i in range(9))
                            + "}\n")),
           test="tests/test_sweep.py::test_cell_count_is_bounded_before_any_product")
    record("sweep `seeds: 1048576`", "sweep", lambda: cli(
        "sweep", sweep_file("seeds.yaml", "command: tsp\nargs: {instance: burma14}\n"
                            "seeds: 1048576\n")),
           test="tests/test_sweep.py::test_seeds_at_most_what_runs_and_rows_estimated_before_setup")

    # ------------------------------------------------------------ the compiled-program cache
    from eaco_jax.driver import minimize as driver_mod
    from eaco_jax.driver import program_cache

    class Payload:
        """Unpickling this creates ``path`` (what a hostile entry would run)."""

        def __init__(self, path: Path) -> None:
            self.path = str(path)

        def __reduce__(self) -> tuple:
            return (open, (self.path, "w"))

    def tampered(how: str) -> str:
        folder = TMP / "programs" / how
        program_cache.set_folder(folder)
        try:
            driver_mod.clear_compiled()
            clean = ea.minimize(eil51, g, seed=0, iterations=8, chunk_size=4)
            init, chunk = sorted(folder.glob("*.jaxexport"), key=lambda p: p.stat().st_size)
            marker = TMP / "programs" / "pwned"
            if how == "pickle":
                chunk.write_bytes(pickle.dumps(Payload(marker)))
            elif how == "bit":
                raw = bytearray(chunk.read_bytes())
                raw[len(raw) - 1000] ^= 0x01
                chunk.write_bytes(bytes(raw))
            else:
                a, b = init.read_bytes(), chunk.read_bytes()
                init.write_bytes(b)
                chunk.write_bytes(a)
            driver_mod.clear_compiled()
            again = ea.minimize(eil51, g, seed=0, iterations=8, chunk_size=4)
            return (f"best_cost {float(again.best_cost):g} (clean {float(clean.best_cost):g})"
                    + ("; payload ran" if marker.exists() else ""))
        finally:
            program_cache.set_folder(None)
            driver_mod.clear_compiled()
    record("program cache entry replaced by a pickle whose `__reduce__` creates a file", "file",
           lambda: tampered("pickle"),
           test="tests/test_program_cache.py::test_a_pickled_entry_is_never_unpickled")
    record("one flipped bit in a program cache entry", "file", lambda: tampered("bit"),
           test="tests/test_program_cache.py::test_one_flipped_bit_is_caught_by_the_digest")
    record("program cache entries of the initialiser and the chunk swapped by name", "file",
           lambda: tampered("swap"),
           test="tests/test_program_cache.py::test_an_entry_of_another_program_under_this_name_is_rebuilt")
    cache_file = TMP / "cache_file"
    cache_file.write_text("x")

    def cache_is_file() -> str:
        res = RUNNER.invoke(app, ["tsp", "--help"], env={"EACO_COMPILE_CACHE": str(cache_file)})
        return f"exit {res.exit_code} (the command runs without the cache)"
    record("`EACO_COMPILE_CACHE` naming a file", "CLI", cache_is_file,
           test="tests/test_program_cache.py::test_a_compile_cache_that_is_a_file_is_said_once")

    checkpoint_folder_rows(burma, g)

    first_hour_rows()

    robot_spec_rows()

    limits_rows()

    leg_ik_rows()  # generic leg IK (gait)

    multiobjective_rows()  # multi-objective mode (issue 30)

    scene_rows()  # scenes and walking-time routes (issue 32)

    constrained_gait_rows()  # constrained gait search and world streams (issue 30)

    quality_diversity_rows()  # MAP-Elites, QD problems, the gait library (issue 32)

    walk_rows()  # eaco walk (issue 32), gait-eval --thermal (issue 30)

    sparse_tsp_rows()  # the sparse TSP path (issue 33), instances too small for local search

    walk_options_and_scripts_rows()  # eaco walk --impl/--motors, the large-TSP scripts

    steered_and_mo_gait_rows()  # the steered and the multi-objective gait problems' settings

    lines = [
        "# Bad inputs and faults, and what each gets now",
        "",
        "Generated by `python experiments/bad_inputs.py` (each row was run; the message is the",
        "first thing the user sees: the one-line error, the warning, or the result fields).",
        "Interrupts (Ctrl-C, SIGTERM) and two concurrent command-line runs are exercised in",
        "`tests/test_interrupt.py`; their messages are listed at the end.",
        "",
        "The last column names the test(s) in `tests/` that fail if the row's behaviour",
        "regresses (`none`: no test holds it yet).",
        "",
        "| tried | via | what it gets now | held by |",
        "|---|---|---|---|",
        *[f"| {w} | {h} | {t} | {b} |" for w, h, t, b in ROWS],
        *[f"| {w} | CLI | {t} | {held_by(b)} |" for w, t, b in INTERRUPT_ROWS],
        "",
    ]
    out = Path(__file__).resolve().parent.parent / "docs" / "bad_inputs.md"
    out.write_text("\n".join(lines))
    print(f"{len(ROWS) + len(INTERRUPT_ROWS)} rows -> {out}")



def scene_rows() -> None:
    """Scenes for walking-time route planning (issue 32): bad scene files through the CLI."""
    base = {"name": "s", "bounds": [0, 0, 10, 10], "start": [0.5, 5], "goal": [9.5, 6],
            "clearance": 0.3, "obstacles": [{"polygon": [[4, 4], [6, 4], [6, 6], [4, 6]],
                                             "height": 0.5}], "ramps": []}

    def scene(name: str, **change: object) -> str:
        f = TMP / f"scene_{name}.json"
        f.write_text(json.dumps({**base, **change}))
        return cli("path", "--scene", str(f), "--iterations", "2", "--ants", "4", "--quiet")

    walls = [{"polygon": [[8.6, 4.5], [8.8, 4.5], [8.8, 7.5], [8.6, 7.5]], "height": 1},
             {"polygon": [[8.6, 4.5], [10.5, 4.5], [10.5, 4.7], [8.6, 4.7]], "height": 1},
             {"polygon": [[8.6, 7.3], [10.5, 7.3], [10.5, 7.5], [8.6, 7.5]], "height": 1}]
    record("scene: goal inside an obstacle", "CLI", lambda: scene("goal", goal=[5, 5]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: start on an obstacle (within the clearance)", "CLI",
           lambda: scene("start", start=[3.8, 5]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: goal walled in (unreachable)", "CLI", lambda: scene("walled", obstacles=walls),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: obstacle polygon that crosses itself (a bow tie)", "CLI",
           lambda: scene("bowtie", obstacles=[{"polygon": [[0, 0], [2, 2], [2, 0], [0, 2]],
                                               "height": 1}]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: non-convex obstacle", "CLI",
           lambda: scene("concave", obstacles=[{"polygon": [[3, 3], [7, 3], [5, 4], [5, 7]],
                                                "height": 1}]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: ramp steeper than the gait table (12 deg)", "CLI",
           lambda: scene("steep", ramps=[{"polygon": [[1, 7], [3, 7], [3, 9], [1, 9]],
                                          "slope_deg": 12}]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    record("scene: start off the floor", "CLI", lambda: scene("off", start=[11, 5]),
           test="tests/test_scenes.py::test_bad_scenes_get_one_line")
    broken = TMP / "scene_broken.json"
    broken.write_text('{"bounds": [0, 0, 10, 10], ')
    record("scene file that is not valid JSON", "CLI",
           lambda: cli("path", "--scene", str(broken), "--quiet"),
           test="tests/test_scenes.py::test_malformed_and_missing_files")
    record("`eaco path --scene missing.json`", "CLI",
           lambda: cli("path", "--scene", str(TMP / "missing.json"), "--quiet"),
           test="tests/test_scenes.py::test_malformed_and_missing_files")


def leg_ik_rows() -> None:
    """Generic leg IK (issue 31): a leg chain that is not one, the analytic IK without the
    NAO's leg geometry."""
    from eaco_jax.gait import ik_generic, walk_engine
    from eaco_jax.gait.robot import load_model, load_robot

    record("a leg chain whose foot is not below the torso body (ik_generic.extract_chain)",
           "API", lambda: ik_generic.extract_chain(load_model(load_robot("nao")), "l_foot",
                                                   "r_foot"),
           test="tests/test_ik_generic.py::test_bad_leg_chains_are_one_line")
    record("walk engine ik='analytic' for a robot without the NAO's leg geometry (op3)", "API",
           lambda: walk_engine.joint_targets(jnp.zeros(14), jnp.float32(0.0),
                                             load_robot("op3"), ik="analytic"),
           test=("tests/test_ik_generic.py::test_analytic_without_geometry_is_refused",
                 "tests/test_robot_gaits.py::test_problem_controls_use_its_ik"))
    # Menagerie robots through the walk engines (issue 31): spec feet / arm swing, --ik, penalty
    from eaco_jax.gait.robot import ROBOTS_DIR

    def op3_spec(**fields: object) -> str:
        raw = json.loads((ROBOTS_DIR / "op3.json").read_text())
        raw.update(xml=str(ROBOTS_DIR / raw["xml"]), **fields)
        path = TMP / "op3_mine.json"
        path.write_text(json.dumps(raw))
        return str(path)

    op3_tiny = ["--backend", "native", "--ants", "4", "--iterations", "1", "--horizon", "0.5",
                "--no-video", "--out", str(TMP / "op3_out")]
    record("robot spec whose `feet` names a body the MJCF lacks", "file",
           lambda: cli("gait", "--robot", op3_spec(feet=["l_toe", "r_ank_roll_link"]),
                       *op3_tiny),
           test="tests/test_robot_gaits.py::test_bad_feet_and_arm_fields_are_one_line")
    record("robot spec whose `arm_swing_joints` names a joint not in joint_names", "file",
           lambda: cli("gait", "--robot", op3_spec(arm_swing_joints=["l_sho_pitch", "r_arm"]),
                       *op3_tiny),
           test="tests/test_robot_gaits.py::test_bad_feet_and_arm_fields_are_one_line")
    record("robot spec whose `arm_swing_joints` turn about the wrong axis (shoulder roll)",
           "file", lambda: cli("gait", "--robot", op3_spec(
               arm_swing_joints=["l_sho_roll", "r_sho_roll"]), *op3_tiny),
           test="tests/test_robot_gaits.py::test_arm_swing_joint_must_turn_sideways")
    record("`eaco gait --robot op3 --ik analytic`", "CLI",
           lambda: cli("gait", "--robot", "op3", "--ik", "analytic", *op3_tiny),
           test="tests/test_robot_gaits.py::test_problem_controls_use_its_ik")
    record("`eaco gait --robot ant --penalty cot` (no motor datasheet)", "CLI",
           lambda: cli("gait", "--robot", "ant", "--penalty", "cot", "--penalty-weight", "0.1",
                       *op3_tiny),
           test="tests/test_robot_gaits.py::test_robust_worlds_and_trials_without_a_motor_datasheet")


def limits_rows() -> None:
    """Limits (issue 28, round three): horizons past the step clock, colonies whose iteration
    does not fit, objectives that are +inf everywhere, 10,000 variables."""
    from eaco_jax.driver.minimize import check_state_memory
    from eaco_jax.runs import tsp as run_tsp
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    gait = TMP / "zero_gait.json"
    gait.write_text(json.dumps({"robot": "nao", "vector": [0.0] * 14}))
    record("`eaco gait-eval G --horizon 1e9` (5e10 control steps)", "CLI",
           lambda: cli("gait-eval", str(gait), "--backend", "native", "--horizon", "1e9"),
           test="tests/test_cli_gait.py::test_horizon_past_the_step_clock_is_refused_before_any_simulation")

    def tsp_200000() -> None:  # what minimize checks before it compiles anything
        built = run_tsp.build(run_tsp.TspSettings(instance="pr1002", ants=200000))
        check_state_memory(built.strategy, built.problem, 1, built.params)
    record("`eaco tsp pr1002 --ants 200000` (local search on the 25 shortest tours; the check "
           "minimize runs first)", "API", tsp_200000,
           test="tests/test_bad_input_rows.py::test_a_colony_whose_iteration_is_large_warns_before_it_runs")
    record("`eaco tsp pr1002 --ants 200000 --ls-best-k 200000` (local search on every tour)",
           "CLI", lambda: cli("tsp", "pr1002", "--ants", "200000", "--ls-best-k", "200000"),
           test="tests/test_trust.py::test_tsp_colony_whose_iteration_does_not_fit_is_refused_up_front")
    hungry = ConstrainedProblem(
        lambda x: jnp.cumsum(jnp.broadcast_to(x[0], (2**20, 2**19)), axis=0)[-1, 0],
        lower=[0.0, 0.0], upper=[1.0, 1.0], name="hungry")
    record("an objective whose evaluation allocates terabytes (XLA RESOURCE_EXHAUSTED in a chunk)",
           "API",
           lambda: ea.minimize(hungry, ContinuousEACO(num_ants=2, refine_ants=0), seed=0,
                               iterations=1),
           test="tests/test_trust.py::test_out_of_memory_in_a_chunk_is_one_line")

    def all_inf() -> str:
        p = ConstrainedProblem(lambda x: jnp.inf * (1.0 + x[0] ** 2), lower=[0.0, 0.0],
                               upper=[1.0, 1.0], name="flat")
        res = ea.minimize(p, seed=0, iterations=4)
        return f"f={res.f} feasible={res.feasible}"
    record("an objective that is +inf everywhere", "API", all_inf,
           test="tests/test_trust.py::test_infinite_objective_everywhere_is_not_feasible_and_warns")

    def wide() -> None:  # what minimize checks before it compiles anything
        p = ConstrainedProblem(lambda x: jnp.sum(x ** 2), lower=[-1.0] * 10000,
                               upper=[1.0] * 10000, name="wide")
        s = ContinuousEACO()
        check_state_memory(s, p, 1, s.default_params(p))
    record("a 10,000-variable problem with the default ContinuousEACO (the check minimize "
           "runs first)", "API", wide,
           test="tests/test_trust.py::test_large_continuous_problem_warns_and_refuses_by_its_hessians")


def first_hour_rows() -> None:
    """The first hour of a new user: the command line's usage errors, --params on every
    search command, tell on a continuous strategy (issue 28)."""
    import jax

    from eaco_jax.problems import functions
    from eaco_jax.strategies import ContinuousEACO

    record("`eaco gait --params q0=0.5` (4 ants, 1 iteration, 0.5 s)", "CLI", lambda: cli(
        "gait", "--backend", "native", "--ants", "4", "--iterations", "1", "--horizon", "0.5",
        "--no-video", "--params", "q0=0.5", "--out", str(TMP / "gait_q0")),
           test="tests/test_cli_first_hour.py::test_gait_params_reach_the_colony")
    record("`eaco gait --params p_repair=0.5` (gait has no gradient repair)", "CLI",
           lambda: cli("gait", "--params", "p_repair=0.5"),
           test="tests/test_cli_first_hour.py::test_gait_params_without_effect_name_nothing_gait_cannot_set")
    record("`eaco constrained g06 --repair-steps 0 --params p_repair=0.3`", "CLI",
           lambda: cli("constrained", "g06", "--repair-steps", "0", "--params", "p_repair=0.3"),
           test="tests/test_cli_first_hour.py::test_params_without_effect_are_refused_by_single_runs")
    record("`eaco tsp burma14 --bogus 1` (an option no command has)", "CLI",
           lambda: cli("tsp", "burma14", "--bogus", "1"),
           test="tests/test_cli_first_hour.py::test_usage_errors_are_one_line_naming_the_help")
    record("`eaco resume` (no folder)", "CLI", lambda: cli("resume"),
           test="tests/test_cli_first_hour.py::test_usage_errors_are_one_line_naming_the_help")
    record("`eaco tsp burma14 --ants many`", "CLI", lambda: cli("tsp", "burma14", "--ants",
                                                                 "many"),
           test="tests/test_cli_first_hour.py::test_usage_errors_are_one_line_naming_the_help")

    def tell_plain_costs() -> object:
        problem = functions.sphere()
        strategy = ContinuousEACO(num_ants=4, archive_size=6, refine_ants=0, repair_steps=0)
        state = strategy.init(jax.random.key(0), problem)
        x, state = strategy.ask(jax.random.key(1), state, problem)
        return strategy.tell(state, x, np.sum(np.asarray(x) ** 2, axis=1), problem)
    record("`ContinuousEACO.tell(state, x, numpy_costs, problem)` (no ea.Evaluation)", "API",
           tell_plain_costs,
           test="tests/test_cli_first_hour.py::test_continuous_tell_with_plain_costs_names_evaluation")


def checkpoint_folder_rows(burma: object, g: object) -> None:
    """History log, checkpoint folders and full disks (issue 28)."""
    import errno

    def run_in(folder: Path, iterations: int, every: int) -> object:
        return ea.minimize(burma, g, seed=0, iterations=iterations, chunk_size=5,
                           checkpointing=ea.Checkpointing(folder, every=every))

    older = TMP / "older"

    def fresh_over_older() -> str:
        run_in(older, 30, 10)
        for step in ("10", "20", "30"):
            shutil.rmtree(older / step)
        return f"iterations={run_in(older, 25, 5).iterations}"
    record("fresh run (every 5, 25 its) in a folder holding an older run's history segments "
           "(every 10, 30 its; its steps gone)", "API", fresh_over_older,
           test="tests/test_checkpoint.py::test_fresh_run_sets_an_earlier_runs_history_aside")

    corrupt = TMP / "allcorrupt"

    def resume_all_corrupt() -> str:
        cli("tsp", "burma14", "--ants", "4", "--iterations", "10", "--local-search", "none",
            "--quiet", "--checkpoint-dir", str(corrupt), "--checkpoint-every", "5")
        for step in (p for p in corrupt.iterdir() if p.name.isdigit()):
            for f in (p for p in (step / "state" / "d").iterdir() if p.is_file()):
                data = bytearray(f.read_bytes())
                data[len(data) // 2] ^= 1
                f.write_bytes(bytes(data))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cli("resume", str(corrupt))  # moves every step into corrupt/
        return cli("resume", str(corrupt))
    record("`eaco resume D` again after every checkpoint in D was corrupt", "CLI",
           resume_all_corrupt,
           test="tests/test_checkpoint.py::test_resume_after_every_checkpoint_was_corrupt_names_the_command")

    full = TMP / "full"

    def disk_full() -> object:
        real = os.fsync

        def fsync(fd: int) -> None:  # the disk refuses the history segment of step 20
            if "/history/.tmp-" in os.readlink(f"/proc/self/fd/{fd}") and \
                    "-10-20." in os.readlink(f"/proc/self/fd/{fd}"):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            real(fd)
        os.fsync = fsync
        try:
            return run_in(full, 20, 10)
        finally:
            os.fsync = real
    record("disk full during a save (ENOSPC injected at the history segment's fsync; a real "
           "full tmpfs in tests/test_checkpoint.py)", "API", disk_full,
           test=("tests/test_checkpoint.py::test_disk_full_during_a_save_is_one_line_and_resumes_bit_identically",
                 "tests/test_checkpoint.py::test_a_real_full_disk_during_a_save_is_one_line"))


def walk_options_and_scripts_rows() -> None:
    """``eaco walk``'s MJX implementation and motor model, the dense TSP path's distances from
    coordinates, and the large-TSP scripts (issue 33): an unknown instance, no LKH binary."""
    import contextlib
    import io

    rows2 = "tests/test_bad_input_rows_2.py::"
    record("`eaco walk default --backend mjx --impl warp` on a machine without CUDA", "CLI",
           lambda: cli("walk", "default", "--backend", "mjx", "--impl", "warp"),
           test=rows2 + "test_walk_warp_without_cuda_is_one_line_naming_impl_jax")
    record("`eaco walk default --motors dc` (an unknown motor model)", "CLI",
           lambda: cli("walk", "default", "--motors", "dc"),
           test=(rows2 + "test_walk_unknown_motor_model_is_one_line_naming_the_choices",
                 "tests/test_walk_motors.py::test_the_setting_is_the_specs_motor_model"))
    huge = write_tsp("huge_dense.tsp", "NAME: huge\nTYPE: TSP\nDIMENSION: 4\nEDGE_WEIGHT_TYPE: "
                     "EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3000000000000 0\n"
                     "3 3000000000000 3000000000000\n4 0 3000000000000\nEOF\n")
    rescale = rows2 + "test_too_large_distances_name_what_to_rescale"
    record("`eaco tsp huge.tsp --sparse off`: coordinates up to 3e12 on the dense path", "CLI",
           lambda: cli("tsp", huge, "--sparse", "off", "--local-search", "none"), test=rescale)
    record("`TSP.from_coords` of coordinates up to 3e12 (`metric='EUC_2D'`)", "API",
           lambda: TSP.from_coords(np.array([[0.0, 0.0], [3e12, 0.0], [3e12, 3e12]]),
                                   metric="EUC_2D"), test=rescale)

    import lkh_reference  # siblings: the script's folder is on the path when run as a script
    import tsp_large

    record("`experiments/tsp_large.py --sizes --instances no_such_instance`", "script",
           lambda: tsp_large.main(["--sizes", "--instances", "no_such_instance", "--work",
                                   str(TMP / "large"), "--out", str(TMP / "large.json")]),
           test="tests/test_lkh_reference.py::test_tsp_large_names_d15112_and_refuses_unknown_names")

    def no_lkh() -> str:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = lkh_reference.main(["--lkh", "no_lkh", "--work",
                                       str(TMP / "large"), "--out-dir", str(TMP / "lkh")])
        return f"exit {code}: {out.getvalue().strip()}"
    record("`experiments/lkh_reference.py --lkh no_lkh` (no such binary on PATH)", "script",
           no_lkh, test="tests/test_lkh_reference.py::test_absent_binary_skips_in_one_line")


def steered_and_mo_gait_rows() -> None:
    """The steered gait problem (``SteerConfig``, ``make_steered_problem``) and the
    multi-objective gait problem (``make_gait_mo_problem``): out-of-range or wrong-shaped
    settings."""
    from eaco_jax.gait.worlds import RobustConfig
    from eaco_jax.problems.gait_mo import make_gait_mo_problem
    from eaco_jax.problems.gait_steer import SteerConfig, make_steered_problem

    rows2 = "tests/test_bad_input_rows_2.py::"
    steer = rows2 + "test_steer_settings_are_one_line_naming_the_range"
    refusals = "tests/test_gait_steer.py::test_refusals"
    for field, value, held in (
            ("segments", 0, (steer, refusals)), ("error_deg", 200.0, steer),
            ("error_deg", [75.0], steer), ("stop_deg", float("nan"), steer),
            ("slow_deg", 130.0, (steer, refusals)), ("slow_deg", "15", steer),
            ("min_step", 1.5, (steer, refusals)), ("fall_cost", "x", steer),
            ("fall_cost", -1.0, steer)):
        record(f"`SteerConfig({field}={value!r})`", "API",
               lambda f=field, v=value: SteerConfig(**{f: v}), test=held)
    robust = RobustConfig(R=1)
    record("`make_steered_problem('nao')` without `robust`", "API",
           lambda: make_steered_problem("nao", backend="native"), test=refusals)
    record("`make_steered_problem('nao', turn='left', robust=...)`", "API",
           lambda: make_steered_problem("nao", backend="native", turn="left", robust=robust),
           test=refusals)
    record("`make_steered_problem('ant', robust=...)` (a quadruped)", "API",
           lambda: make_steered_problem("ant", backend="native", robust=robust), test=refusals)
    record("`make_steered_problem('nao', robust=..., steer={})`", "API",
           lambda: make_steered_problem("nao", backend="native", robust=robust, steer={}),
           test=refusals)
    record("`make_steered_problem('nao', robust=..., walker_physics='no')`", "API",
           lambda: make_steered_problem("nao", backend="native", robust=robust,
                                        walker_physics="no"),
           test=rows2 + "test_steer_takes_numpy_scalars_as_numbers_and_walker_physics_as_a_boolean")

    mo = "tests/test_gait_mo.py::test_mo_gait_settings_errors"
    record("`make_gait_mo_problem('nao', 'energy')`", "API",
           lambda: make_gait_mo_problem("nao", "energy", backend="native"), test=mo)
    record("`make_gait_mo_problem('nao', constrained=True)`", "API",
           lambda: make_gait_mo_problem("nao", backend="native", constrained=True), test=mo)
    record("`make_gait_mo_problem('ant')` (no electrical motor data)", "API",
           lambda: make_gait_mo_problem("ant", backend="native"), test=mo)
    problem = make_gait_mo_problem("nao", backend="native", horizon=0.2)
    report = rows2 + "test_mo_gait_report_names_the_shape_or_the_non_finite_values"
    record("MO gait `report` of 3 parameters (the NAO's gait has 14)", "API",
           lambda: problem.report(np.zeros(3)), test=report)
    record("MO gait `report` of 14 parameters, one NaN", "API",
           lambda: problem.report(np.r_[np.zeros(13), np.nan]), test=report)


if __name__ == "__main__":
    main()
    os._exit(0)

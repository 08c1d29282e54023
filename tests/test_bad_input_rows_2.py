"""Rows of docs/bad_inputs.md for ``eaco walk``'s MJX and motor options, the steered and the
multi-objective gait problems' settings, and messages that name the fix for the caller
(``--sparse on`` / ``sparse=True``, ``--clearance``, coordinates / matrix)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

import eaco_jax as ea
from eaco_jax.cli import app

RUNNER = CliRunner()


def _cli(*args: str) -> tuple[int, str]:
    res = RUNNER.invoke(app, ["--no-compile-cache", *args])
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    return res.exit_code, (lines[-1] if lines else "")


# ---------------------------------------------------------------- eaco walk: --impl, --motors
def test_walk_warp_without_cuda_is_one_line_naming_impl_jax():
    """MuJoCo Warp has no CPU path: refused before any planning, naming --impl jax."""
    from eaco_jax.gait.mjx_import import warp_usable

    if warp_usable():
        pytest.skip("this machine can run MuJoCo Warp")
    code, last = _cli("walk", "default", "--backend", "mjx", "--impl", "warp")
    assert code == 2 and last == ("error: impl 'warp' needs a CUDA GPU and warp-lang (pip "
                                  "install 'eaco-jax[gpu]'); use --impl jax"), last


def test_walk_unknown_motor_model_is_one_line_naming_the_choices():
    code, last = _cli("walk", "default", "--motors", "dc")
    assert code == 2 and last == "error: motors='dc' is not one of servo, spec", last


# ---------------------------------------------------------------- eaco walk: --clearance
def _gap_scene(path, gap: bool = True) -> str:
    """A goal behind a 0.7 m gap: open at clearance 0.3 m, walled in at 0.4 m (``gap=False``:
    no gap, walled in at any clearance)."""
    front = ([[[8.6, 4.5], [8.8, 4.5], [8.8, 5.65], [8.6, 5.65]],
              [[8.6, 6.35], [8.8, 6.35], [8.8, 7.5], [8.6, 7.5]]] if gap else
             [[[8.6, 4.5], [8.8, 4.5], [8.8, 7.5], [8.6, 7.5]]])
    walls = [*front,
             [[8.6, 4.5], [10.5, 4.5], [10.5, 4.7], [8.6, 4.7]],
             [[8.6, 7.3], [10.5, 7.3], [10.5, 7.5], [8.6, 7.5]]]
    path.write_text(json.dumps({
        "name": "gap", "bounds": [0, 0, 10, 10], "start": [0.5, 5], "goal": [9.5, 6],
        "clearance": 0.3, "obstacles": [{"polygon": w, "height": 1} for w in walls],
        "ramps": []}))
    return str(path)


def test_walk_clearance_refusal_names_the_option_only_where_it_is_the_cause(tmp_path):
    """Walled in only at the walk's --clearance: the message names --clearance; walled in at
    the scene's own clearance too: the scene's message alone; --clearance 0.3 plans it."""
    from eaco_jax.runs import walk

    gap = _gap_scene(tmp_path / "gap.json")
    with pytest.raises(ea.ProblemError) as err:
        walk.build(walk.WalkSettings(scene=gap))
    assert str(err.value).endswith(
        "lower the clearance (eaco walk plans at --clearance 0.4 m, above the scene's 0.3 m: "
        "pass a smaller --clearance, not below the NAO's half-width 0.25 m)"), err.value
    assert walk.build(walk.WalkSettings(scene=gap, clearance=0.3)).problem.scene.clearance \
        == pytest.approx(0.3)
    walled = _gap_scene(tmp_path / "walled.json", gap=False)
    with pytest.raises(ea.ProblemError) as err:
        walk.build(walk.WalkSettings(scene=walled))
    assert str(err.value) == ("gap: the goal cannot be reached from the start around these "
                              "obstacles; move an obstacle or lower the clearance"), err.value


# ---------------------------------------------------------------- TSP messages
def test_max_new_edges_on_the_dense_path_names_the_cli_and_the_library_fix():
    code, last = _cli("tsp", "eil51", "--max-new-edges", "5", "--iterations", "2", "--quiet")
    assert code == 2 and last == (
        "error: max_new_edges (focused construction) needs the sparse path (no distance "
        "matrix): pass --sparse on to eaco tsp, or sparse=True to load_tsplib"), last
    from eaco_jax.problems import load_tsplib
    from eaco_jax.strategies import GraphEACO

    sparse = load_tsplib("eil51", sparse=True)  # the fix the message names is taken
    assert GraphEACO(max_new_edges=5).prepare(sparse) is sparse


def test_too_large_distances_name_what_to_rescale(tmp_path):
    """Coordinates (a coordinate file on the dense path, TSP.from_coords) say coordinates;
    a matrix (TSP.from_distance_matrix, an EXPLICIT file) says matrix."""
    from eaco_jax.problems import TSP

    huge = tmp_path / "huge.tsp"
    huge.write_text("NAME: huge\nTYPE: TSP\nDIMENSION: 4\nEDGE_WEIGHT_TYPE: EUC_2D\n"
                    "NODE_COORD_SECTION\n1 0 0\n2 3000000000000 0\n"
                    "3 3000000000000 3000000000000\n4 0 3000000000000\nEOF\n")
    code, last = _cli("tsp", str(huge), "--sparse", "off", "--local-search", "none")
    assert code == 2 and last == ("error: integer distances >= 2**24 cannot be held exactly "
                                  "in float32; rescale the coordinates"), last
    xy = np.array([[0.0, 0.0], [3e12, 0.0], [3e12, 3e12], [0.0, 3e12]])
    with pytest.raises(ea.ProblemError, match="2\\*\\*24 .*; rescale the coordinates$"):
        TSP.from_coords(xy, metric="EUC_2D")
    big = np.array([[0, 2**25, 1], [2**25, 0, 1], [1, 1, 0]])
    with pytest.raises(ea.ProblemError, match="2\\*\\*24 .*; rescale the matrix$"):
        TSP.from_distance_matrix(big)
    with pytest.raises(ea.ProblemError, match="float32 sums; rescale the coordinates$"):
        TSP.from_coords([[0.0, 0.0], [0.5, 0.0], [1e38, 0.0]])
    explicit = tmp_path / "big3.tsp"
    rows = "\n".join(" ".join(str(int(v)) for v in row) for row in big)
    explicit.write_text("NAME: big3\nTYPE: TSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: EXPLICIT\n"
                        f"EDGE_WEIGHT_FORMAT: FULL_MATRIX\nEDGE_WEIGHT_SECTION\n{rows}\nEOF\n")
    with pytest.raises(ea.ProblemError, match="; rescale the matrix$"):
        ea.problems.load_tsplib(str(explicit))


# ---------------------------------------------------------------- steered gait settings
@pytest.mark.parametrize(("field", "value", "says"), [
    ("segments", 0, "steer segments must be an integer >= 1, got 0"),
    ("segments", True, "steer segments must be an integer >= 1, got True"),
    ("error_deg", 200.0, "steer error_deg must be <= 180 (a heading error wraps at 180), got "
                         "200.0"),
    ("error_deg", [75.0], "steer error_deg must be a finite number > 0, got [75.0]"),
    ("stop_deg", math.nan, "steer stop_deg must be a finite number > 0, got nan"),
    ("slow_deg", 130.0, "steer slow_deg must be in [0, stop_deg=120.0), got 130.0"),
    ("slow_deg", "15", "steer slow_deg must be a number, got '15'"),
    ("min_step", [0.5], "steer min_step must be a number, got [0.5]"),
    ("min_step", 1.5, "steer min_step must be in (0, 1], got 1.5"),
    ("fall_cost", "x", "steer fall_cost must be a number >= 0 or None, got 'x'"),
    ("fall_cost", -1.0, "steer fall_cost must be a finite number >= 0 or None, got -1.0"),
])
def test_steer_settings_are_one_line_naming_the_range(field, value, says):
    from eaco_jax.problems.gait_steer import SteerConfig

    with pytest.raises(ea.ProblemError) as err:
        SteerConfig(**{field: value})
    assert str(err.value) == says


def test_steer_takes_numpy_scalars_as_numbers_and_walker_physics_as_a_boolean():
    from eaco_jax.gait.worlds import RobustConfig
    from eaco_jax.problems.gait_steer import SteerConfig, make_steered_problem

    cfg = SteerConfig(segments=np.int64(4), error_deg=np.float32(30.0))
    assert (cfg.segments, cfg.error_deg) == (4, 30.0)
    assert json.loads(json.dumps({"segments": cfg.segments}))["segments"] == 4
    with pytest.raises(ea.ProblemError, match="walker_physics must be True or False, got 'no'"):
        make_steered_problem("nao", backend="native", robust=RobustConfig(R=1),
                             walker_physics="no")


# ---------------------------------------------------------------- multi-objective gait
def test_mo_gait_report_names_the_shape_or_the_non_finite_values():
    from eaco_jax.problems.gait_mo import make_gait_mo_problem

    problem = make_gait_mo_problem("nao", backend="native", horizon=0.2)
    with pytest.raises(ea.ProblemError, match=r"a gait needs 14 finite parameters, got shape "
                                              r"\(3,\)$"):
        problem.report(np.zeros(3))
    bad = np.zeros(problem.dim)
    bad[2] = np.nan
    with pytest.raises(ea.ProblemError, match="a gait needs 14 finite parameters, got NaN or "
                                              "infinite at index 2$"):
        problem.report(bad)


def test_every_one_gait_entry_names_the_non_finite_index_not_a_right_shape():
    """report, simulate, evaluate_trials and thermal_walk take one gait: a right-shaped vector
    with NaN or inf is refused by index, never as "got shape (14,)"."""
    from eaco_jax.gait.thermal_walk import thermal_walk
    from eaco_jax.gait.validate import evaluate_trials
    from eaco_jax.problems.gait import make_gait_problem

    plain = make_gait_problem("nao", backend="native", horizon=0.2)
    constrained = make_gait_problem("nao", backend="native", horizon=0.2, constrained=True)
    bad = np.zeros(14)
    bad[[0, 13]] = [np.inf, np.nan]
    calls = {"simulate": lambda p: plain.simulate(p), "report": constrained.report,
             "trials": lambda p: evaluate_trials(plain, p, n=1),
             "thermal": lambda p: thermal_walk(plain, p)}
    for what, call in calls.items():
        lead = "simulate" if what == "simulate" else "a gait"
        with pytest.raises(ea.ProblemError, match=rf"^{lead} needs 14 finite parameters, got NaN "
                                                  r"or infinite at index 0, 13$"):
            call(bad)
        with pytest.raises(ea.ProblemError, match=rf"^{lead} needs 14 finite parameters, got "
                                                  r"shape \(15,\)$"):
            call(np.zeros(15))

"""The LKH-3 reference of the large-TSP experiment (issue 33) and the shipped d15112.

CI has no LKH: these tests check the script's skip, its tour reading and length rule by hand,
that every stored LKH tour has the stored length on the instance regenerated from its seed
(so the file LKH solved is the file ``eaco tsp`` reads), how ``tsp_large.py`` scores a run,
and that d15112 ships with an optimum between its spanning tree and a tour.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from eaco_jax.errors import ProblemError

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"
LKH_RESULTS = EXPERIMENTS / "results" / "tsp_large" / "lkh"


@pytest.fixture
def scripts(monkeypatch):
    """``lkh_reference`` and ``tsp_large`` imported as their scripts import each other."""
    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    return importlib.import_module("lkh_reference"), importlib.import_module("tsp_large")


def test_absent_binary_skips_in_one_line(scripts, tmp_path, capsys):
    lkh, _ = scripts
    out = tmp_path / "results"
    assert lkh.main(["--lkh", str(tmp_path / "no_lkh"), "--sizes", "50", "--work",
                     str(tmp_path / "work"), "--out-dir", str(out)]) == 0
    printed = capsys.readouterr().out.strip().splitlines()
    assert len(printed) == 1 and "skipped" in printed[0] and "--lkh" in printed[0]
    assert not out.exists()


def test_tour_file_and_length_by_hand(scripts, tmp_path):
    lkh, _ = scripts
    # a 3-4-5 triangle and a point at (3, 0.6): edges 5, 4, 3 and nint(sqrt(9.36)) = 3
    (tmp_path / "t.tsp").write_text(
        "NAME : t\nTYPE : TSP\nDIMENSION : 4\nEDGE_WEIGHT_TYPE : EUC_2D\nNODE_COORD_SECTION\n"
        "1 0 0\n2 3 4\n3 3 0\n4 3 0.6\nEOF\n")
    (tmp_path / "t.tour").write_text(
        "NAME : t.tour\nTYPE : TOUR\nDIMENSION : 4\nTOUR_SECTION\n1\n2\n4\n3\n-1\nEOF\n")
    tour = lkh.read_tour(tmp_path / "t.tour", 4)
    assert tour.tolist() == [0, 1, 3, 2]
    # 1-2: 5, 2-4: nint(3.4) = 3, 4-3: nint(0.6) = 1, 3-1: 3
    assert lkh.tour_length(tmp_path / "t.tsp", tour) == 12
    (tmp_path / "bad.tour").write_text("TOUR_SECTION\n1\n2\n2\n3\n-1\n")
    with pytest.raises(ProblemError, match="permutation"):
        lkh.read_tour(tmp_path / "bad.tour", 4)


def test_lkh_output_is_parsed(scripts):
    lkh, _ = scripts
    text = ("Lower bound = 22744948.4, Ascent time = 0.36 sec.\nPreprocessing time = 0.36 sec.\n"
            "*** Time limit exceeded ***\nCost.min = 22912417, Cost.avg = 22912417.00\n"
            "Trials.min = 20, Trials.avg = 21.0, Trials.max = 22\n"
            "Time.min = 0.08 sec., Time.avg = 0.09 sec., Time.max = 0.10 sec.\n")
    got = lkh.parse_output(text)
    assert got == {"lower_bound": 22744948.4, "ascent_seconds": 0.36, "cost_min": 22912417.0,
                   "preprocessing_seconds": 0.36, "run_seconds": 0.08, "trials": 20.0,
                   "time_limit_hit": True}


def _stored() -> list[tuple[Path, dict]]:
    return [(p, json.loads(p.read_text())["rows"][0]) for p in sorted(LKH_RESULTS.glob("*.json"))]


def test_stored_lkh_tours_have_their_length_on_the_regenerated_instances(scripts, tmp_path):
    lkh, large = scripts
    stored = _stored()
    assert stored, "no LKH reference stored under experiments/results/tsp_large/lkh"
    checked = 0
    for path, row in stored:
        assert row["parameters"]["RUNS"] == 1
        assert row["parameters"]["CANDIDATE_SET_TYPE"] == "POPMUSIC"
        assert row["lkh_version"] and row["cpu_seconds"] > 0
        assert row["lkh_lower_bound"] <= row["length"]
        if row.get("optimum"):
            assert row["length"] >= row["optimum"]
        tour_file = path.with_suffix(".tour")
        if not tour_file.is_file():
            continue
        if row.get("instance_seed") is None:
            instance = large.find_file(row["instance"])
        else:
            instance = large.random_instance(tmp_path, row["n"], row["instance_seed"])
            # the file holds exactly the generator's integer coordinates
            from eaco_jax.problems.tsplib import read_tsplib

            xy = np.random.default_rng([row["n"], row["instance_seed"]]).integers(
                0, large.SIDE, (row["n"], 2))
            assert np.array_equal(read_tsplib(instance).coords, xy)
        tour = lkh.read_tour(tour_file, row["n"])
        assert lkh.tour_length(instance, tour) == row["length"], row["instance"]
        checked += 1
    assert checked >= 1
    assert large.reference_lengths() == {row["instance"]: row["length"] for _, row in stored}


def test_tsp_large_gap_is_against_the_optimum_or_lkh(scripts):
    _, large = scripts
    rand = large.score({"best_length": 101.0}, Path("rand10000_s0.tsp"), 10_000, None,
                       {"rand10000_s0": 100})
    assert rand["reference"] == "lkh-3" and rand["gap_percent"] == pytest.approx(1.0)
    assert rand["over_bhh_percent"] == pytest.approx(
        100 * (101 / (large.BHH * 100 * large.SIDE) - 1))
    named = large.score({"best_length": 1_588_815.0}, Path("d15112.tsp"), 15112, 1_573_084,
                        {"d15112": 1_580_000})
    assert named["reference"] == "optimum"
    assert named["gap_percent"] == pytest.approx(100 * (1_588_815 / 1_573_084 - 1))
    assert named["gap_to_lkh_percent"] == pytest.approx(100 * (1_588_815 / 1_580_000 - 1))
    assert "over_bhh_percent" not in named
    bare = large.score({"best_length": 5.0}, Path("rand20_s1.tsp"), 20, None, {})
    assert "gap_percent" not in bare and "over_bhh_percent" in bare
    failed = {"error": "boom"}
    assert large.score(dict(failed), Path("rand20_s1.tsp"), 20, None, {}) == failed


def test_tsp_large_names_d15112_and_refuses_unknown_names(scripts, tmp_path):
    _, large = scripts
    assert large.find_file("d15112").name == "d15112.tsp"
    assert large.known_optimum(large.find_file("d15112")) == 1_573_084
    with pytest.raises(SystemExit, match="no_such_instance: no such instance"):
        large.main(["--sizes", "--instances", "no_such_instance", "--out",
                    str(tmp_path / "r.json")])
    # a bad name is refused before the random instances are written (nothing to clean up)
    with pytest.raises(SystemExit, match="no_such_instance: no such instance"):
        large.main(["--sizes", "50", "--instances", "no_such_instance", "--work",
                    str(tmp_path / "work"), "--out", str(tmp_path / "r.json")])
    assert not (tmp_path / "work").exists() and not (tmp_path / "r.json").exists()


def test_d15112_ships_with_an_optimum_between_its_spanning_tree_and_a_tour():
    """The Euclidean minimum spanning tree lies on the Delaunay triangulation (and rounding
    keeps its order), so its length is a lower bound; a space-filling-curve tour is an upper
    one. A wrong optimum or garbled coordinates break a bound."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree
    from scipy.spatial import Delaunay

    import eaco_jax as ea
    from eaco_jax.ops.construction_sparse import hilbert_tour
    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.problems.tsplib import pair_distances, read_tsplib

    problem = load_tsplib("d15112")
    assert problem.n == 15112 and problem.optimum == 1_573_084
    assert ea.problems.get("d15112").optimum == 1_573_084
    inst = read_tsplib(ROOT / "eaco_jax" / "data" / "tsplib" / "large" / "d15112.tsp")
    xy = inst.coords
    tri = Delaunay(xy).simplices
    i = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2]])
    j = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0]])
    w = pair_distances(xy[i], xy[j], "EUC_2D") + 1e-9  # keep zero-length edges in the graph
    tree = minimum_spanning_tree(coo_matrix((w, (i, j)), shape=(len(xy),) * 2)).sum()
    tour = np.asarray(hilbert_tour(xy))
    curve = pair_distances(xy[tour], xy[np.roll(tour, -1)], "EUC_2D").sum()
    assert tree <= problem.optimum <= curve, (tree, curve)
    assert problem.optimum >= 1.05 * tree  # a tour beats its tree by a margin on d15112


def test_rescore_adds_the_lkh_gap_to_an_earlier_file(scripts, tmp_path):
    _, large = scripts
    earlier = {"command": "tsp_large.py --sizes 10000", "date": "2026-11-25", "info": {},
               "seeds": {"run_seeds": [0]},
               "rows": [{"instance": "rand10000_s0", "n": 10000, "seed": 0,
                         "best_length": 75_000_000},
                        {"instance": "d15112", "n": 15112, "seed": 0,
                         "best_length": 1_600_000},
                        {"instance": "rand10000_s0", "seed": 1, "error": "killed"}]}
    (tmp_path / "old.json").write_text(json.dumps(earlier))
    large.main(["--rescore", str(tmp_path / "old.json"), "--out", str(tmp_path / "new.json")])
    new = json.loads((tmp_path / "new.json").read_text())
    rand, d15112, failed = new["rows"]
    lkh = large.reference_lengths()["rand10000_s0"]
    assert rand["reference"] == "lkh-3"
    assert rand["gap_percent"] == pytest.approx(100 * (75_000_000 / lkh - 1))
    assert d15112["reference"] == "optimum"
    assert d15112["gap_percent"] == pytest.approx(100 * (1_600_000 / 1_573_084 - 1))
    assert "gap_percent" not in failed
    assert new["source"]["command"] == earlier["command"]

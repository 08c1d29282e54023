"""TSPLIB reader and distance rules: exact against known optima and hand computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp import DATA_DIR, bundled_instances, bundled_optima
from eaco_jax.problems.tsplib import coord_distances, distance_matrix, read_tsplib

# Canonical optimal tours from TSPLIB (1-based node ids), as space-separated strings.
OPT_TOURS = {
    "att48": [
        int(c)
        for c in (
            "1 8 38 31 44 18 7 28 6 37 19 27 17 43 30 36 46 33 20 47 21 32 39 48 5 42 24 10 "
            "45 35 4 26 2 29 34 41 16 22 3 23 14 25 13 11 12 15 40 9"
        ).split()
    ],
    "eil51": [
        int(c)
        for c in (
            "1 22 8 26 31 28 3 36 35 20 2 29 21 16 50 34 30 9 49 10 39 33 45 15 44 42 40 19 "
            "41 13 25 14 24 43 7 23 48 6 27 51 46 12 47 18 4 17 37 5 38 11 32"
        ).split()
    ],
    "kroA100": [
        int(c)
        for c in (
            "94 22 70 66 26 65 4 97 56 80 31 89 42 8 92 75 19 90 49 6 63 1 47 93 28 67 58 61 "
            "51 87 25 81 69 64 40 54 2 44 50 73 68 85 82 95 13 76 33 37 5 52 78 96 39 30 48 "
            "100 41 71 14 3 43 46 29 34 83 55 7 9 57 20 12 27 86 35 62 60 77 23 98 91 45 32 "
            "11 15 17 59 74 21 72 10 84 36 99 38 24 18 79 53 88 16"
        ).split()
    ],
}
# Lengths of the identity tour 1, 2, ..., n (TSPLIB95 lists pcb442's as 221440).
IDENTITY_LENGTHS = {"pcb442": 221440}


def _length(d: np.ndarray, tour_1based) -> int:
    t = np.asarray(tour_1based) - 1
    return int(d[t, np.roll(t, -1)].sum())


def _held_karp(d: np.ndarray) -> int:
    """Exact optimum by dynamic programming over subsets (n <= ~16)."""
    n = len(d)
    m = n - 1
    inf = np.iinfo(np.int64).max // 4
    cost = np.full((1 << m, m), inf, np.int64)
    for j in range(m):
        cost[1 << j, j] = d[0, j + 1]
    masks = np.arange(1 << m)
    pop = np.array([bin(x).count("1") for x in masks])
    for size in range(2, m + 1):
        subsets = masks[pop == size]
        for j in range(m):
            s = subsets[(subsets >> j) & 1 == 1]
            cost[s, j] = (cost[s ^ (1 << j)] + d[1:, j + 1][None, :]).min(1)
    return int((cost[-1] + d[1:, 0]).min())


def _load(name: str) -> np.ndarray:
    return distance_matrix(read_tsplib(DATA_DIR / f"{name}.tsp"))


@pytest.mark.parametrize("name", sorted(OPT_TOURS))
def test_canonical_optimal_tours_have_the_published_length(name):
    d = _load(name)
    assert sorted(OPT_TOURS[name]) == list(range(1, len(d) + 1))
    assert _length(d, OPT_TOURS[name]) == bundled_optima()[name]


def test_identity_tour_length_pcb442():
    d = _load("pcb442")
    assert _length(d, range(1, 443)) == IDENTITY_LENGTHS["pcb442"]


def test_burma14_geo_optimum_by_exact_dp():
    assert _held_karp(_load("burma14")) == 3323


def test_every_bundled_instance_reads_and_is_symmetric():
    names = bundled_instances()
    assert set(names) == set(bundled_optima())
    for name in names:
        inst = read_tsplib(DATA_DIR / f"{name}.tsp")
        d = distance_matrix(inst)
        assert d.dtype == np.int64 and d.shape == (inst.dimension, inst.dimension)
        assert inst.coords.shape == (inst.dimension, 2)
        assert np.array_equal(d, d.T) and np.all(np.diag(d) == 0)
        # the optimum is at least n times the smallest positive distance
        off = d[~np.eye(len(d), dtype=bool)]
        assert bundled_optima()[name] >= len(d) * off.min()


def test_every_bundled_optimum_lies_between_the_spanning_tree_and_a_greedy_tour():
    """A tour less one edge is a spanning tree, and no tour beats the optimum: a wrong optimum
    in optima.csv, or coordinates lost or garbled in a copied file, breaks one of the bounds."""
    from scipy.sparse.csgraph import minimum_spanning_tree

    from eaco_jax.problems.tsp import nearest_neighbour_tour

    for name, optimum in bundled_optima().items():
        d = distance_matrix(read_tsplib(DATA_DIR / f"{name}.tsp"))
        tree = minimum_spanning_tree(d.astype(np.float64)).sum()
        tour = nearest_neighbour_tour(d)
        greedy = int(d[tour, np.roll(tour, -1)].sum())
        assert tree <= optimum <= greedy, (name, tree, optimum, greedy)


def test_distance_rules_by_hand():
    xy = np.array([[0.0, 0.0], [3.0, 4.5], [10.0, 0.0]])
    # sqrt(9 + 20.25) = 5.408: EUC_2D rounds, CEIL_2D rounds up
    assert coord_distances(xy, "EUC_2D")[0, 1] == 5
    assert coord_distances(xy, "CEIL_2D")[0, 1] == 6
    # ATT: r = sqrt(100 / 10) = 3.1623, nint = 3 < r -> 4
    assert coord_distances(xy, "ATT")[0, 2] == 4
    # att48 cities 1 and 2 by hand
    att = read_tsplib(DATA_DIR / "att48.tsp").coords
    dx, dy = att[0] - att[1]
    r = math.sqrt((dx * dx + dy * dy) / 10.0)
    t = int(r + 0.5)
    assert distance_matrix(read_tsplib(DATA_DIR / "att48.tsp"))[0, 1] == (t + 1 if t < r else t)


def test_geo_rule_by_hand():
    # burma14 cities 1 (16.47, 96.10) and 2 (16.47, 94.44), TSPLIB95 formula with PI=3.141593
    pi, rrr = 3.141593, 6378.388

    def rad(v):
        deg = int(v)
        return pi * (deg + 5.0 * (v - deg) / 3.0) / 180.0

    la1, lo1, la2, lo2 = rad(16.47), rad(96.10), rad(16.47), rad(94.44)
    q1, q2, q3 = math.cos(lo1 - lo2), math.cos(la1 - la2), math.cos(la1 + la2)
    want = int(rrr * math.acos(0.5 * ((1 + q1) * q2 - (1 - q1) * q3)) + 1.0)
    assert _load("burma14")[0, 1] == want
    # negative coordinates truncate towards zero (ulysses22 city 11 has longitude -5.21)
    assert coord_distances(np.array([[36.08, -5.21], [36.08, 5.21]]), "GEO")[0, 1] > 0


def _write(tmp_path, text: str, name: str = "bad.tsp"):
    p = tmp_path / name
    p.write_text(text)
    return p


HEADER = "NAME : t\nTYPE : TSP\nDIMENSION : 3\nEDGE_WEIGHT_TYPE : {ewt}\n"


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "empty file"),
        ("\n\n  \n", "empty file"),
        (HEADER.format(ewt="EUC_3D") + "NODE_COORD_SECTION\n1 0 0 0\nEOF\n", "EUC_3D"),
        (HEADER.format(ewt="EUC_2D") + "EOF\n", "missing NODE_COORD_SECTION"),
        (HEADER.format(ewt="EUC_2D") + "NODE_COORD_SECTION\n1 0 0\n2 1 1\nEOF\n", "2 nodes"),
        (HEADER.format(ewt="EUC_2D") + "NODE_COORD_SECTION\n1 0 0\n2 1 x\n3 2 2\n", "non-numeric"),
        (HEADER.format(ewt="EUC_2D") + "NODE_COORD_SECTION\n1 0 0\n1 1 1\n3 2 2\n", "duplicate"),
        (HEADER.format(ewt="EUC_2D") + "NODE_COORD_SECTION\n1 0 0\n2 1 1\n7 2 2\n", "outside"),
        (HEADER.format(ewt="EUC_2D") + "NODE_COORD_SECTION\n1 0 0\n2 1 1\n3 nan 2\n", "non-fin"),
        ("NAME : t\nTYPE : ATSP\nDIMENSION : 3\n", "ATSP"),
        ("NAME : t\nTYPE : TSP\nEDGE_WEIGHT_TYPE : EUC_2D\n", "missing DIMENSION"),
        ("NAME : t\nDIMENSION : three\n", "not an integer"),
        ("this is not a tsplib file\n", "KEY : VALUE"),
    ],
)
def test_malformed_files_raise_one_line_errors(tmp_path, text, match):
    p = _write(tmp_path, text)
    with pytest.raises(ProblemError, match=match) as err:
        read_tsplib(p)
    msg = str(err.value)
    assert "\n" not in msg and str(p) in msg


def test_missing_file(tmp_path):
    with pytest.raises(ProblemError, match="no such"):
        read_tsplib(tmp_path / "nope.tsp")


def test_explicit_formats_agree(tmp_path):
    rng = np.random.default_rng(0)
    n = 5
    a = rng.integers(1, 50, (n, n))
    d = np.triu(a, 1) + np.triu(a, 1).T
    blocks = {
        "FULL_MATRIX": d,
        "UPPER_ROW": [d[i, i + 1 :] for i in range(n)],
        "LOWER_ROW": [d[i, :i] for i in range(n)],
        "UPPER_DIAG_ROW": [d[i, i:] for i in range(n)],
        "LOWER_DIAG_ROW": [d[i, : i + 1] for i in range(n)],
    }
    for fmt, rows in blocks.items():
        body = "\n".join(" ".join(str(int(v)) for v in row) for row in rows)
        text = (
            f"NAME : e\nTYPE : TSP\nDIMENSION : {n}\nEDGE_WEIGHT_TYPE : EXPLICIT\n"
            f"EDGE_WEIGHT_FORMAT : {fmt}\nEDGE_WEIGHT_SECTION\n{body}\nEOF\n"
        )
        inst = read_tsplib(_write(tmp_path, text, f"{fmt}.tsp"))
        assert np.array_equal(distance_matrix(inst), d), fmt
    bad = text.replace(body, body + " 7")
    with pytest.raises(ProblemError, match="expected"):
        read_tsplib(_write(tmp_path, bad, "short.tsp"))

"""The sparse TSP path (no distance matrix, memory O(n k)): its parts equal the dense path's
where they should, its fallback follows the reference tour, its state grows linearly."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.errors import ConfigError
from eaco_jax.ops import pheromone
from eaco_jax.ops.construction_sparse import construct_tours_sparse, hilbert_tour
from eaco_jax.ops.diversity import edge_diversity
from eaco_jax.problems import load_tsplib, tsplib
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp import TSP
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.problems.tsplib import coord_distances, read_tsplib
from eaco_jax.strategies.graph_eaco import GraphEACO


def _write_tsp(path: Path, xy: np.ndarray, metric: str = "EUC_2D") -> Path:
    n = len(xy)
    with open(path, "w") as fh:
        fh.write(f"NAME : {path.stem}\nTYPE : TSP\nDIMENSION : {n}\n"
                 f"EDGE_WEIGHT_TYPE : {metric}\nNODE_COORD_SECTION\n")
        np.savetxt(fh, np.column_stack([np.arange(1, n + 1), xy]), fmt="%d")
        fh.write("EOF\n")
    return path


def _all_pairs(p: SparseTSP) -> np.ndarray:
    i = np.arange(p.n)
    return np.asarray(p.dist[i[:, None], i[None, :]])


@pytest.mark.parametrize("metric", ["EUC_2D", "CEIL_2D", "ATT"])
def test_coordinate_distances_are_the_tsplib_integers(metric):
    rng = np.random.default_rng(0)
    for scale in (1_000, 1_000_000, 8_000_000):
        xy = rng.integers(0, scale, (200, 2))
        p = SparseTSP.from_coords(xy, metric=metric, neighbors=8)
        assert p.exact
        np.testing.assert_array_equal(_all_pairs(p), coord_distances(xy, metric))
    # squared lengths next to a rounding boundary: t^2 + t and t^2 + t + 1 (EUC_2D), t^2 and
    # t^2 + 1 (CEIL_2D), at lengths where float32 cannot tell them apart
    t = 3_000_001
    pts = [(0, 0), (t, 0), (0, t), (t, 1), (1, t), (t - 1, 2449), (2449, t - 1)]
    xy = np.array(pts + [(5, 7), (11, 3)])
    p = SparseTSP.from_coords(xy, metric=metric, neighbors=3)
    want = coord_distances(xy, metric)
    np.testing.assert_array_equal(_all_pairs(p), want)
    # the native local search's reading of the same coordinates
    from eaco_jax.ops.local_search_native import MODES, _d

    table = np.asarray(p.coords)
    got = [[_d(table, MODES[metric], i, j) for j in range(p.n)] for i in range(p.n)]
    np.testing.assert_array_equal(np.array(got), want)


def test_candidate_lists_are_the_dense_ones():
    for name, k in (("eil51", 10), ("eil51", 50), ("kroA100", 16), ("kroA100", 99)):
        dense = load_tsplib(name, neighbors=k)
        sparse = load_tsplib(name, neighbors=k, sparse=True)
        assert isinstance(sparse, SparseTSP) and not hasattr(sparse, "tau")
        np.testing.assert_array_equal(sparse.neighbors, dense.neighbors)
        i = np.arange(sparse.n)
        np.testing.assert_array_equal(np.asarray(sparse.dist[i[:, None], sparse.neighbors]),
                                      np.asarray(dense.dist)[i[:, None], dense.neighbors])


def test_pheromone_updates_on_candidate_edges_equal_the_dense_ones():
    p = load_tsplib("kroA100", neighbors=12)
    n, nbr = p.n, p.neighbors
    rng = np.random.default_rng(1)
    tours = jnp.asarray(np.stack([rng.permutation(n) for _ in range(6)]), jnp.int32)
    lengths = jnp.asarray(rng.uniform(2e4, 3e4, 6), jnp.float32)
    tau = jnp.asarray(rng.uniform(1e-5, 1e-4, (n, n)), jnp.float32)
    tau = tau + tau.T

    def on_cands(x):
        return np.asarray(jnp.take_along_axis(x, nbr, axis=1))

    tau_c = jnp.take_along_axis(tau, nbr, axis=1)
    pairs = [
        (pheromone.global_update(tau, tours[0], lengths[0], 0.2),
         pheromone.global_update(tau_c, tours[0], lengths[0], 0.2, nbr)),
        (pheromone.local_update(tau, tours, lengths, 0.1, 1.0),
         pheromone.local_update(tau_c, tours, lengths, 0.1, 1.0, nbr)),
        (pheromone.elitist_update(tau, tours, lengths, jnp.ones(6) / 6, tours[1], lengths[1],
                                  0.2, 1.0, 6.0),
         pheromone.elitist_update(tau_c, tours, lengths, jnp.ones(6) / 6, tours[1],
                                  lengths[1], 0.2, 1.0, 6.0, nbr)),
    ]
    for dense, sparse in pairs:
        np.testing.assert_array_equal(on_cands(dense), np.asarray(sparse))
    # with lists of every other city the diversity is the dense one
    full = load_tsplib("eil51", neighbors=50)
    t51 = jnp.asarray(np.stack([rng.permutation(51) for _ in range(5)]), jnp.int32)
    np.testing.assert_allclose(pheromone.candidate_edge_diversity(t51, full.neighbors),
                               edge_diversity(t51), rtol=1e-6)


def _reference_construction(cand_w, cands, start, ref):
    """The sparse rule with q0 = 1 in plain Python: the heaviest allowed candidate (the
    highest list position among equal weights, as the packed argmax), else the first
    unvisited city after the current one in the reference tour."""
    n = len(ref)
    pos = {c: i for i, c in enumerate(ref)}
    tour, seen = [start], {start}
    while len(tour) < n:
        cur = tour[-1]
        best, best_w = None, 0.0
        for j, c in enumerate(cands[cur]):
            if c not in seen and cand_w[cur, j] > 0 and cand_w[cur, j] >= best_w:
                best, best_w = c, cand_w[cur, j]
        if best is None:
            i = pos[cur]
            while ref[i % n] in seen:
                i += 1
            best = ref[i % n]
        tour.append(int(best))
        seen.add(best)
    return tour


def test_fallback_takes_the_next_unvisited_city_of_the_reference_tour():
    rng = np.random.default_rng(2)
    xy = rng.integers(0, 10_000, (60, 2))
    p = SparseTSP.from_coords(xy, neighbors=3)
    cands = np.asarray(p.neighbors)
    cand_w = rng.uniform(0.1, 1.0, cands.shape).astype(np.float32)
    ref = np.asarray(hilbert_tour(p.coords))
    starts = jnp.asarray([0, 7, 33, 59], jnp.int32)
    tours = np.asarray(construct_tours_sparse(jax.random.key(0), jnp.asarray(cand_w),
                                              p.neighbors, starts, jnp.asarray(ref), q0=1.0))
    for a, s in enumerate(np.asarray(starts)):
        assert sorted(tours[a]) == list(range(60))
        assert tours[a].tolist() == _reference_construction(cand_w, cands, int(s), ref.tolist())


def _colony_tours(problem, local_search: str, iterations: int = 2, ants: int = 8):
    strategy = GraphEACO(num_ants=ants, local_search=local_search, seed_tour=False)
    params = strategy.default_params(problem)
    key, k_init = jax.random.split(jax.random.key(3))
    state = strategy.init(k_init, problem, params)
    out = []
    for _ in range(iterations):
        key, k = jax.random.split(key)
        tours, state = strategy.ask(k, state, problem)
        out.append(np.asarray(tours))
        state, _ = strategy.tell(state, tours, problem.evaluate(tours), problem)
    return out, state


def _same_colony(name: str, local_search: str) -> None:
    n = load_tsplib(name).n
    dense, sparse = load_tsplib(name, neighbors=n - 1), load_tsplib(name, neighbors=n - 1,
                                                                    sparse=True)
    a, sa = _colony_tours(dense, local_search)
    b, sb = _colony_tours(sparse, local_search)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(np.take_along_axis(np.asarray(sa.tau), dense.neighbors, 1),
                                  np.asarray(sb.tau))
    assert float(sa.best_cost) == float(sb.best_cost)


def test_lists_of_every_city_give_the_dense_tours_eil51():
    """k = n - 1: no ant ever finds every candidate tabu, so the fallbacks (the only rule that
    differs) never run; trails and tours agree bit for bit."""
    _same_colony("eil51", "none")


@pytest.mark.slow
@pytest.mark.parametrize("name,local_search", [
    ("eil51", "2opt+oropt"), ("kroA100", "none"), ("kroA100", "2opt"),
    ("kroA100", "or-2opt"), ("kroA100", "2opt+oropt")])
def test_lists_of_every_city_give_the_dense_tours(name, local_search):
    _same_colony(name, local_search)


def test_local_searches_on_coordinate_distances_equal_the_matrix_ones():
    from eaco_jax.ops import local_search

    dense = load_tsplib("kroA100", neighbors=10)
    sparse = load_tsplib("kroA100", neighbors=10, sparse=True)
    rng = np.random.default_rng(7)
    tours = jnp.asarray(np.stack([rng.permutation(100) for _ in range(3)]), jnp.int32)
    a = local_search.two_opt(tours, dense.dist, dense.neighbors, or_opt=True)
    b = local_search.two_opt(tours, sparse.dist, sparse.neighbors, or_opt=True)
    np.testing.assert_array_equal(a, b)
    active = jnp.asarray(rng.random((3, 100)) < 0.2)  # the focused search too
    a = local_search.two_opt(tours, dense.dist, dense.neighbors, or_opt=True, active=active,
                             focus_width=8)
    b = local_search.two_opt(tours, sparse.dist, sparse.neighbors, or_opt=True, active=active,
                             focus_width=8)
    np.testing.assert_array_equal(a, b)
    key = jax.random.key(0)
    a = local_search.dlb_local_search(key, tours, dense.dist, dense.neighbors, or_opt=True,
                                      impl="native")
    b = local_search.dlb_local_search(key, tours, sparse.dist, sparse.neighbors, or_opt=True,
                                      impl="native")
    np.testing.assert_array_equal(a, b)


def test_state_memory_grows_linearly_with_the_cities():
    from eaco_jax.driver.memory import state_row_bytes

    strategy = GraphEACO(num_ants=16, local_search="or-2opt")
    sizes = (2000, 4000, 8000)
    rng = np.random.default_rng(4)
    sizes_bytes = []
    for n in sizes:
        p = SparseTSP.from_coords(rng.integers(0, 1_000_000, (n, 2)))
        sizes_bytes.append(state_row_bytes(strategy, p, strategy.default_params(p)))
    r1, r2 = sizes_bytes[1] / sizes_bytes[0], sizes_bytes[2] / sizes_bytes[1]
    assert 1.9 < r1 < 2.1 and 1.9 < r2 < 2.1, sizes_bytes
    assert sizes_bytes[2] < 8000 * 16 * 4 * 4  # O(n k), far below one n x n float32 array


_RSS_RUN = """
import resource, sys, json
import numpy as np
import eaco_jax as ea
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.strategies.graph_eaco import GraphEACO
n = int(sys.argv[1])
p = SparseTSP.from_coords(np.random.default_rng(0).integers(0, 1_000_000, (n, 2)))
res = ea.minimize(p, GraphEACO(num_ants=8, local_search="2opt+oropt", ls_best_k=4,
                               preset="mmas"), seed=0, iterations=2)
try:  # this process's own peak: ru_maxrss keeps the forking parent's high-water mark
    hwm = [ln for ln in open("/proc/self/status") if ln.startswith("VmHWM:")]
    rss = int(hwm[0].split()[1]) * 1024
except (OSError, IndexError):
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"cost": float(res.best_cost), "rss": rss}))
"""


def _rss_run(n: int) -> dict:
    out = subprocess.run([sys.executable, "-c", _RSS_RUN, str(n)], capture_output=True,
                         text=True, check=True, env={"JAX_PLATFORMS": "cpu", "PATH": ""})
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_2000_cities_run_on_the_cpu_in_little_memory():
    got = _rss_run(2000)
    assert got["rss"] < 2 * 2**30 and 0.7 * 2000**0.5 * 1e6 < got["cost"] < 2e8


@pytest.mark.slow
def test_10000_cities_run_on_the_cpu_in_under_2_gb():
    got = _rss_run(10_000)
    assert got["rss"] < 2 * 2**30, got


def test_large_files_read_fast_and_take_the_sparse_path(tmp_path, monkeypatch):
    xy = np.random.default_rng(5).integers(0, 1_000_000, (100_000, 2))
    f = _write_tsp(tmp_path / "r100k.tsp", xy)
    parsed = []  # what the numpy reader (no loop over the cities) returned
    fast = tsplib._read_coords_fast
    monkeypatch.setattr(tsplib, "_read_coords_fast",
                        lambda *a: parsed.append(fast(*a)) or parsed[-1])
    t0 = time.perf_counter()
    inst = read_tsplib(f)
    assert time.perf_counter() - t0 < 2.0
    np.testing.assert_array_equal(inst.coords, xy)
    assert parsed[0] is inst
    small = _write_tsp(tmp_path / "r8000.tsp", xy[:8000])
    assert isinstance(load_tsplib(str(small)), SparseTSP)  # auto: from 8,000 cities
    tiny = _write_tsp(tmp_path / "r300.tsp", xy[:300])
    assert isinstance(load_tsplib(str(tiny)), TSP)
    assert isinstance(load_tsplib(str(tiny), sparse=True), SparseTSP)
    bad = tmp_path / "bad.tsp"  # malformed: the line-by-line reader names the fault
    bad.write_text(f.read_text().replace("\n17 ", "\n17 x ", 1))
    with pytest.raises(ProblemError, match=r"bad.tsp:\d+: .*'id x y'"):
        read_tsplib(bad)
    with pytest.raises(ProblemError, match="no sparse path"):
        load_tsplib("burma14", sparse=True)  # GEO


def test_eaco_tsp_reports_memory_and_tours_per_second(tmp_path):
    from eaco_jax.runs import tsp as run_tsp

    xy = np.random.default_rng(6).integers(0, 10**6, (300, 2))
    f = _write_tsp(tmp_path / "r300.tsp", xy)
    s = run_tsp.TspSettings(instance=str(f), sparse="on", ants=4, iterations=2,
                            local_search="2opt", ls_best_k=2)
    rec = run_tsp.run(s)
    assert rec["sparse"] and rec["neighbors"] == 16 and rec["n"] == 300
    assert rec["peak_host_bytes"] > 2**20 and rec["tours_per_second"] > 0
    assert "tours/s" in run_tsp.summary(rec) and "MiB host" in run_tsp.summary(rec)
    t = np.asarray(rec["tour"])
    assert rec["best_length"] == coord_distances(xy, "EUC_2D")[t, np.roll(t, -1)].sum()


def test_focused_construction_changes_few_edges_of_the_reference():
    rng = np.random.default_rng(8)
    p = SparseTSP.from_coords(rng.integers(0, 100_000, (400, 2)), neighbors=8)
    ref = np.asarray(hilbert_tour(p.coords))
    ref_edges = {frozenset(e) for e in zip(ref, np.roll(ref, -1), strict=True)}
    cand_w = jnp.asarray(rng.uniform(0.1, 1.0, (400, 8)), jnp.float32)
    starts = jnp.asarray(rng.integers(0, 400, 6), jnp.int32)

    def build(cap):
        return np.asarray(construct_tours_sparse(jax.random.key(1), cand_w, p.neighbors,
                                                 starts, jnp.asarray(ref), 0.0,
                                                 max_new_edges=cap))

    for t in build(5):  # <= 5 chosen, <= 6 skips over cities visited early, the closing edge
        assert sorted(t) == list(range(400))
        new = sum(frozenset(e) not in ref_edges for e in zip(t, np.roll(t, -1), strict=True))
        assert new <= 2 * 5 + 2
    np.testing.assert_array_equal(build(400), build(None))  # a cap never reached


@pytest.mark.parametrize("cap", [None, 3])
def test_kernel_builds_the_scan_tours(cap):
    """The sparse construction as one Pallas kernel (here in Pallas' interpreter; compiled on
    a GPU): the same tours as the scan, with padded ants (21 of a block of 32), the stacked
    greedy row, a chaos factor and the focused limit."""
    rng = np.random.default_rng(9)
    p = SparseTSP.from_coords(rng.integers(0, 10_000, (70, 2)), neighbors=4)
    cand_w = jnp.asarray(rng.uniform(0.1, 1.0, (140, 4)), jnp.float32)
    ref = hilbert_tour(p.coords)
    starts = jnp.asarray(rng.integers(0, 70, 21), jnp.int32)
    offset = jnp.asarray(np.r_[np.zeros(20), [70]], jnp.int32)
    factor = jnp.asarray(rng.uniform(0.5, 1.5, (21, 70)), jnp.float32)
    for q0, fac in ((0.0, None), (0.3, factor)):
        args = (jax.random.key(0), cand_w, p.neighbors, starts, ref, q0, offset, fac, cap)
        np.testing.assert_array_equal(construct_tours_sparse(*args, plan="kernel"),
                                      construct_tours_sparse(*args))


def test_time_alone_reads_the_clock_after_every_sparse_iteration(tmp_path):
    """Sparse-path iterations take seconds: with --max-seconds alone the clock is read after
    each, so the budget is overshot by at most one iteration (dense runs keep 15)."""
    from eaco_jax.runs import tsp as run_tsp

    f = _write_tsp(tmp_path / "r300.tsp", np.random.default_rng(10).integers(0, 10**6, (300, 2)))
    sparse = run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="on", max_seconds=5.0))
    dense = run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="off", max_seconds=5.0))
    assert sparse.budget["chunk_size"] == 1 and dense.budget["chunk_size"] == 15
    assert sparse.budget["max_seconds"] == 5.0
    assert "chunk_seconds" not in sparse.budget
    paced = run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="on", max_seconds=5.0,
                                              chunk_seconds=0.2))
    assert (paced.budget["chunk_size"], paced.budget["chunk_seconds"]) == (
        run_tsp.PACED_CHUNK, 0.2)
    dense = run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="off", max_seconds=5.0,
                                              chunk_seconds=0.2))  # paced within its 15
    assert (dense.budget["chunk_size"], dense.budget["chunk_seconds"]) == (15, 0.2)
    with pytest.raises(ConfigError, match="chunk_seconds paces a run that --max-seconds alone"):
        run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="on", iterations=30,
                                          chunk_seconds=0.2))


def test_the_pace_band_paces_and_unrolls_small_sparse_gpu_runs(tmp_path, monkeypatch):
    """On a GPU the sparse path below the pace band's size paces --max-seconds runs at the
    band's chunk_seconds and unrolls the first greedy rounds; 0 and explicit settings win, an
    iteration budget stays unpaced, a CPU and sizes past the band get neither. The GPU
    allocator setting is put in the environment unless the user set it."""
    import dataclasses

    import jax

    from eaco_jax.runs import tsp as run_tsp

    f = _write_tsp(tmp_path / "r300.tsp", np.random.default_rng(10).integers(0, 10**6, (300, 2)))

    def built(**kw):
        return run_tsp.build(run_tsp.TspSettings(instance=str(f), sparse="on", **kw))

    cpu = built(max_seconds=5.0)  # this machine: no band
    assert "chunk_seconds" not in cpu.budget and cpu.strategy.ls_acceptance == "rounds"
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    row = run_tsp.sparse_defaults("gpu")
    band = run_tsp.row_pace(row, 300)
    assert band is not None and band.ls_acceptance != "rounds"
    gpu = built(max_seconds=5.0)
    assert (gpu.budget["chunk_size"], gpu.budget["chunk_seconds"]) == (
        run_tsp.PACED_CHUNK, band.chunk_seconds)
    assert gpu.strategy.ls_acceptance == band.ls_acceptance
    off = built(max_seconds=5.0, chunk_seconds=0, ls_acceptance="rounds")
    assert "chunk_seconds" not in off.budget and off.budget["chunk_size"] == 1
    assert off.strategy.ls_acceptance == "rounds"
    counted = built(iterations=4)  # an iteration budget: whole chunks, unpaced
    assert "chunk_seconds" not in counted.budget
    assert counted.strategy.ls_acceptance == band.ls_acceptance
    assert built(iterations=4, chunk_seconds=0).budget == counted.budget  # 0 is allowed
    from eaco_jax.driver.minimize import Checkpointing

    ck = Checkpointing("unused", run_info={"settings": {"construction": "auto"}})
    pinned = run_tsp.with_resolved_settings(ck, gpu).run_info["settings"]  # for eaco resume
    assert (pinned["chunk_seconds"], pinned["ls_acceptance"]) == (
        band.chunk_seconds, band.ls_acceptance)
    assert run_tsp.with_resolved_settings(ck, off).run_info["settings"]["chunk_seconds"] == 0
    past = dataclasses.replace(row, paces=(dataclasses.replace(band, below=300),))
    monkeypatch.setattr(run_tsp, "SPARSE_DEFAULTS", (past,))
    assert run_tsp.row_pace(past, 299) is not None and run_tsp.row_pace(past, 300) is None
    beyond = built(max_seconds=5.0)
    assert "chunk_seconds" not in beyond.budget and beyond.strategy.ls_acceptance == "rounds"
    (name, value), = run_tsp.GPU_ALLOCATOR.items()
    monkeypatch.delenv(name, raising=False)
    built(iterations=1)
    assert os.environ[name] == value
    monkeypatch.setenv(name, "user's")
    built(iterations=1)
    assert os.environ[name] == "user's"


def test_a_focused_colony_searches_from_the_changed_edges(monkeypatch):
    """GraphEACO with ``ls_focus_width`` hands the batched search the ends of the edges each
    ant changed (``active``)."""
    from eaco_jax.driver import program_cache
    from eaco_jax.driver.programs import clear_compiled
    from eaco_jax.ops import local_search

    # the spy sees the search only while the colony is traced: no program from a cache
    monkeypatch.setattr(program_cache, "_folder", None)
    clear_compiled()
    seen = []
    real = local_search.two_opt

    def spy(*args, **kw):
        seen.append(kw.get("active"))
        return real(*args, **kw)

    monkeypatch.setattr(local_search, "two_opt", spy)
    rng = np.random.default_rng(11)
    p = SparseTSP.from_coords(rng.integers(0, 100_000, (300, 2)), neighbors=8)
    st = GraphEACO(num_ants=4, local_search="or-2opt", max_new_edges=4, construction="moves",
                   ls_focus_width=16, seed_tour=True)
    res = ea.minimize(p, st, seed=0, iterations=2)
    assert sorted(np.asarray(res.best_solution)) == list(range(300))
    active = [a for a in seen if a is not None]  # one (ants, n) mask per traced search
    assert active and active[-1].shape == (4, 300)

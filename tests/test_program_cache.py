"""Exported chunks on disk (``driver/program_cache.py``): a later run loads the program instead
of tracing it and returns exactly what a traced run returns; programs that cannot be exported,
damaged entries and code from outside the package are traced as before."""

from __future__ import annotations

import subprocess
import sys

import jax
import numpy as np
import pytest
from test_driver import RandomSearch, Sphere

import eaco_jax as ea
from eaco_jax.driver import minimize as driver
from eaco_jax.driver import program_cache
from eaco_jax.problems import load_tsplib
from eaco_jax.strategies.graph_eaco import GraphEACO


@pytest.fixture
def cache(tmp_path, monkeypatch):
    program_cache.set_folder(tmp_path)
    driver.clear_compiled()
    yield tmp_path
    program_cache._folder = program_cache._UNSET
    driver.clear_compiled()


def _run(strategy, problem, seed=3):
    res = ea.minimize(problem, strategy, seed=seed, iterations=12, chunk_size=4)
    return float(res.best_cost), np.asarray(res.best_solution), res.history["best_cost"]


def _same(a, b):
    assert a[0] == b[0]
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[2], b[2])


def test_a_second_run_loads_the_program_without_tracing(cache, monkeypatch):
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=16, local_search="2opt")
    program_cache.set_folder(None)
    plain = _run(strategy, problem)
    program_cache.set_folder(cache)
    driver.clear_compiled()
    first = _run(strategy, problem)
    entries = list(cache.glob("*.jaxexport"))
    assert len(entries) == 2  # the initialiser and the chunk
    driver.clear_compiled()

    def no_tracing(*args, **kwargs):
        raise AssertionError("traced although its program is on disk")

    monkeypatch.setattr(driver, "make_chunk_fn", lambda *a, **k: no_tracing)
    monkeypatch.setattr(GraphEACO, "_init", no_tracing)
    loaded = _run(strategy, problem)
    _same(first, plain)
    _same(loaded, plain)
    # another colony size is another program
    monkeypatch.undo()
    program_cache.set_folder(cache)
    _run(GraphEACO(num_ants=8, local_search="2opt"), problem)
    assert len(list(cache.glob("*.jaxexport"))) == 4


def test_a_fresh_process_loads_it(cache):
    code = (
        "import sys, jax\n"
        "from eaco_jax.driver import program_cache, minimize as driver\n"
        "from eaco_jax.problems import load_tsplib\n"
        "from eaco_jax.strategies.graph_eaco import GraphEACO\n"
        "import eaco_jax as ea\n"
        "program_cache.set_folder(sys.argv[1])\n"
        "how = []\n"
        "real = program_cache.compiled\n"
        "def spy(*a):\n"
        "    out = real(*a); how.append(out[1]); return out\n"
        "program_cache.compiled = spy\n"
        "r = ea.minimize(load_tsplib('eil51'), GraphEACO(num_ants=16, local_search='2opt'),\n"
        "                seed=3, iterations=12, chunk_size=4)\n"
        "print(','.join(how), float(r.best_cost))\n")
    env = {"JAX_PLATFORMS": "cpu"}
    import os

    env = {**os.environ, **env}
    outs = [subprocess.run([sys.executable, "-c", code, str(cache)], capture_output=True,
                           text=True, env=env, check=True).stdout.split()[-2:]
            for _ in range(2)]
    assert [o[0] for o in outs] == ["exported,exported", "loaded,loaded"]  # init, chunk
    assert outs[0][1] == outs[1][1]


def test_host_callbacks_are_marked_and_traced(cache):
    problem = load_tsplib("eil51")
    strategy = GraphEACO(num_ants=8, local_search="2opt+oropt")
    if jax.default_backend() != "cpu":
        pytest.skip("the native search (host callbacks) runs on a CPU backend")
    program_cache.set_folder(None)
    plain = _run(strategy, problem)
    program_cache.set_folder(cache)
    driver.clear_compiled()
    _same(_run(strategy, problem), plain)
    assert len(list(cache.glob("*.traced"))) == 1  # the chunk; the initialiser has no callback


def test_a_damaged_entry_is_rebuilt(cache):
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    first = _run(strategy, problem)
    entry = max(cache.glob("*.jaxexport"), key=lambda p: p.stat().st_size)
    entry.write_bytes(entry.read_bytes()[:100])
    driver.clear_compiled()
    with pytest.warns(UserWarning, match="unreadable"):
        again = _run(strategy, problem)
    _same(again, first)
    assert entry.stat().st_size > 100


def test_code_from_outside_the_package_is_never_loaded(cache):
    """A test's own strategy and problem: their source is not in the digest, so a changed
    definition must never meet a stale program."""
    _run(RandomSearch(num_ants=4), Sphere(lower=-jax.numpy.ones(3), upper=jax.numpy.ones(3)))
    assert not list(cache.iterdir())


def test_batched_seeds_settings_and_capped_runs_load_the_same(cache, monkeypatch):
    """Rows of seeds x settings and a max_evaluations cap: other programs (vmapped keys,
    a budget argument), the same equality."""
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    p0 = strategy.default_params(problem)
    settings = [p0, p0.replace(q0=jax.numpy.asarray(0.5, p0.q0.dtype))]

    def go():
        res = ea.minimize(problem, strategy, seed=[1, 2], params=settings,
                          max_evaluations=8 * 9, chunk_size=4)
        return np.asarray(res.best_cost), np.asarray(res.best_solution), res.history["best_cost"]

    program_cache.set_folder(None)
    plain = go()
    program_cache.set_folder(cache)
    driver.clear_compiled()
    go()
    assert len(list(cache.glob("*.jaxexport"))) == 2
    driver.clear_compiled()
    how, real = [], program_cache.compiled

    def spy(*args):
        out = real(*args)
        how.append(out[1])
        return out

    monkeypatch.setattr(program_cache, "compiled", spy)
    loaded = go()
    assert how == ["loaded", "loaded"]
    for a, b in zip(plain, loaded, strict=True):
        np.testing.assert_array_equal(a, b)

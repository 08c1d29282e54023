"""Exported chunks on disk (``driver/program_cache.py``): a later run loads the program instead
of tracing it and returns exactly what a traced run returns; programs that cannot be exported,
damaged entries and code from outside the package are traced as before."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

import jax
import numpy as np
import pytest
from test_driver import RandomSearch, Sphere

import eaco_jax as ea
from eaco_jax.driver import minimize as driver
from eaco_jax.driver import program_cache, programs
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

    monkeypatch.setattr(programs, "make_chunk_fn", lambda *a, **k: no_tracing)
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
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
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


# ------------------------------------------------------------ entries are data, verified


def _chunk_entry(cache):
    """The chunk's entry (the larger of the run's two programs)."""
    return max(cache.glob("*.jaxexport"), key=lambda p: p.stat().st_size)


def _valid(entry):
    header, _ = program_cache._unpack(entry.read_bytes())
    return header["key"] == entry.stem


class _Payload:
    """Unpickling this creates ``path``: what a hostile writer of a shared cache would run."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_a_pickled_entry_is_never_unpickled(cache, tmp_path_factory):
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    first = _run(strategy, problem)
    marks = tmp_path_factory.mktemp("marks")
    pickle.loads(pickle.dumps(_Payload(marks / "control")))
    assert (marks / "control").exists()  # the payload is live: unpickling it runs it
    entry = _chunk_entry(cache)
    entry.write_bytes(pickle.dumps(_Payload(marks / "pwned")))
    driver.clear_compiled()
    with pytest.warns(UserWarning, match="not an eaco_jax program entry") as caught:
        again = _run(strategy, problem)
    assert not (marks / "pwned").exists()
    assert len([w for w in caught if "program cache" in str(w.message)]) == 1
    _same(again, first)
    assert _valid(entry)  # written again, as data


@pytest.mark.parametrize("where", ["program", "header"])
def test_one_flipped_bit_is_caught_by_the_digest(cache, where):
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    first = _run(strategy, problem)
    entry = _chunk_entry(cache)
    raw = bytearray(entry.read_bytes())
    _, data = program_cache._unpack(bytes(raw))
    at = (len(raw) - len(data) // 2 if where == "program"
          else raw.index(b'"best_cost"') + 5)  # a metric's name in the output description
    raw[at] ^= 0x01
    entry.write_bytes(bytes(raw))
    driver.clear_compiled()
    with pytest.warns(UserWarning, match="sha256 does not match") as caught:
        again = _run(strategy, problem)
    assert len([w for w in caught if "program cache" in str(w.message)]) == 1
    _same(again, first)
    assert _valid(entry)


def test_an_entry_of_another_program_under_this_name_is_rebuilt(cache):
    """The initialiser's entry copied over the chunk's (or two entries swapped by name)."""
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    first = _run(strategy, problem)
    entries = sorted(cache.glob("*.jaxexport"), key=lambda p: p.stat().st_size)
    entries[1].write_bytes(entries[0].read_bytes())
    driver.clear_compiled()
    with pytest.warns(UserWarning, match="holds the program of key") as caught:
        again = _run(strategy, problem)
    assert len([w for w in caught if "program cache" in str(w.message)]) == 1
    _same(again, first)
    assert _valid(entries[1]) and _valid(entries[0])


def _forge(entry, header=None, data=None):
    """Rewrite ``entry`` with a valid digest: damage only a writer could make on purpose."""
    old_header, old_data = program_cache._unpack(entry.read_bytes())
    entry.write_bytes(program_cache._pack(header or old_header,
                                          old_data if data is None else data))


def _plus_one(x):
    return x + 1


def test_a_program_that_fails_to_lower_is_traced_again(cache):
    x3, x4 = jax.numpy.arange(3.0), jax.numpy.arange(4.0)
    a, b = "a" * 32, "b" * 32
    program_cache.compiled(jax.jit(_plus_one), (x3,), a)
    program_cache.compiled(jax.jit(_plus_one), (x4,), b)
    _forge(cache / f"{a}.jaxexport", data=program_cache._unpack(
        (cache / f"{b}.jaxexport").read_bytes())[1])  # another shape's program
    with pytest.warns(UserWarning, match="program cache") as caught:
        run, how = program_cache.compiled(jax.jit(_plus_one), (x3,), a)
    assert len(caught) == 1 and how == "exported"
    np.testing.assert_array_equal(run(x3), x3 + 1)
    assert _valid(cache / f"{a}.jaxexport")


def test_a_program_whose_first_call_fails_is_traced_again(cache):
    """A header describing another output structure fails when the result is rebuilt."""
    x = jax.numpy.arange(3.0)
    key = "c" * 32
    program_cache.compiled(jax.jit(_plus_one), (x,), key)
    entry = cache / f"{key}.jaxexport"
    header, _ = program_cache._unpack(entry.read_bytes())
    _forge(entry, header={**header, "out_tree": ["tuple", None, [None, None]],
                          "out_keys": [None, None]})
    run, how = program_cache.compiled(jax.jit(_plus_one), (x,), key)
    assert how == "loaded"
    with pytest.warns(UserWarning, match="program cache") as caught:
        out = run(x)
    assert len(caught) == 1 and not entry.exists()
    np.testing.assert_array_equal(out, x + 1)
    np.testing.assert_array_equal(run(x), x + 1)  # the traced program from now on


def test_an_output_type_outside_the_package_is_refused(cache):
    x = jax.numpy.arange(3.0)
    key = "d" * 32
    program_cache.compiled(jax.jit(_plus_one), (x,), key)
    entry = cache / f"{key}.jaxexport"
    header, _ = program_cache._unpack(entry.read_bytes())
    _forge(entry, header={**header, "out_tree": ["subprocess:Popen", None, [None]]})
    with pytest.warns(UserWarning, match="is not of this package"):
        run, how = program_cache.compiled(jax.jit(_plus_one), (x,), key)
    assert how == "exported"
    np.testing.assert_array_equal(run(x), x + 1)


@pytest.fixture
def partitionable():
    before = jax.config.jax_threefry_partitionable
    yield
    jax.config.update("jax_threefry_partitionable", before)
    driver.clear_compiled()


def test_jax_options_read_while_tracing_are_in_the_key(cache, partitionable):
    """JAX_THREEFRY_PARTITIONABLE=0 draws other random numbers: a program traced with the
    default must not be loaded, and the run equals an uncached one with the option."""
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    default = _run(strategy, problem)  # on disk now
    key = program_cache.program_key(("x",))
    jax.config.update("jax_threefry_partitionable", False)
    driver.clear_compiled()
    cached = _run(strategy, problem)
    program_cache.set_folder(None)
    driver.clear_compiled()
    plain = _run(strategy, problem)
    assert plain[0] != default[0]  # the option changes this run's answer
    _same(cached, plain)
    assert program_cache.program_key(("x",)) != key


@pytest.mark.parametrize("keep", ["_COMPILED", "_INITS"])
def test_jax_options_key_the_programs_held_in_process(cache, partitionable, keep):
    """Flipping a JAX option mid-process (no clear_compiled) traces the chunk and the
    initialiser again: a run equals one started fresh with the option. ``keep`` is the
    in-process cache left filled while the other is emptied, so each one's key is tested."""
    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="none")
    program_cache.set_folder(None)
    default = _run(strategy, problem)
    jax.config.update("jax_threefry_partitionable", False)
    getattr(programs, "_INITS" if keep == "_COMPILED" else "_COMPILED").clear()
    flipped = _run(strategy, problem)
    driver.clear_compiled()
    fresh = _run(strategy, problem)
    assert fresh[0] != default[0]  # the option changes this run's answer
    _same(flipped, fresh)


def test_a_compile_cache_that_is_a_file_is_said_once(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "EACO_COMPILE_CACHE": str(afile)}
    res = subprocess.run([sys.executable, "-m", "eaco_jax", "tsp", "--help"], env=env,
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert lines == [f"warning: compile cache off: EACO_COMPILE_CACHE={afile} is a file, not a "
                     "folder; point it at a writable folder, or pass --no-compile-cache"]
    assert afile.read_text() == "x"


def test_the_state_size_comes_from_the_program_traced_exported_or_loaded(cache):
    """``out_nbytes`` of the initialiser equals the traced state size times the rows, whether
    the program was traced (cache off), exported now or loaded from disk."""
    from eaco_jax.driver import memory, rows

    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="2opt")
    p = strategy.default_params(problem)
    one_row = memory.state_row_bytes(strategy, problem, p)
    assert one_row > 0
    for seeds, params, n in (([0], None, 1), ([0, 1], None, 2), ([0, 1], [p, p], 4)):
        for folder in (None, cache, cache):  # traced, exported, loaded
            program_cache.set_folder(folder)
            driver.clear_compiled()
            init, _, _ = rows.compiled_initial(strategy, problem, seeds, params)
            assert program_cache.out_nbytes(init) == one_row * n, (seeds, params, folder)
    assert len(list(cache.glob("*.jaxexport"))) == 3  # one initialiser per row layout


def test_minimize_sizes_the_state_from_its_program_not_a_second_trace(cache, monkeypatch):
    """The memory check reads the state's size from the compiled initialiser (a fresh process
    with the program on disk traces nothing), and still refuses a state too large."""
    from eaco_jax.driver import memory
    from eaco_jax.errors import ConfigError

    def traced(*args, **kwargs):
        raise AssertionError("the initialiser was traced again to size its state")

    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="2opt")
    monkeypatch.setattr(memory, "state_row_bytes", traced)
    for folder in (None, cache, cache):  # traced, exported, loaded
        program_cache.set_folder(folder)
        driver.clear_compiled()
        _run(strategy, problem)
    monkeypatch.setattr(memory, "_memory_limit", lambda: 2 * 1000)
    with pytest.raises(ConfigError, match="the colony state needs"):
        ea.minimize(problem, strategy, seed=0, iterations=2)


def test_a_run_looks_its_chunk_up_once_and_searches_the_same(monkeypatch):
    """One-iteration chunks reuse the compiled chunk once its output state has the input's
    shapes (no signature and cache lookup per chunk), with the same search as longer chunks."""
    calls = []
    real = driver.compiled_chunk

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    problem, strategy = load_tsplib("eil51"), GraphEACO(num_ants=8, local_search="2opt")
    monkeypatch.setattr(driver, "compiled_chunk", counted)
    one = ea.minimize(problem, strategy, seed=5, iterations=12, chunk_size=1)
    assert one.iterations == 12 and 1 <= len(calls) <= 2
    four = ea.minimize(problem, strategy, seed=5, iterations=12, chunk_size=4)
    np.testing.assert_array_equal(one.history["best_cost"], four.history["best_cost"])
    np.testing.assert_array_equal(np.asarray(one.best_solution), np.asarray(four.best_solution))

"""Sweeps: cell expansion, one vmapped call per static group, resume, tables, CLI."""

import dataclasses
import json

import jax.numpy as jnp
import numpy as np
import pytest
from test_driver import RandomSearch, Sphere

import eaco_jax as ea
from eaco_jax import sweep as sw
from eaco_jax.errors import ConfigError
from eaco_jax.runs import Built, RunKind
from eaco_jax.sweep import local


@dataclasses.dataclass(frozen=True)
class ToySettings:
    """Sphere + random search; ``ants`` and ``iterations`` are static settings."""

    ants: int = 8
    iterations: int = 10
    seed: int = 0

    def __post_init__(self):
        if self.ants < 1:
            raise ConfigError(f"ants must be >= 1, got {self.ants}")


def _build(s):
    strategy = RandomSearch(num_ants=int(s.ants))
    problem = Sphere(lower=-jnp.ones(3), upper=jnp.ones(3))
    return Built(problem, strategy, strategy.default_params(problem),
                 {"iterations": int(s.iterations), "chunk_size": 5})


def _metrics(built, result, row):
    return {"success": bool(np.asarray(result.best_cost)[row] < 0.2)}


TOY = RunKind("toy", ToySettings, _build, None, _metrics)

SPEC = {
    "name": "toy",
    "kind": "test_sweep:TOY",
    "args": {"iterations": 10},
    "seeds": 3,
    "grid": {"scale": [0.25, 0.5, 1.0], "ants": [4, 8]},
}


def test_params_list_rows_match_single_runs():
    problem = Sphere(lower=-jnp.ones(3), upper=jnp.ones(3))
    s = RandomSearch()
    params = [s.default_params(problem).replace(scale=jnp.float32(v)) for v in (0.5, 1.0)]
    batch = ea.minimize(problem, s, params=params, seed=[0, 1], iterations=10)
    assert batch.history["best_cost"].shape == (4, 10)
    assert batch.seeds == [0, 1, 0, 1]
    for r in range(4):
        one = ea.minimize(problem, s, seed=batch.seeds[r], iterations=10, params=params[r // 2])
        np.testing.assert_allclose(batch.history["best_cost"][r], one.history["best_cost"],
                                   rtol=1e-6)


def test_expand_splits_traced_and_static():
    kind, cells = sw.plan(SPEC)
    assert kind is TOY
    assert len(cells) == 6 and len({c.id for c in cells}) == 6
    assert all(set(c.params) == {"scale"} and "ants" in c.args for c in cells)
    groups = sw.groups_of(cells)
    assert [len(g) for g in groups] == [3, 3]  # one vmapped call per ants


def test_sweep_runs_groups_writes_tables_and_resumes(tmp_path, monkeypatch):
    calls = []
    real = local.run_group

    def counting(kind, cells, seeds, **kw):
        calls.append((cells[0].args["ants"], len(cells), len(seeds)))
        return real(kind, cells, seeds, **kw)

    monkeypatch.setattr(local, "run_group", counting)
    rec = sw.run_sweep(SPEC, tmp_path)
    assert calls == [(4, 3, 3), (8, 3, 3)]  # 6 cells x 3 seeds in two calls
    assert rec["runs"] == 18 and rec["cells"] == 6 and rec["groups"] == 2
    table = json.loads((tmp_path / "table.json").read_text())
    assert len(table["rows"]) == 18 and {"cell", "scale", "ants", "seed", "best_cost",
                                         "success"} <= set(table["columns"])
    assert (tmp_path / "table.csv").read_text().count("\n") == 19
    assert (tmp_path / "summary.png").stat().st_size > 1000
    # every row equals a single run with the same settings
    for row in table["rows"][::5]:
        s = RandomSearch(num_ants=row["ants"])
        p = Sphere(lower=-jnp.ones(3), upper=jnp.ones(3))
        one = ea.minimize(p, s, seed=row["seed"], iterations=10, chunk_size=5,
                          params=s.default_params(p).replace(scale=jnp.float32(row["scale"])))
        np.testing.assert_allclose(row["best_cost"], float(one.best_cost), rtol=1e-6)

    # interrupted sweep: drop two finished cells; only they run again, the table is the same
    cells = sorted((tmp_path / "cells").glob("*.json"))  # c000, c002: ants=4
    for f in (cells[0], cells[2]):
        f.unlink()
    calls.clear()
    again = sw.run_sweep(SPEC, tmp_path)
    assert calls == [(4, 2, 3)] and again["cells_run_now"] == 2
    assert json.loads((tmp_path / "table.json").read_text()) == table


def test_random_and_listed_cells(tmp_path):
    spec = {"kind": "test_sweep:TOY", "seeds": [5],
            "random": {"n": 4, "seed": 1, "space": {"scale": [0.1, 1.0],
                                                     "ants": {"choice": [4, 6]}}}}
    _, cells = sw.plan(spec)
    assert len(cells) == 4 and all(0.1 <= c.params["scale"] <= 1.0 for c in cells)
    spec = {"kind": "test_sweep:TOY", "cells": [{"scale": 0.3}, {"scale": 0.6}],
            "grid": {"ants": [4, 5]}}
    _, cells = sw.plan(spec)
    assert [c.values for c in cells][:2] == [{"scale": 0.3, "ants": 4},
                                              {"scale": 0.3, "ants": 5}]


@pytest.mark.parametrize("spec, msg", [
    ({"kind": "test_sweep:TOY", "grid": {"scale": 3}}, "non-empty list"),
    ({"kind": "test_sweep:TOY", "seeds": 0}, "seeds"),
    ({"kind": "nowhere:fn"}, "cannot import"),
    ({"command": "nope"}, "unknown run kind 'nope'; known: constrained, gait"),
    ({"kind": "test_sweep:TOY", "bogus": 1}, "unknown sweep keys"),
    ({"kind": "test_sweep:TOY", "grid": {"colour": [1]}},
     r"sweep cell 0 .*unknown key\(s\) \['colour'\]; valid: ants, iterations, scale"),
    ({"kind": "test_sweep:TOY", "grid": {"scale": [float("nan")]}}, "not finite"),
    ({"kind": "test_sweep:TOY", "grid": {"scale": ["abc"]}}, "scale='abc' is not a number"),
    ({"kind": "test_sweep:TOY", "cells": [{"ants": 4}, {"ants": 0}]},
     r"sweep cell 1 \{\"ants\": 0\}: ants must be >= 1"),
    ({"kind": "test_sweep:TOY", "args": {"seed": 3}}, "cannot set 'seed'"),
])
def test_bad_specs(tmp_path, spec, msg):
    with pytest.raises(ConfigError, match=msg):
        sw.run_sweep(spec, tmp_path)
    assert not (tmp_path / "cells").exists()  # refused before anything ran


def test_sweep_cli_json(tmp_path):
    import yaml
    from typer.testing import CliRunner

    from eaco_jax.cli import app

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({**SPEC, "grid": {"scale": [0.5, 1.0]}}))
    out = CliRunner().invoke(app, ["sweep", str(path), "--out", str(tmp_path / "o"), "--json"])
    assert out.exit_code == 0, out.output
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    assert rec["runs"] == 6 and len(rec["summary"]) == 2
    bad = CliRunner().invoke(app, ["sweep", str(tmp_path / "missing.yaml")])
    assert bad.exit_code == 2 and "error:" in bad.output


def test_infeasible_rows_do_not_break_the_tables(tmp_path):
    """A row without a feasible point is written as null (inf) and the plot still draws."""
    from eaco_jax.sweep.report import plot_summary, summarise

    rec = {"cell": "c0", "values": {"q0": 0.5},
           "rows": [{"best_cost": None}, {"best_cost": 2.0}]}
    assert summarise(rec)["best"] == 2.0 and summarise(rec)["runs"] == 2
    plot_summary(tmp_path / "s.png", [rec, {**rec, "rows": [{"best_cost": None}]}], "t")
    assert (tmp_path / "s.png").stat().st_size > 1000


# --------------------------------------------------------------------------- bounded plans
def _refused_fast(fn, match, seconds=1.5):
    """``fn`` raises one ConfigError line matching ``match`` within ``seconds``."""
    import time

    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=match) as err:
        fn()
    assert time.perf_counter() - t0 < seconds
    assert "\n" not in str(err.value)
    return str(err.value)


def _cli(*args):
    from typer.testing import CliRunner

    from eaco_jax.cli import app

    return CliRunner().invoke(app, ["sweep", *map(str, args)])


TSP = {"command": "tsp", "args": {"instance": "burma14", "ants": 4, "iterations": 2,
                                  "local_search": "none"}, "seeds": 1}


def test_list_valued_cell_refused_before_anything_is_built(tmp_path):
    _refused_fast(lambda: sw.plan({**TSP, "cells": [{"q0": [0.5, 0.6]}]}),
                  r"sweep cell 0 key 'q0': \[0.5, 0.6\] is a list, not one value; give each "
                  r"value its own cell, or sweep them with grid: \{q0: \[\.\.\.\]\}")
    _refused_fast(lambda: sw.plan({**SPEC, "grid": {"scale": [[0.5], 0.6]}}),
                  r"grid entry 'scale' value 0: \[0.5\] is a list, not one value")
    _refused_fast(lambda: sw.plan({**SPEC, "args": {"iterations": {"a": 1}}}),
                  r"sweep args key 'iterations': \{'a': 1\} is a mapping, not one value")
    _refused_fast(lambda: sw.plan({"kind": "test_sweep:TOY", "random": {
        "n": 2, "space": {"ants": {"choice": [[4, 8]]}}}}), r"choice 0: \[4, 8\] is a list")
    path = tmp_path / "s.yaml"
    path.write_text("command: tsp\nargs: {instance: burma14}\ncells: [{q0: [0.5, 0.6]}]\n")
    out = _cli(path, "--out", tmp_path / "o")
    assert out.exit_code == 2 and out.output.count("\n") == 1
    assert out.output.startswith("error: sweep cell 0 key 'q0': [0.5, 0.6] is a list")
    assert not (tmp_path / "o").exists()


def test_cell_count_is_bounded_before_any_product(tmp_path):
    grid = {f"k{i}": list(range(10)) for i in range(9)}
    msg = _refused_fast(lambda: sw.plan({**TSP, "grid": grid}), "the sweep has 1,000,000,000 "
                        "cells")
    assert "(10 k0 x 10 k1 x" in msg and "max_cells: N in the file, or --max-cells N" in msg
    _refused_fast(lambda: sw.plan({**TSP, "cells": [{}] * 3, "grid": grid}),
                  "3,000,000,000 cells \\(3 listed x 10 k0")
    _refused_fast(lambda: sw.plan({**TSP, "random": {"n": 10**9, "space": {"q0": [0, 1]}}}),
                  "1,000,000,000 cells \\(random n\\)")
    # the limit is the file's max_cells, overridden by the caller's (the command's flag)
    six = {**SPEC, "grid": {"scale": [0.25, 0.5, 1.0], "ants": [4, 8]}}
    _refused_fast(lambda: sw.plan({**six, "max_cells": 5}), "6 cells .* max_cells=5;")
    assert len(sw.plan({**six, "max_cells": 6})[1]) == 6
    _refused_fast(lambda: sw.plan(six, max_cells=5), "max_cells=5;")
    assert len(sw.plan({**six, "max_cells": 5}, max_cells=6)[1]) == 6
    _refused_fast(lambda: sw.plan({**six, "max_cells": 0}), "max_cells must be an integer >= 1")
    import yaml

    path = tmp_path / "six.yaml"
    path.write_text(yaml.safe_dump(six))
    out = _cli(path, "--max-cells", 5, "--out", tmp_path / "o")
    assert out.exit_code == 2 and out.output.startswith("error: the sweep has 6 cells")
    path.write_text(yaml.safe_dump({**six, "max_cells": 5, "args": {"iterations": 2}}))
    out = _cli(path, "--max-cells", 6, "--out", tmp_path / "o", "--json")
    assert out.exit_code == 0, out.output
    assert json.loads(out.stdout.strip().splitlines()[-1])["cells"] == 6


ALIAS_BOMB = "command: tsp\n" + "".join(
    f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else '0'] * 10)}]\n" for i in range(10)
) + "cells: [{q0: *l9}]\n"  # 10**10 leaves in 602 bytes


def test_yaml_alias_bomb_refused_fast_in_little_memory(tmp_path):
    import tracemalloc

    path = tmp_path / "bomb.yaml"
    path.write_text(ALIAS_BOMB)
    assert len(ALIAS_BOMB) < 1024
    tracemalloc.start()
    try:
        _refused_fast(lambda: sw.load_spec(path), r"bomb.yaml expands to more than 2,000,000 "
                      "values \\(through its aliases\\)")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20
    out = _cli(path)
    assert out.exit_code == 2 and out.output.count("\n") == 1 and "expands to more" in out.output
    path.write_text("command: tsp\nname: &a [*a]\n")
    _refused_fast(lambda: sw.load_spec(path), "holds a recursive alias")
    path.write_text("command: tsp\nname: " + "[" * 5000 + "]" * 5000 + "\n")
    _refused_fast(lambda: sw.load_spec(path), "nested too deeply", seconds=5)
    # a sweep file with ordinary aliases still loads
    path.write_text("kind: test_sweep:TOY\nargs: &a {iterations: 3}\ncells: [{scale: 0.5}]\n"
                    "grid: {ants: &n [4, 5]}\nname: ok\n")
    spec = sw.load_spec(path)
    assert spec.args == {"iterations": 3} and spec.grid == {"ants": (4, 5)}


def test_seeds_at_most_what_runs_and_rows_estimated_before_setup():
    msg = _refused_fast(lambda: sw.plan({**TSP, "seeds": 1048576}),
                        "seeds: 1,048,576 seeds is more than the 65,536 a sweep runs")
    assert "about 32 GiB of host memory" in msg
    _refused_fast(lambda: sw.plan({**TSP, "seeds": list(range(65537))}), "65,537 seeds")
    # within the seed limit, a group's rows (cells x seeds, one vmapped call) are estimated
    # with the driver's state estimate and refused before anything is set up
    many = {**SPEC, "seeds": 65536, "grid": {"scale": [i / 300 for i in range(1, 301)]}}
    msg = _refused_fast(lambda: sw.plan(many), r"the sweep's largest group needs about .* GiB "
                        r"\(300 cell\(s\) x 65,536 seeds = 19,660,800 rows of", seconds=10)
    assert "use fewer seeds" in msg


def test_the_spec_is_parsed_once_and_the_typed_spec_flows(tmp_path, monkeypatch):
    from eaco_jax.sweep import spec as spec_mod

    calls = []
    real = spec_mod._from_raw

    def counting(raw, max_cells):
        calls.append(raw)
        return real(raw, max_cells)

    monkeypatch.setattr(spec_mod, "_from_raw", counting)
    small = {**SPEC, "grid": {"scale": [0.5, 1.0]}, "seeds": 2}
    rec = sw.run_sweep(small, tmp_path / "a")
    assert len(calls) == 1 and rec["runs"] == 4
    typed = sw.parse_spec(small)
    assert isinstance(typed, sw.SweepSpec) and typed.seeds == (0, 1) and typed.run_kind is TOY
    assert typed.grid == {"scale": (0.5, 1.0)} and typed.num_cells == 2
    calls.clear()
    again = sw.run_sweep(typed, tmp_path / "a")
    assert calls == [] and again["cells_run_now"] == 0  # same cells: all finished already
    assert json.loads((tmp_path / "a" / "spec.json").read_text())["seeds"] == 2

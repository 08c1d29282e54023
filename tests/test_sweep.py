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

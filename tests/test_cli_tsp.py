"""``eaco tsp``: JSON schema, output files, clean errors."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.runs import kinds


def test_json_schema_and_out_folder(tmp_path):
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["tsp", "burma14", "--ants", "8", "--iterations", "6",
                                   "--seed", "3", "--json", "--out", str(out)])
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout.strip().splitlines()[-1])
    for key in ("instance", "best_length", "tour", "iterations", "evaluations", "seconds",
                "seconds_per_iteration", "history_best", "gap_percent", "optimum"):
        assert key in record, key
    assert record["instance"] == "burma14" and record["optimum"] == 3323
    assert isinstance(record["best_length"], int)
    assert sorted(record["tour"]) == list(range(14))
    assert record["iterations"] == 6 and record["evaluations"] == 48
    assert len(record["history_best"]) == 6 and record["history_best"][-1] == record["best_length"]
    assert abs(record["gap_percent"] - 100 * (record["best_length"] / 3323 - 1)) < 1e-9
    for name in ("result.json", "history.csv", "convergence.png", "tour.png"):
        assert (out / name).is_file(), name
    assert json.loads((out / "result.json").read_text())["best_length"] == record["best_length"]
    assert len((out / "history.csv").read_text().strip().splitlines()) == 7
    assert "tsp" in kinds()


def test_malformed_and_missing_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.tsp"
    bad.write_text("NAME: bad\nTYPE: TSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: EUC_2D\n"
                   "NODE_COORD_SECTION\n1 0 0\n2 oops 1\nEOF\n")
    runner = CliRunner()
    for target in (str(bad), str(tmp_path / "missing.tsp"), "no_such_instance"):
        res = runner.invoke(app, ["tsp", target, "--json"])
        assert res.exit_code == 2, (target, res.output)
        err = res.stderr.strip()
        assert err.startswith("error:") and len(err.splitlines()) == 1, err
        assert "Traceback" not in res.output


def test_library_bugs_keep_their_traceback(monkeypatch):
    """Only user errors become one line; anything else is a bug and is not hidden."""
    import pytest

    from eaco_jax.runs import tsp

    def broken(settings):
        raise TypeError("a bug deep in the library")

    monkeypatch.setattr(tsp, "build", broken)
    res = CliRunner().invoke(app, ["tsp", "burma14", "--iterations", "1", "--json"])
    assert res.exit_code != 2 and isinstance(res.exception, TypeError)
    with pytest.raises(TypeError, match="a bug deep"):
        tsp.run(tsp.TspSettings(instance="burma14", iterations=1))


def test_local_search_settings_reach_the_strategy(tmp_path):
    """--local-search 2opt+oropt --ls-best-k 3 runs (ACOTSP-style search on the 3 best) and
    is recorded; a k below 1 is a one-line error naming the setting."""
    from eaco_jax.runs import tsp

    settings = tsp.TspSettings("burma14", ants=8, iterations=4, local_search="2opt+oropt",
                               ls_best_k=3)
    built = tsp.build(settings)
    assert built.strategy.local_search == "2opt+oropt" and built.strategy.ls_best_k == 3
    res = CliRunner().invoke(app, ["tsp", "burma14", "--ants", "8", "--iterations", "4",
                                   "--local-search", "2opt+oropt", "--ls-best-k", "3",
                                   "--json"])
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout.strip().splitlines()[-1])
    assert record["local_search"] == "2opt+oropt" and record["ls_best_k"] == 3
    assert sorted(record["tour"]) == list(range(14))
    res = CliRunner().invoke(app, ["tsp", "burma14", "--ls-best-k", "0", "--json"])
    assert res.exit_code == 2 and "ls_best_k" in res.stderr, res.output
    assert len(res.stderr.strip().splitlines()) == 1


def test_ls_acceptance_reaches_the_strategy_and_keeps_the_tours():
    """--ls-acceptance unrolled runs the focused colony's search with its first greedy rounds
    inline: the record says so, and the tour is the one the default rounds loop finds (the
    same moves); an unknown name is a one-line error."""
    from eaco_jax.runs import tsp

    kw = dict(instance="eil51", sparse="on", ants=8, iterations=3, max_new_edges=8,
              construction="moves", merge_ants=4, seed=3, local_search="or-2opt")
    built = tsp.build(tsp.TspSettings(**kw, ls_acceptance="unrolled"))
    assert built.strategy.ls_acceptance == "unrolled"
    rounds = tsp.run(tsp.TspSettings(**kw))
    unrolled = tsp.run(tsp.TspSettings(**kw, ls_acceptance="unrolled"))
    assert (rounds["ls_acceptance"], unrolled["ls_acceptance"]) == ("rounds", "unrolled")
    assert unrolled["tour"] == rounds["tour"]
    res = CliRunner().invoke(app, ["tsp", "eil51", "--ls-acceptance", "eager", "--json"])
    assert res.exit_code == 2 and "ls_acceptance" in res.stderr, res.output
    assert len(res.stderr.strip().splitlines()) == 1


def test_setting_choices_are_the_strategys():
    """The settings list the strategy's names themselves (runs/tsp.py does not import the
    strategy, and so jax, to print --help): the two lists must not drift apart."""
    import dataclasses

    from eaco_jax.runs import tsp
    from eaco_jax.strategies import graph_eaco

    choices = {f.name: f.metadata["choices"] for f in dataclasses.fields(tsp.TspSettings)}
    assert choices["local_search"] == ("auto", *graph_eaco.LOCAL_SEARCHES)
    assert choices["preset"] == ("auto", *graph_eaco.PRESETS)
    assert choices["crossover"] == ("auto", *graph_eaco.CROSSOVERS)
    assert choices["mutation"] == ("auto", *graph_eaco.MUTATIONS)
    assert choices["ls_acceptance"] == ("auto", *graph_eaco.LS_ACCEPTANCES)


def test_auto_help_is_read_from_the_colony_table():
    """--help says what 'auto' resolves to from COLONY_DEFAULTS itself (every row, the
    short-budget one included), so the help cannot drift from the table."""
    import dataclasses

    from eaco_jax.runs import tsp

    helps = {f.name: f.metadata["help"] for f in dataclasses.fields(tsp.TspSettings)}
    assert ("auto: 50 on a CPU; on a GPU 768 below 700 cities, 384 below 1,500 cities (256 "
            "with --max-seconds 5 or less), else 96;") in helps["ants"]
    assert helps["local_search"].endswith(
        "auto: 2opt+oropt on a CPU; on a GPU 2opt below 8 cities, else or-2opt)")
    gpu = tsp.sparse_defaults("gpu")
    assert f"sparse path's default on a GPU {tsp.bands_text(gpu)};" in helps["ants"]
    three = dataclasses.replace(gpu, ants=(tsp.AntsBand(10, 8, "a"), tsp.AntsBand(20, 8, "b"),
                                           tsp.AntsBand(30, 4, "c"), tsp.AntsBand(40, 8, "d")))
    assert tsp.bands_text(three) == ("8 below 20 cities, 4 below 30 cities, "
                                     "8 below 40 cities")
    assert helps["ls_best_k"].endswith("(auto: the 25 best on a CPU; every tour on a GPU)")
    assert helps["ls_neighbors"].endswith("(auto: all on a CPU; on a GPU 16 below 700 cities, "
                                          "else all (8 for 700-1,499 cities with "
                                          "--max-seconds 5 or less))")
    assert helps["preset"].endswith("auto: mmas on a CPU; on a GPU default below 700 cities, "
                                    "else mmas")
    colony = tsp.ColonyDefaults(10, "2opt", None, "mmas")
    rows = (tsp.ColonyRow("cpu", 0, None, None, colony, "x"),
            tsp.ColonyRow("gpu", 0, None, 2.0, dataclasses.replace(colony, ants=30), "x"),
            tsp.ColonyRow("gpu", 0, None, None, dataclasses.replace(colony, ants=20), "x"))
    assert tsp.auto_help("ants", rows=rows) == \
        "10 on a CPU; 20 (30 with --max-seconds 2 or less) on a GPU"


def test_colony_defaults_by_backend(tmp_path):
    """--ants / --local-search / --ls-best-k / --preset left out: on a CPU (this machine) 50
    ants, don't-look-bit 2-opt + Or-opt on the 25 best, MMAS as ACOTSP runs it; on a GPU
    or-2opt with the measured best colony for the instance size; an explicit value wins."""
    from eaco_jax.runs import tsp

    cpu = tsp.colony_defaults(442, "cpu")
    assert (cpu.ants, cpu.local_search, cpu.ls_best_k, cpu.preset) == (
        50, "2opt+oropt", 25, "mmas")
    for n, ants, preset, k in ((442, 768, "default", 16), (1002, 384, "mmas", None),
                               (2392, 96, "mmas", None)):
        gpu = tsp.colony_defaults(n, "gpu")
        assert (gpu.ants, gpu.local_search, gpu.ls_best_k, gpu.preset, gpu.ls_neighbors) == (
            ants, "or-2opt", None, preset, k)
    assert tsp.colony_defaults(7, "gpu").local_search == "2opt"
    # a short budget on 700-1,499 cities: 256 ants scanning 8 candidates; else the above
    for n, seconds, want in ((1002, 3.7, (256, 8)), (783, 5.0, (256, 8)), (1002, 5.5, (384, None)),
                             (1002, None, (384, None)), (442, 3.0, (768, 16)),
                             (2392, 3.0, (96, None))):
        gpu = tsp.colony_defaults(n, "gpu", seconds)
        assert (gpu.ants, gpu.ls_neighbors) == want, (n, seconds)
    assert tsp.colony_defaults(1002, "cpu", 3.0).ls_neighbors is None
    st = tsp.build(tsp.TspSettings("burma14", ls_neighbors=5, iterations=2)).strategy
    assert st.ls_neighbors == 5
    built = tsp.build(tsp.TspSettings("burma14", iterations=2))
    st = built.strategy
    assert (st.num_ants, st.local_search, st.ls_best_k, st.preset) == (
        50, "2opt+oropt", 25, "mmas")
    assert (st.crossover, st.mutation) == ("none", "none")  # ACOTSP's MMAS has neither
    built = tsp.build(tsp.TspSettings("burma14", ants=6, local_search="or-2opt", ls_best_k=2,
                                      preset="default"))
    st = built.strategy
    assert (st.num_ants, st.local_search, st.ls_best_k, st.preset) == (6, "or-2opt", 2, "default")
    assert st.crossover == "erx"
    res = CliRunner().invoke(app, ["tsp", "burma14", "--iterations", "2", "--json"])
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout.strip().splitlines()[-1])
    assert (record["ants"], record["local_search"], record["ls_best_k"], record["preset"],
            record["ls_neighbors"]) == (50, "2opt+oropt", 25, "mmas", None)


def test_checkpoint_stores_the_resolved_colony(tmp_path):
    """A checkpointed run stores what auto resolved to (ants, local search, ls_best_k,
    preset), so eaco resume rebuilds the same colony on another backend; resume continues."""
    from eaco_jax.driver.checkpoint import read_meta

    ck = tmp_path / "ck"
    res = CliRunner().invoke(app, ["tsp", "burma14", "--iterations", "6", "--checkpoint-dir",
                                   str(ck), "--checkpoint-every", "3", "--json"])
    assert res.exit_code == 0, res.output
    stored = read_meta(ck)["run_info"]["settings"]
    assert (stored["ants"], stored["local_search"], stored["ls_best_k"], stored["preset"]) == (
        50, "2opt+oropt", 25, "mmas")
    again = CliRunner().invoke(app, ["resume", str(ck), "--json"])
    assert again.exit_code == 0, again.output
    assert (json.loads(again.stdout.strip().splitlines()[-1])["best_length"]
            == json.loads(res.stdout.strip().splitlines()[-1])["best_length"])


def test_max_seconds_alone_governs_the_run(tmp_path):
    """Issue 33: with --max-seconds and no --iterations, time ends the run (not the default
    300 iterations), the record and the summary line say so, and the checkpoint resumes."""
    out, ck = tmp_path / "run", tmp_path / "ck"
    res = CliRunner().invoke(app, ["tsp", "eil51", "--max-seconds", "2", "--local-search",
                                   "none", "--ants", "8", "--out", str(out),
                                   "--checkpoint-dir", str(ck), "--checkpoint-every", "100"])
    assert res.exit_code == 0, res.output
    record = json.loads((out / "result.json").read_text())
    assert record["stop_reason"] == "max_seconds", record["stop_reason"]
    assert record["iterations"] > 300 and record["seconds"] >= 2.0
    assert "stopped by max_seconds" in res.stdout.strip().splitlines()[-1]
    assert read_settings(ck)["iterations"] is None
    again = CliRunner().invoke(app, ["resume", str(ck), "--json"])
    assert again.exit_code == 0, again.output
    assert json.loads(again.stdout.strip().splitlines()[-1])["best_length"] == \
        record["best_length"]


def test_no_budget_stops_at_the_default_iterations():
    res = CliRunner().invoke(app, ["tsp", "burma14", "--local-search", "none", "--ants", "8",
                                   "--json"])
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout.strip().splitlines()[-1])
    assert (record["iterations"], record["stop_reason"]) == (300, "iterations")


def read_settings(ck):
    from eaco_jax.driver.checkpoint import read_meta

    return read_meta(ck)["run_info"]["settings"]


def test_sparse_defaults_resolve_by_backend_and_stay_pinned_for_resume(monkeypatch, capsys):
    """A sparse run left on --construction auto without --max-new-edges gets its backend's
    SPARSE_DEFAULTS row (on a GPU: 128 new edges as moves, ants by size, 96 merged) and the focused
    search (LS_FOCUS_WIDTH); a CPU has no row; explicit settings win; 0 turns the focus off; the
    stored settings pin what resolved, so a resume on another backend builds the same colony."""
    import jax

    from eaco_jax.driver.minimize import Checkpointing
    from eaco_jax.runs import tsp

    def strategy(**kw):
        return tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2, **kw)).strategy

    cpu = tsp.sparse_defaults("cpu")
    st = strategy()  # this machine: a CPU, 32 new edges city by city
    assert (st.max_new_edges, st.construction) == (cpu.max_new_edges, "ants")
    st = strategy(construction="scan")  # explicit: full construction
    assert (st.max_new_edges, st.construction, st.ls_focus_width) == (None, "ants", None)
    st = strategy(max_new_edges=8, local_search="or-2opt")
    assert (st.max_new_edges, st.ls_focus_width) == (8, tsp.LS_FOCUS_WIDTH)
    assert strategy(max_new_edges=8, ls_focus_width=0).ls_focus_width is None
    assert strategy(max_new_edges=8, ls_focus_width=16).ls_focus_width == 16
    ck = Checkpointing("unused", run_info={"settings": {"construction": "scan"}})
    built = tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2, construction="scan"))
    pinned = tsp.with_resolved_settings(ck, built).run_info["settings"]
    assert (pinned["max_new_edges"], pinned["construction"], pinned["ls_focus_width"]) == (
        None, "scan", 0)  # full construction stays full on a backend with a row
    ck = Checkpointing("unused", run_info={"settings": {"construction": "auto"}})
    built = tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2))
    pinned = tsp.with_resolved_settings(ck, built).run_info["settings"]
    assert (pinned["max_new_edges"], pinned["construction"]) == (cpu.max_new_edges, "scan")

    from eaco_jax.problems.tsp_sparse import is_sparse

    # --sparse auto: a CPU takes the sparse path from its row's from_cities (pr2392 has 2,392)
    assert cpu.from_cities <= 2392
    assert is_sparse(tsp.build(tsp.TspSettings("pr2392", iterations=2)).problem)
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert not is_sparse(tsp.build(tsp.TspSettings("pr2392", iterations=2)).problem)
    row = tsp.sparse_defaults("gpu")
    assert row.merge_ants >= 2
    st = strategy()
    built_c, built_e = tsp.row_construction(row, 51)
    assert (st.max_new_edges, st.construction, st.ls_focus_width, st.merge_ants) == (
        built_e, built_c, tsp.LS_FOCUS_WIDTH, row.merge_ants)
    # the constructions by size, as the colony sizes; past the last band the row's own
    bands = row.constructions
    assert bands and [b.below for b in bands] == sorted(b.below for b in bands)
    assert (built_c, built_e) == (bands[0].construction, bands[0].max_new_edges)
    for lo, hi in zip(bands, bands[1:], strict=False):
        assert tsp.row_construction(row, lo.below - 1) == (lo.construction, lo.max_new_edges)
        assert tsp.row_construction(row, lo.below) == (hi.construction, hi.max_new_edges)
    assert tsp.row_construction(row, bands[-1].below) == (row.construction, row.max_new_edges)
    assert len({tsp.row_construction(row, b.below - 1) for b in bands}) > 1  # bands differ
    assert strategy(merge_ants=0).merge_ants is None  # 0 turns the row's merging off
    assert strategy(merge_ants=8).merge_ants == 8
    first, last = row.ants[0], row.ants[-1]
    assert st.num_ants == first.ants  # the row's colony size for 51 cities
    assert first.ants != tsp.colony_defaults(51, "gpu").ants  # (else the check above is idle)
    assert strategy(ants=40).num_ants == 40  # an explicit --ants wins over the row
    # the bands by size; past the last the size table decides (100,000 cities: measured with
    # the table's colony)
    assert [b.below for b in row.ants] == sorted(b.below for b in row.ants)
    for lo, hi in zip(row.ants, row.ants[1:], strict=False):
        assert tsp.row_ants(row, lo.below - 1) == lo.ants and tsp.row_ants(row, lo.below) == hi.ants
    assert last.below <= 100_000 and tsp.row_ants(row, 100_000) is None
    assert tsp.row_ants(row, last.below) is None and tsp.row_ants(row, last.below - 1) == last.ants
    import dataclasses

    small = dataclasses.replace(row, ants=(tsp.AntsBand(51, 7, ""),))  # eil51 past the band
    monkeypatch.setattr(tsp, "SPARSE_DEFAULTS", (small,))
    assert strategy().num_ants == tsp.colony_defaults(51, "gpu").ants
    monkeypatch.setattr(tsp, "SPARSE_DEFAULTS", (row,))
    st = strategy(construction="scan")  # an explicit construction: no row
    assert (st.max_new_edges, st.construction, st.merge_ants) == (None, "ants", None)
    assert st.num_ants == tsp.colony_defaults(51, "gpu").ants
    capsys.readouterr()
    st = strategy(max_new_edges=8, construction="moves")  # explicit edges: no row, no merge
    assert (st.max_new_edges, st.merge_ants) == (8, None)
    assert "leaves out this backend's measured sparse row" in capsys.readouterr().err  # said
    strategy(max_new_edges=8, construction="moves", ants=40)
    assert capsys.readouterr().err == ""  # --ants chosen: nothing to say
    st = tsp.build(tsp.TspSettings("eil51", iterations=2)).strategy  # dense: no row
    assert st.max_new_edges is None
    built = tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2))
    pinned = tsp.with_resolved_settings(ck, built).run_info["settings"]
    keys = ("max_new_edges", "construction", "ls_focus_width", "merge_ants", "ants",
            "reference")
    assert tuple(pinned[k] for k in keys) == (
        built_e, built_c, tsp.LS_FOCUS_WIDTH, row.merge_ants, row.ants[0].ants, "best")
    # the reference: the best so far unless told otherwise, on the row's path or not
    assert strategy().reference == "best"
    assert strategy(reference="iteration").reference == "iteration"
    assert strategy(reference="iteration", max_new_edges=8, construction="moves",
                    ants=40).reference == "iteration"
    monkeypatch.undo()
    st = tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2,
                                   **{k: pinned[k] for k in keys})).strategy
    assert (st.max_new_edges, st.construction, st.ls_focus_width, st.merge_ants,
            st.num_ants, st.reference) == (built_e, built_c, 128, row.merge_ants,
                                           row.ants[0].ants, "best")
    # the CPU's row merges nothing: a pinned CPU run resumes without merging on any backend
    ck_cpu = Checkpointing("unused", run_info={"settings": {"construction": "auto"}})
    built = tsp.build(tsp.TspSettings("eil51", sparse="on", iterations=2))
    assert tsp.with_resolved_settings(ck_cpu, built).run_info["settings"]["merge_ants"] == 0

"""Checkpoints: exact resume, retention, refusal of foreign/corrupt/incompatible checkpoints."""

import dataclasses
import hashlib
import math
import shutil
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_driver import RandomSearch, Sphere

import eaco_jax as ea
from eaco_jax.driver.checkpoint import CheckpointError, latest_step, read_meta


def _problem(scale=1.0):
    return Sphere(lower=-scale * jnp.ones(3), upper=scale * jnp.ones(3))


def mini(problem, strategy, *, checkpoint_dir=None, checkpoint_every=None,
         checkpoint_seconds=None, keep=3, run_info=None, **kw):
    """minimize with the checkpoint options spelled out as keywords."""
    ck = None
    if checkpoint_dir is not None:
        ck = ea.Checkpointing(checkpoint_dir, every=checkpoint_every, seconds=checkpoint_seconds,
                              keep=keep, run_info=run_info)
    return ea.minimize(problem, strategy, checkpointing=ck, **kw)


def _run(tmp, seed=1, iterations=30, **kw):
    kw.setdefault("chunk_size", 5)
    return mini(_problem(), RandomSearch(), seed=seed, iterations=iterations,
                checkpoint_dir=tmp, **kw)


def _same(a, b):
    np.testing.assert_array_equal(a.best_cost, b.best_cost)
    np.testing.assert_array_equal(a.best_solution, b.best_solution)
    assert a.history.keys() == b.history.keys()
    for k in a.history:
        np.testing.assert_array_equal(a.history[k], b.history[k], err_msg=k)
    assert a.iterations == b.iterations


def _fingerprint(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name != ".lock"}


def _steps(folder: Path) -> list[int]:
    return sorted(int(p.name) for p in folder.iterdir() if p.name.isdigit())


@pytest.mark.parametrize("seed", [1, [1, 2, 3]])
def test_resume_from_every_step_is_bit_identical(tmp_path, seed):
    unbroken = ea.minimize(_problem(), RandomSearch(), seed=seed, iterations=30, chunk_size=5)
    full = tmp_path / "full"
    first = _run(full, seed=seed, checkpoint_every=10, keep=5)
    _same(unbroken, first)
    assert _steps(full) == [10, 20, 30]
    for step in (10, 20):  # pretend the run died right after saving `step`
        part = tmp_path / f"upto{step}"
        shutil.copytree(full, part)
        for later in _steps(part):
            if later > step:
                shutil.rmtree(part / str(later))
        seen = []  # iterations done after each chunk this process computed
        resumed = _run(part, seed=seed, checkpoint_every=10,
                       callback=lambda state, info, seen=seen: seen.append(info.iterations))
        _same(unbroken, resumed)
        assert _steps(part)[-1] == 30
        # only the chunks after `step` ran: a run recomputed from the seed matches too
        assert seen == list(range(step + 5, 31, 5))
    # a finished run in the folder is returned as it is, computing nothing
    seen = []
    _same(unbroken, _run(full, seed=seed, checkpoint_every=10,
                         callback=lambda state, info: seen.append(info.iterations)))
    assert seen == []


def test_prng_key_and_counters_survive(tmp_path):
    a = _run(tmp_path, iterations=20, checkpoint_every=5)
    b = _run(tmp_path, iterations=20, checkpoint_every=5)
    assert jax.dtypes.issubdtype(b.state.key.dtype, jax.dtypes.prng_key)
    np.testing.assert_array_equal(jax.random.key_data(a.state.key),
                                  jax.random.key_data(b.state.key))
    assert int(b.state.iteration) == 20 and int(b.state.evaluations) == 20 * 8


def test_keeps_last_k_and_time_trigger(tmp_path):
    _run(tmp_path / "k", iterations=40, checkpoint_every=5, keep=2)
    assert _steps(tmp_path / "k") == [35, 40]
    # every chunk is "due" after 1e-9 s: one checkpoint per chunk (only the last 3 kept)
    _run(tmp_path / "t", iterations=20, chunk_size=4, checkpoint_seconds=1e-9)
    assert _steps(tmp_path / "t") == [12, 16, 20]
    # without a trigger only the end of the run is saved
    _run(tmp_path / "end", iterations=20)
    assert _steps(tmp_path / "end") == [20]


def test_checkpoint_every_sets_default_chunk(tmp_path):
    mini(_problem(), RandomSearch(), seed=0, iterations=100, checkpoint_every=3,
         checkpoint_dir=tmp_path, keep=100)
    assert _steps(tmp_path)[:3] == [3, 6, 9] and _steps(tmp_path)[-1] == 100


def test_target_stop_is_remembered(tmp_path):
    a = _run(tmp_path, iterations=200, target=0.5, checkpoint_every=5)
    assert a.iterations < 200
    b = _run(tmp_path, iterations=200, target=0.5, checkpoint_every=5)
    _same(a, b)


@pytest.mark.parametrize(
    "change, needle",
    [
        (dict(problem=_problem(2.0)), "problem hash"),
        (dict(strategy=RandomSearch(num_ants=9)), "config fields"),
        (dict(iterations=40), "config total"),
        (dict(seed=7), "config seeds"),
        (dict(params="scaled"), "config params_hash"),
    ],
)
def test_foreign_checkpoint_refused_and_untouched(tmp_path, change, needle):
    _run(tmp_path, checkpoint_every=10)
    before = _fingerprint(tmp_path)
    kw = dict(problem=_problem(), strategy=RandomSearch(), seed=1, iterations=30, chunk_size=5)
    if change.get("params") == "scaled":
        change = dict(params=RandomSearch().default_params(None).replace(scale=jnp.float32(0.5)))
    kw.update(change)
    problem, strategy = kw.pop("problem"), kw.pop("strategy")
    with pytest.raises(CheckpointError, match=needle) as err:
        mini(problem, strategy, checkpoint_dir=tmp_path, checkpoint_every=10, **kw)
    assert "\n" not in str(err.value)
    assert _fingerprint(tmp_path) == before


def test_incompatible_version_refused(tmp_path, monkeypatch):
    _run(tmp_path)
    before = _fingerprint(tmp_path)
    from eaco_jax.driver import checkpoint

    monkeypatch.setattr(checkpoint, "__version__", "0.3.0")
    with pytest.raises(CheckpointError, match="incompatible"):
        _run(tmp_path)
    monkeypatch.setattr(checkpoint, "__version__", "0.2.7")  # patch releases are compatible
    _run(tmp_path)
    assert _fingerprint(tmp_path) == before


def _damage(step_dir: Path, damage: str) -> None:
    if damage == "meta":
        target = step_dir / "meta" / "metadata"
        target.write_text(target.read_text()[:20])
        return
    arrays = [p for p in (step_dir / "state").rglob("*") if p.is_file() and p.parent.name == "d"]
    assert arrays
    for target in arrays:
        data = bytearray(target.read_bytes())
        if damage == "truncate":
            data = data[: len(data) // 2]
        elif damage == "garble":
            data = bytearray(b ^ 0x5A for b in data)
        else:  # one flipped bit in the middle of the file
            data[len(data) // 2] ^= 0x01
        target.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", ["truncate", "garble", "meta", "flip"])
def test_corrupt_step_moved_aside_and_resume_falls_back(tmp_path, damage):
    """The newest step damaged: a warning, the step moved to corrupt/ (not deleted), the run
    continues from the previous step and ends bit-identical to an unbroken run."""
    unbroken = _run(tmp_path / "ref", checkpoint_every=10, keep=5)
    ck = tmp_path / "ck"
    _run(ck, iterations=30, checkpoint_every=10, keep=5)
    shutil.rmtree(ck / "30")
    _damage(ck / "20", damage)
    with pytest.warns(UserWarning, match="step 20 .* corrupt"):
        resumed = _run(ck, checkpoint_every=10, keep=5)
    _same(unbroken, resumed)
    moved = list((ck / "corrupt").iterdir())
    assert len(moved) == 1 and moved[0].name.startswith("20-")
    assert _steps(ck) == [10, 20, 30]


def test_every_step_corrupt_is_one_line(tmp_path):
    _run(tmp_path, iterations=10, checkpoint_every=10)
    _damage(tmp_path / "10", "flip")
    with pytest.warns(UserWarning), pytest.raises(CheckpointError, match="every checkpoint"):
        _run(tmp_path, iterations=10, checkpoint_every=10)
    assert (tmp_path / "corrupt").is_dir()


def test_second_run_on_one_folder_is_refused(tmp_path):
    from eaco_jax.driver.checkpoint import _Lock

    holder = _Lock(tmp_path)
    tmp_path.mkdir(exist_ok=True)
    holder.acquire()
    try:
        with pytest.raises(CheckpointError, match="in use by another run"):
            _run(tmp_path, checkpoint_every=10)
    finally:
        holder.release()
    _run(tmp_path, checkpoint_every=10)  # free again


def test_save_frequency_is_not_identity_and_saves_land_on_multiples(tmp_path):
    unbroken = _run(tmp_path / "ref", iterations=30, chunk_size=7)
    ck = tmp_path / "ck"
    _run(ck, iterations=30, chunk_size=7, checkpoint_every=5, keep=10)
    assert _steps(ck) == [5, 10, 15, 20, 25, 30]
    for step in (30, 25, 20):
        shutil.rmtree(ck / str(step))
    # resumed with another checkpoint interval (and chunk size): accepted, same result
    _same(unbroken, _run(ck, iterations=30, chunk_size=4, checkpoint_every=10, keep=10))
    assert _steps(ck) == [5, 10, 15, 20, 30]


def test_unwritable_checkpoint_folder_is_one_line(tmp_path):
    import os

    blocked = tmp_path / "ro"
    blocked.mkdir()
    os.chmod(blocked, 0o500)
    try:
        if os.access(blocked, os.W_OK):
            pytest.skip("running as a user who can write anywhere")
        with pytest.raises(CheckpointError, match="not writable"):
            _run(blocked / "ck", checkpoint_every=10)
    finally:
        os.chmod(blocked, 0o700)
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(CheckpointError, match="is a file"):
        _run(afile, checkpoint_every=10)


def test_half_written_step_is_ignored(tmp_path):
    """A write killed before orbax's final rename leaves a tmp folder that is never restored."""
    unbroken = _run(tmp_path / "ref", checkpoint_every=10)
    ck = tmp_path / "ck"
    shutil.copytree(tmp_path / "ref", ck)
    shutil.rmtree(ck / "30")
    shutil.copytree(ck / "20", ck / "30.orbax-checkpoint-tmp-1234")
    shutil.rmtree(ck / "30.orbax-checkpoint-tmp-1234" / "state")
    assert latest_step(ck) == 20
    _same(unbroken, _run(ck, checkpoint_every=10))
    assert latest_step(ck) == 30


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="checkpoint_every"):
        _run(tmp_path, checkpoint_every=0)
    with pytest.raises(CheckpointError, match="no checkpoint"):
        read_meta(tmp_path / "nothing")


def test_eaco_resume_cli_continues_stored_run(tmp_path):
    """A run kind of one's own, checkpointed, killed (newest steps gone), resumed by the CLI."""
    import dataclasses
    import json

    from typer.testing import CliRunner

    from eaco_jax.cli import app
    from eaco_jax.outputs import to_jsonable
    from eaco_jax.runs import Built, RunKind, registry
    from eaco_jax.runs.base import checkpointing_for

    @dataclasses.dataclass(frozen=True)
    class ToySettings:
        iterations: int = 30
        seed: int = 0

    def build(s):
        return Built(_problem(), RandomSearch(), None, {"iterations": s.iterations})

    def run(s, *, progress=False, checkpointing=None):
        b = build(s)
        res = ea.minimize(b.problem, b.strategy, seed=s.seed, chunk_size=5, progress=progress,
                          checkpointing=checkpointing, **b.budget)
        return {"best": float(res.best_cost), "iterations": res.iterations,
                "history_best": res.history["best_cost"]}

    kind = registry.register(RunKind("toy", ToySettings, build, run))
    try:
        s = ToySettings(iterations=30, seed=4)
        unbroken = run(s, checkpointing=checkpointing_for("toy", s, tmp_path / "a", 10))
        run(s, checkpointing=checkpointing_for("toy", s, tmp_path / "b", 10))
        shutil.rmtree(tmp_path / "b" / "30")
        shutil.rmtree(tmp_path / "b" / "20")
        out = CliRunner().invoke(app, ["resume", str(tmp_path / "b"), "--json"])
        assert out.exit_code == 0, out.output
        record = json.loads(out.stdout.strip().splitlines()[-1])
        assert record == json.loads(json.dumps(to_jsonable(unbroken)))
        bad = CliRunner().invoke(app, ["resume", str(tmp_path / "missing")])
        assert bad.exit_code == 2 and "does not exist" in bad.output
        assert kind is registry.get("toy")
    finally:
        registry._KINDS.pop("toy", None)


def test_problem_hash_ignores_static_functions_but_not_leaves():
    from flax import struct

    from eaco_jax.driver.checkpoint import tree_hash

    @struct.dataclass
    class WithFn:
        lower: jax.Array
        fn: object = struct.field(pytree_node=False, default=None)

    a = WithFn(lower=jnp.zeros(3), fn=lambda x: x)
    b = WithFn(lower=jnp.zeros(3), fn=lambda x: x)  # another object, another repr
    assert tree_hash(a) == tree_hash(b)
    assert tree_hash(a) != tree_hash(WithFn(lower=jnp.ones(3)))
    assert tree_hash(a) != tree_hash(WithFn(lower=jnp.zeros(3, jnp.int32)))


@pytest.mark.slow
@pytest.mark.parametrize("which", ["graph", "continuous"])
def test_real_strategies_resume_bit_identical(tmp_path, which):
    """GraphEACO on eil51 and ContinuousEACO on g01 (float64): resume from step 4 and 8."""
    import contextlib

    from eaco_jax.problems import cec2006, float64, load_tsplib
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO
    from eaco_jax.strategies.graph_eaco import GraphEACO

    if which == "graph":
        ctx, make = contextlib.nullcontext, lambda: (load_tsplib("eil51"), GraphEACO(num_ants=8))
    else:
        ctx, make = float64, lambda: (cec2006("g01"), ContinuousEACO(num_ants=10))
    with ctx():
        problem, strategy = make()
        kw = dict(seed=[0, 1], iterations=12, chunk_size=4, checkpoint_every=4, keep=5)
        full = mini(problem, strategy, checkpoint_dir=tmp_path / "full", **kw)
        shutil.copytree(tmp_path / "full", tmp_path / "part")
        for step in ("12", "8"):
            shutil.rmtree(tmp_path / "part" / step)
        resumed = mini(problem, strategy, checkpoint_dir=tmp_path / "part", **kw)
    _same(full, resumed)
    for name in ("f", "violation"):
        np.testing.assert_array_equal(getattr(full, name), getattr(resumed, name))


def test_checkpoint_of_the_old_state_layout_refused(tmp_path, monkeypatch):
    """Checkpoints of an older layout (format 1: problem data in the state; 2: history in
    every step) get one line."""
    from eaco_jax.driver import checkpoint

    now = checkpoint.FORMAT
    monkeypatch.setattr(checkpoint, "FORMAT", now - 1)
    _run(tmp_path, iterations=10)
    monkeypatch.setattr(checkpoint, "FORMAT", now)
    before = _fingerprint(tmp_path)
    with pytest.raises(CheckpointError,
                       match=f"has format {now - 1}, this eaco_jax reads format {now}") as e:
        _run(tmp_path, iterations=10)
    assert "\n" not in str(e.value) and _fingerprint(tmp_path) == before


def test_history_is_one_append_only_log_not_a_copy_per_step(tmp_path):
    """Each save appends the iterations since the last one to history/ (one segment per
    save); the steps hold the state only, so a save costs the same however long the run."""
    from eaco_jax.driver.history import HistoryLog

    res = _run(tmp_path, iterations=30, checkpoint_every=10, keep=2)
    segs = HistoryLog(tmp_path / "history", 0).segments()
    assert [(s, e) for s, e, _ in segs] == [(0, 10), (10, 20), (20, 30)]
    assert _steps(tmp_path) == [20, 30]  # keep=2 drops steps, never history segments
    items = {p.name for p in (tmp_path / "30").iterdir() if p.is_dir()}
    assert items == {"state", "meta"}  # no history item in the step
    logged = HistoryLog(tmp_path / "history", 0).read(30, read_meta(tmp_path)["history_chain"])
    for k, v in res.history.items():
        np.testing.assert_array_equal(logged[k], v, err_msg=k)


@pytest.mark.parametrize("damage", ["flip", "missing"])
def test_corrupt_history_segment_moved_aside_with_its_step(tmp_path, damage):
    """A flipped byte in (or the loss of) the newest history segment: the step that needs it
    and the segment go to corrupt/ with a warning; the run resumes from the step before and
    ends bit-identical to an unbroken run."""
    unbroken = _run(tmp_path / "ref", checkpoint_every=10, keep=5)
    ck = tmp_path / "ck"
    _run(ck, iterations=30, checkpoint_every=10, keep=5)
    shutil.rmtree(ck / "30")
    seg = ck / "history" / f"{10:012d}-{20:012d}.npz"
    if damage == "missing":
        seg.unlink()
    else:
        data = bytearray(seg.read_bytes())
        data[len(data) // 2] ^= 0x01
        seg.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match="step 20 .* corrupt .*history"):
        resumed = _run(ck, checkpoint_every=10, keep=5)
    _same(unbroken, resumed)
    moved = sorted(p.name for p in (ck / "corrupt").iterdir())
    assert moved[0].startswith("20-")
    if damage == "flip":
        assert len(moved) == 2 and moved[1].startswith("history-000000000010-000000000020")
    assert _steps(ck) == [10, 20, 30]


def test_segments_past_the_restored_step_are_rewritten(tmp_path):
    """A save killed after its history segment but before its step: the segment is past the
    newest step, dropped on resume, and written again (the result equals an unbroken run)."""
    unbroken = _run(tmp_path / "ref", checkpoint_every=10, keep=5)
    ck = tmp_path / "ck"
    _run(ck, iterations=30, checkpoint_every=10, keep=5)
    shutil.rmtree(ck / "30")  # the step never landed; its segment [20, 30) did
    (ck / "history" / ".tmp-1-30-40.npz").write_bytes(b"half a save")
    resumed = _run(ck, checkpoint_every=10, keep=5)
    _same(unbroken, resumed)
    assert not list((ck / "history").glob(".tmp-*"))
    assert not (ck / "corrupt").exists()


def test_driver_holds_only_the_history_since_the_last_save(tmp_path, monkeypatch):
    """Memory stays flat on a long checkpointed run: every save is handed the chunks since the
    previous save only (never the whole history), and the result still has every iteration."""
    from eaco_jax.driver.checkpoint import RunCheckpointer

    seen = []
    original = RunCheckpointer.after_chunk

    def spy(self, state, done, pending, finished, force=False):
        seen.append(sum(next(iter(h.values())).shape[0] for h in pending))
        return original(self, state, done, pending, finished, force)

    monkeypatch.setattr(RunCheckpointer, "after_chunk", spy)
    res = _run(tmp_path, iterations=60, checkpoint_every=10, chunk_size=5)
    assert max(seen) <= 10 and len(seen) == 12  # 12 chunks of 5, a save every 2
    assert res.history["best_cost"].shape[0] == 60
    unbroken = ea.minimize(_problem(), RandomSearch(), seed=1, iterations=60, chunk_size=5)
    _same(unbroken, res)


def _segment_names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.glob("*.npz"))


def test_fresh_run_sets_an_earlier_runs_history_aside(tmp_path):
    """A fresh run (no step in the folder) with another interval over an earlier run's
    segments: they are moved to old/ (kept), the run and its resume equal an unbroken one."""
    ck = tmp_path / "ck"
    _run(ck, iterations=30, checkpoint_every=10)
    earlier = _segment_names(ck / "history")
    for step in _steps(ck):
        shutil.rmtree(ck / str(step))
    unbroken = _run(tmp_path / "ref", iterations=25, checkpoint_every=5)
    with pytest.warns(UserWarning, match=r"3 history segment\(s\) .* earlier run"):
        fresh = _run(ck, iterations=25, checkpoint_every=5)
    _same(unbroken, fresh)
    assert _segment_names(ck / "history") == _segment_names(tmp_path / "ref" / "history")
    (old,) = (ck / "old").iterdir()
    assert _segment_names(old) == earlier
    _same(unbroken, _run(ck, iterations=25, checkpoint_every=5))


def test_history_read_prefers_the_segments_that_chain(tmp_path):
    """A folder where an earlier run's segments (0-10, 10-20, 20-30) sit beside this run's
    (0-5, ..., 20-25): read follows the chain, and a resume sets the others aside."""
    from eaco_jax.driver.history import HistoryLog

    ck, other = tmp_path / "ck", tmp_path / "other"
    _run(other, iterations=30, checkpoint_every=10)
    unbroken = _run(ck, iterations=25, checkpoint_every=5, keep=5)
    for seg in (other / "history").glob("*.npz"):
        shutil.copy(seg, ck / "history" / seg.name)
    shutil.rmtree(ck / "25")
    log = HistoryLog(ck / "history", 0)
    logged = log.read(20, read_meta(ck)["history_chain"])
    for k, v in unbroken.history.items():
        np.testing.assert_array_equal(logged[k], v[:20], err_msg=k)
    with pytest.warns(UserWarning, match=r"2 history segment.* \(step 20 does not chain"):
        resumed = _run(ck, iterations=25, checkpoint_every=5, keep=5)
    _same(unbroken, resumed)
    assert _steps(ck) == [5, 10, 15, 20, 25] and not (ck / "corrupt").exists()
    assert _segment_names(next((ck / "old").iterdir())) == [
        f"{0:012d}-{10:012d}.npz", f"{10:012d}-{20:012d}.npz"]


def _toy_kind():
    """A small checkpointed run kind of one's own (registered; pop it from registry._KINDS)."""
    import dataclasses

    from eaco_jax.runs import Built, RunKind, registry

    @dataclasses.dataclass(frozen=True)
    class ToySettings:
        iterations: int = 30
        seed: int = 0

    def build(s):
        return Built(_problem(), RandomSearch(), None, {"iterations": s.iterations})

    def run(s, *, progress=False, checkpointing=None):
        b = build(s)
        res = ea.minimize(b.problem, b.strategy, seed=s.seed, chunk_size=5, progress=progress,
                          checkpointing=checkpointing, **b.budget)
        return {"best": float(res.best_cost), "iterations": res.iterations}

    return registry.register(RunKind("toy", ToySettings, build, run)), ToySettings


def test_resume_after_every_checkpoint_was_corrupt_names_the_command(tmp_path):
    """Every step corrupt: the first `eaco resume` moves them aside, and it and every later
    one say so and print the command that starts the run again (from run.json); nothing
    moved aside is lost."""
    import json

    from typer.testing import CliRunner

    from eaco_jax.cli import app
    from eaco_jax.runs import registry
    from eaco_jax.runs.base import checkpointing_for

    kind, settings = _toy_kind()
    try:
        s = settings(iterations=20, seed=4)
        ck = tmp_path / "ck"
        kind.run(s, checkpointing=checkpointing_for("toy", s, ck, 10))
        assert json.loads((ck / "run.json").read_text())["settings"] == {"iterations": 20,
                                                                         "seed": 4}
        for step in _steps(ck):
            _damage(ck / str(step), "flip")
        history = _fingerprint(ck / "history")
        want = (f"every checkpoint in {ck} was corrupt (moved to {ck / 'corrupt'}); start again "
                f"with: eaco toy --iterations 20 --seed 4 --checkpoint-dir {ck} "
                "--checkpoint-every 10")
        with pytest.warns(UserWarning, match="corrupt"):
            first = CliRunner().invoke(app, ["resume", str(ck)])
        again = CliRunner().invoke(app, ["resume", str(ck)])
        for out in (first, again):
            assert out.exit_code == 2
            assert out.output.strip().splitlines()[-1] == f"error: {want}"
        assert len(list((ck / "corrupt").iterdir())) == 2
        assert _fingerprint(ck / "history") == history
    finally:
        registry._KINDS.pop("toy", None)


@pytest.mark.parametrize("name, values", [
    ("tsp", {"instance": "burma14", "ants": 8, "local_search": "none", "max_seconds": 2.5,
             "out": "o u t"}),
    ("gait", {"video": False, "iterations": 3}),
])
def test_command_line_parses_back_to_the_settings(tmp_path, name, values):
    """The command printed to start a run again is what the `eaco <kind>` command parses
    into the same settings (flags generated from the settings, booleans as --x/--no-x)."""
    import shlex

    import typer

    from eaco_jax.cli import app
    from eaco_jax.runs import get
    from eaco_jax.runs.base import command_line

    kind = get(name)
    s = kind.make_settings(values)
    words = shlex.split(command_line(name, s, tmp_path / "ck", 5))
    assert words[:2] == ["eaco", name] and ("--no-video" in words) == (name == "gait")
    ctx = typer.main.get_command(app).commands[name].make_context(name, words[2:])
    params = dict(ctx.params)
    assert params.pop("checkpoint_dir") == tmp_path / "ck"
    assert params.pop("checkpoint_every") == 5
    assert not params.pop("json_out") and not params.pop("quiet")
    assert kind.make_settings(params) == s


def _no_space_for_history_from(monkeypatch, start: int) -> None:
    """The disk refuses (ENOSPC) the fsync of every history segment from ``start`` on: an
    OSError injected at the lowest level of the write, the file's fsync."""
    import errno
    import os

    real = os.fsync

    def fsync(fd):
        name = os.readlink(f"/proc/self/fd/{fd}")
        if "/history/.tmp-" in name and int(name.rsplit("-", 2)[-2]) >= start:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def test_disk_full_during_a_save_is_one_line_and_resumes_bit_identically(tmp_path, monkeypatch):
    unbroken = _run(tmp_path / "ref", iterations=30, checkpoint_every=10)
    ck = tmp_path / "ck"
    with monkeypatch.context() as m:
        _no_space_for_history_from(m, 20)
        with pytest.raises(CheckpointError) as err:
            _run(ck, iterations=30, checkpoint_every=10)
    assert str(err.value) == (
        f"could not write checkpoint step 30 in {ck} (No space left on device); the last good "
        "step is 20: free space, then call minimize() again with the same Checkpointing")
    assert _steps(ck) == [10, 20] and not list((ck / "history").glob(".tmp-*"))
    _same(unbroken, _run(ck, iterations=30, checkpoint_every=10))


def test_a_real_full_disk_during_a_save_is_one_line(tmp_path):
    """A size-limited tmpfs fills during a save (orbax reports it inside a ValueError): one
    line; after space is freed the run resumes and equals an unbroken one. Needs mount."""
    import subprocess

    mnt = tmp_path / "small"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=280k", "tmpfs", str(mnt)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    try:
        ck = mnt / "ck"
        kw = dict(iterations=200, checkpoint_every=10, keep=100)
        with pytest.raises(CheckpointError) as err:
            _run(ck, **kw)
        text = str(err.value)
        step = int(text.split("could not write checkpoint step ")[1].split()[0])
        assert text == (
            f"could not write checkpoint step {step} in {ck} (No space left on device); the "
            f"last good step is {step - 10}: free space, then call minimize() again with the "
            "same Checkpointing")
        assert step >= 20 and _steps(ck)[-1] == step - 10
        assert not list(ck.glob(f"{step}.orbax-checkpoint-tmp*"))
        subprocess.run(["mount", "-o", "remount,size=32m", str(mnt)], check=True)
        _same(_run(tmp_path / "ref", **kw), _run(ck, **kw))
    finally:
        subprocess.run(["umount", str(mnt)], check=False)


def _jsonable_before_outputs_rule(value):
    """The checkpoint's own sanitiser before it shared ``outputs.to_jsonable`` (verbatim): it
    kept non-finite floats, which json wrote as NaN/Infinity."""
    if isinstance(value, dict):
        return {str(k): _jsonable_before_outputs_rule(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable_before_outputs_rule(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


@dataclasses.dataclass(frozen=True)
class CeilingSearch(RandomSearch):
    """RandomSearch with a float field whose default is not finite (a strategy of one's own)."""
    ceiling: float = math.inf


def test_a_checkpoint_written_by_the_old_sanitiser_resumes(tmp_path, monkeypatch):
    """Run identities are compared through today's JSON rule on both sides: a checkpoint whose
    identity holds ``Infinity`` (the old rule) resumes bit-identically; another value of the
    same field is still another run."""
    from eaco_jax.driver import checkpoint

    kw = dict(seed=1, iterations=30, chunk_size=5, checkpoint_every=10)
    unbroken = ea.minimize(_problem(), CeilingSearch(), seed=1, iterations=30, chunk_size=5)
    folder = tmp_path / "old"
    with monkeypatch.context() as m:
        m.setattr(checkpoint, "to_jsonable", _jsonable_before_outputs_rule)
        mini(_problem(), CeilingSearch(), checkpoint_dir=folder, **kw)
    assert read_meta(folder)["config"]["fields"]["ceiling"] == math.inf  # as stored before
    shutil.rmtree(folder / "30")
    shutil.rmtree(folder / "20")
    _same(unbroken, mini(_problem(), CeilingSearch(), checkpoint_dir=folder, **kw))
    assert read_meta(folder)["config"]["fields"]["ceiling"] is None  # saved by today's rule
    before = _fingerprint(folder)
    with pytest.raises(CheckpointError, match="different run.*fields"):
        mini(_problem(), CeilingSearch(ceiling=2.0), checkpoint_dir=folder, **kw)
    assert _fingerprint(folder) == before


@dataclasses.dataclass(frozen=True)
class LaterFieldSearch(RandomSearch):
    """RandomSearch with a field added in a later version (its default: the old behaviour)."""
    later: int | None = None


def test_a_checkpoint_written_before_a_strategy_field_existed_resumes(tmp_path, monkeypatch):
    """A checkpoint whose stored strategy fields lack one added since resumes bit-identically
    while that field is at its default; set to another value it is another run."""
    from eaco_jax.driver import checkpoint

    real = checkpoint.run_identity

    def older(*args, **kw):  # the identity as a version without ``later`` stored it
        ident = real(*args, **kw)
        del ident["config"]["fields"]["later"]
        del ident[checkpoint.FIELD_DEFAULTS]
        return ident

    kw = dict(seed=1, iterations=30, chunk_size=5, checkpoint_every=10)
    unbroken = ea.minimize(_problem(), LaterFieldSearch(), seed=1, iterations=30, chunk_size=5)
    folder = tmp_path / "old"
    with monkeypatch.context() as m:
        m.setattr(checkpoint, "run_identity", older)
        mini(_problem(), LaterFieldSearch(), checkpoint_dir=folder, **kw)
    assert "later" not in read_meta(folder)["config"]["fields"]
    shutil.rmtree(folder / "30")
    shutil.rmtree(folder / "20")
    before = _fingerprint(folder)
    with pytest.raises(CheckpointError, match="different run.*fields"):
        mini(_problem(), LaterFieldSearch(later=3), checkpoint_dir=folder, **kw)
    assert _fingerprint(folder) == before
    _same(unbroken, mini(_problem(), LaterFieldSearch(), checkpoint_dir=folder, **kw))


def test_one_json_rule():
    from eaco_jax.outputs import to_jsonable

    value = {1: np.float32(np.nan), "p": Path("a/b"), "t": (1, np.int64(2), -math.inf),
             "a": jnp.array([1.5, jnp.inf]), "s": RandomSearch(num_ants=3), "ok": [True, None]}
    want = {"1": None, "p": "a/b", "t": [1, 2, None], "a": [1.5, None],
            "s": repr(RandomSearch(num_ants=3)), "ok": [True, None]}
    assert to_jsonable(value) == want
    assert to_jsonable(want) == want


def test_a_step_of_another_state_layout_is_refused_in_one_line_and_kept(tmp_path):
    """A step written by a version whose colony state had other fields (its stored tree names
    them) is not called corrupt or moved: one line names the fields and the way out."""
    import json

    from eaco_jax.driver.checkpoint import OtherLayout

    kw = dict(seed=1, iterations=30, chunk_size=5, checkpoint_every=10)
    folder = tmp_path / "old"
    mini(_problem(), RandomSearch(), checkpoint_dir=folder, **kw)
    shutil.rmtree(folder / "30")
    for step in (10, 20):  # as a version without the ``stagnation`` field stored them
        path = folder / str(step) / "state" / "_METADATA"
        meta = json.loads(path.read_text())
        meta["tree_metadata"] = {k: v for k, v in meta["tree_metadata"].items()
                                 if not k.startswith("('stagnation'")}
        path.write_text(json.dumps(meta))
    before = _fingerprint(folder)
    with pytest.raises(OtherLayout, match=r"another layout \(fields this eaco_jax needs and it "
                       r"lacks: stagnation;.*resume it with that version or use a new "
                       r"--checkpoint-dir") as err:
        mini(_problem(), RandomSearch(), checkpoint_dir=folder, **kw)
    assert "\n" not in str(err.value)
    assert _fingerprint(folder) == before and not (folder / "corrupt").exists()

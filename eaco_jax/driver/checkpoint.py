"""Checkpoints of a whole run, written atomically with orbax, for exact resume.

A checkpoint holds everything a run needs to continue as if it had never stopped:

* ``state``: the colony pytree (PRNG key included, stored as raw key data and re-wrapped with
  the template's key implementation on restore), hence the iteration counter;
* ``history``: the per-iteration statistics recorded so far;
* ``meta`` (JSON): the run's identity - checkpoint format, package version, problem name and a
  content hash of its array leaves, strategy class and static fields, hyper-parameter hash,
  seeds, iteration budget and chunk length - plus ``done`` (iterations completed), ``finished``
  and the caller's ``run_info`` (for ``eaco resume``: the command name and its arguments).

Checkpoints are written between compiled chunks only (see :func:`eaco_jax.minimize.run_chunks`),
with the step number = iterations done. A resumed run therefore executes exactly the same
compiled chunks on exactly the same state as an unbroken one, and its results are bit-identical.

Atomicity: orbax writes each step into ``<step>.orbax-checkpoint-tmp-*`` and renames it when it
is complete, so a process killed mid-write leaves at most a temporary folder that is never
listed as a step; restore always reads the newest *complete* step. Mismatched runs, corrupt
files and incompatible versions raise :class:`CheckpointError` (one line) before anything in
the folder is written or deleted.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

from eaco_jax._version import __version__
from eaco_jax.driver.history import merge_history
from eaco_jax.errors import CheckpointError, ConfigError

#: bumped whenever the on-disk layout changes; other formats are refused on restore.
#: 2: problem data and telemetry left the colony state (eaco_jax 0.2).
FORMAT = 2




# --------------------------------------------------------------------------- identity
def _is_key(x: Any) -> bool:
    return hasattr(x, "dtype") and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)


def _leaf_bytes(x: Any) -> tuple[str, bytes]:
    if _is_key(x):
        x = jax.random.key_data(x)
    a = np.asarray(jax.device_get(x))
    return f"{a.dtype}{a.shape}", np.ascontiguousarray(a).tobytes()


def tree_hash(tree: Any) -> str:
    """sha256 over every leaf's path, dtype, shape and bytes.

    Only leaf paths enter, not the treedef: a problem's static fields may hold functions
    whose repr changes from process to process.
    """
    h = hashlib.sha256()
    for path, leaf in jax.tree_util.tree_leaves_with_path(tree):
        head, data = _leaf_bytes(leaf)
        h.update(f"{jax.tree_util.keystr(path)}:{head};".encode())
        h.update(data)
    return h.hexdigest()[:16]


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


def run_identity(
    problem: Any,
    strategy: Any,
    initial_params: Any,
    seeds: list[int],
    total: int,
    chunk: int,
) -> dict[str, Any]:
    """What must match between a checkpoint and the run that wants to resume from it."""
    fields = {f.name: getattr(strategy, f.name) for f in dataclasses.fields(strategy)}
    return {
        "format": FORMAT,
        "version": __version__,
        "problem": {
            "name": str(getattr(problem, "name", type(problem).__name__)),
            "kind": str(getattr(problem, "kind", "")),
            "hash": tree_hash(problem),
        },
        "config": {
            "strategy": f"{type(strategy).__module__}.{type(strategy).__qualname__}",
            "fields": _jsonable(fields),
            "params_hash": tree_hash(initial_params),
            "seeds": [int(s) for s in seeds],
            "total": int(total),
            "chunk": int(chunk),
        },
    }


def _compatible_version(stored: str, current: str) -> bool:
    """Same major.minor (patch releases never change the state layout)."""
    return stored.split(".")[:2] == current.split(".")[:2]


def check_identity(stored: dict[str, Any], current: dict[str, Any], where: Path) -> None:
    """Raise :class:`CheckpointError` naming the first thing that differs."""
    if stored.get("format") != current["format"]:
        raise CheckpointError(
            f"checkpoint in {where} has format {stored.get('format')!r}, this eaco_jax reads "
            f"format {current['format']} (the colony state's layout changed); resume it with "
            "the version that wrote it or use a new --checkpoint-dir"
        )
    if not _compatible_version(str(stored.get("version", "")), current["version"]):
        raise CheckpointError(
            f"checkpoint in {where} was written by eaco_jax {stored.get('version')}, incompatible "
            f"with {current['version']}; use that version or a new --checkpoint-dir"
        )
    for section in ("problem", "config"):
        old, new = stored.get(section, {}), current[section]
        for name in new:
            if old.get(name) != new[name]:
                raise CheckpointError(
                    f"checkpoint in {where} belongs to a different run ({section} {name}: "
                    f"stored {_short(old.get(name))}, now {_short(new[name])}); use another "
                    "--checkpoint-dir or the original settings"
                )


def _short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, default=str)
    return text if len(text) <= 80 else text[:77] + "..."


# --------------------------------------------------------------------------- state <-> disk
def _to_disk(tree: Any) -> Any:
    """Typed PRNG keys -> raw uint32 key data (what orbax stores)."""
    return jax.tree.map(lambda x: jax.random.key_data(x) if _is_key(x) else x, tree)


def _from_disk(restored: Any, template: Any, where: Path) -> Any:
    """Re-wrap key data and check every leaf against the template's shape and dtype."""

    def fix(t: Any, r: Any) -> Any:
        if _is_key(t):
            r = jax.random.wrap_key_data(np.asarray(r), impl=jax.random.key_impl(t))
        if tuple(r.shape) != tuple(t.shape) or r.dtype != t.dtype:
            raise CheckpointError(
                f"checkpoint in {where} holds a {r.dtype}{tuple(r.shape)} leaf where this run "
                f"has {t.dtype}{tuple(t.shape)}; use another --checkpoint-dir"
            )
        return jax.device_put(r)

    return jax.tree.map(fix, template, restored)


def strong_types(tree: Any) -> Any:
    """Copy of ``tree`` with plain (non-weak) dtypes, as a restored state has.

    Applied to a fresh state too, so fresh and resumed runs compile the same program.
    """
    return jax.tree.map(lambda x: x if _is_key(x) else jax.device_put(np.asarray(x)), tree)


@dataclasses.dataclass
class Restored:
    """A checkpoint read back: state, iterations done, history so far, stored metadata."""

    state: Any
    done: int
    history: dict[str, np.ndarray]
    finished: bool
    meta: dict[str, Any]


def _manager(directory: Path, keep: int | None, read_only: bool = False):
    import logging

    import orbax.checkpoint as ocp

    if read_only:  # orbax logs two warnings per read-only manager; they are expected here
        logging.getLogger("absl").setLevel(logging.ERROR)
    options = ocp.CheckpointManagerOptions(
        max_to_keep=keep,
        enable_async_checkpointing=False,
        create=not read_only,
        read_only=read_only,
        cleanup_tmp_directories=False,
    )
    return ocp.CheckpointManager(directory, options=options)


def latest_step(directory: str | Path) -> int | None:
    """Newest complete step in ``directory`` (None when it holds no checkpoint)."""
    directory = Path(directory)
    if not directory.is_dir():
        return None
    return _manager(directory, None, read_only=True).latest_step()


def read_meta(directory: str | Path) -> dict[str, Any]:
    """The JSON metadata of the newest complete checkpoint (for ``eaco resume``)."""
    import orbax.checkpoint as ocp

    directory = Path(directory)
    step = latest_step(directory)
    if step is None:
        raise CheckpointError(f"no checkpoint in {directory}")
    try:
        out = _manager(directory, None, read_only=True).restore(
            step, args=ocp.args.Composite(meta=ocp.args.JsonRestore())
        )
        meta = dict(out["meta"])
    except Exception as err:  # orbax raises many types for unreadable files
        raise CheckpointError(
            f"checkpoint {directory / str(step)} is corrupt ({type(err).__name__}); "
            "delete that step folder to fall back to an older one"
        ) from None
    if not isinstance(meta, dict) or "config" not in meta:
        raise CheckpointError(f"checkpoint {directory / str(step)} has no run metadata")
    return meta


# --------------------------------------------------------------------------- the checkpointer
class RunCheckpointer:
    """Saves a run every ``every`` iterations and/or ``seconds`` seconds, keeping the last ``keep``.

    Used by :func:`eaco_jax.minimize.minimize`: :meth:`restore` once before the run,
    :meth:`after_chunk` at every chunk boundary.
    """

    def __init__(
        self,
        directory: str | Path,
        identity: dict[str, Any],
        *,
        every: int | None = None,
        seconds: float | None = None,
        keep: int = 3,
        run_info: dict[str, Any] | None = None,
        batched: bool = False,
    ) -> None:
        if every is not None and every < 1:
            raise ConfigError(f"checkpoint_every must be >= 1, got {every}")
        if seconds is not None and seconds <= 0:
            raise ConfigError(f"checkpoint_seconds must be > 0, got {seconds}")
        if keep < 1:
            raise ConfigError(f"keep must be >= 1, got {keep}")
        self.directory = Path(directory).absolute()
        self.identity = identity
        self.every = every
        self.seconds = seconds
        self.keep = keep
        self.run_info = _jsonable(run_info or {})
        self.axis = 1 if batched else 0
        self._last_done = 0
        self._last_time = time.monotonic()
        self._mgr = None

    def _writer(self):
        if self._mgr is None:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._mgr = _manager(self.directory, self.keep)
        return self._mgr

    def restore(self, template: Any) -> Restored | None:
        """The newest complete checkpoint of this same run, or None if the folder has none."""
        import orbax.checkpoint as ocp

        step = latest_step(self.directory)
        if step is None:
            return None
        meta = read_meta(self.directory)
        check_identity(meta, self.identity, self.directory)
        where = self.directory / str(step)
        try:
            out = _manager(self.directory, None, read_only=True).restore(
                step,
                args=ocp.args.Composite(
                    state=ocp.args.StandardRestore(_to_disk(template)),
                    history=ocp.args.StandardRestore(),
                ),
            )
        except Exception as err:  # truncated / garbled array files
            raise CheckpointError(
                f"checkpoint {where} is corrupt ({type(err).__name__}); delete that step folder "
                "to fall back to an older one"
            ) from None
        state = _from_disk(out["state"], template, where)
        history = {k: np.asarray(v) for k, v in dict(out["history"] or {}).items()}
        done = int(meta["done"])
        lengths = {v.shape[self.axis] for v in history.values()} if history else {0}
        if lengths != {done}:
            raise CheckpointError(f"checkpoint {where} is corrupt (history length != {done})")
        self._last_done = done
        self._last_time = time.monotonic()
        return Restored(state, done, history, bool(meta.get("finished", False)), meta)

    def due(self, done: int) -> bool:
        by_iters = self.every is not None and done - self._last_done >= self.every
        by_time = self.seconds is not None and time.monotonic() - self._last_time >= self.seconds
        return by_iters or by_time

    def after_chunk(
        self, state: Any, done: int, history: list[dict[str, Any]], finished: bool
    ) -> bool:
        """Save if a checkpoint is due (always at the end of the run). Returns whether it did."""
        if not (finished or self.due(done)):
            return False
        self.save(state, done, merge_history(history, self.axis), finished)
        return True

    def save(self, state: Any, done: int, history: dict[str, Any], finished: bool) -> None:
        import orbax.checkpoint as ocp

        meta = dict(self.identity)
        meta.update(
            done=int(done),
            finished=bool(finished),
            run_info=self.run_info,
            saved_at=time.time(),
            writer=f"eaco_jax {__version__}",
        )
        mgr = self._writer()
        if done in mgr.all_steps():  # e.g. the final save of a run resumed at its last step
            return
        mgr.save(
            done,
            args=ocp.args.Composite(
                state=ocp.args.StandardSave(_to_disk(state)),
                history=ocp.args.StandardSave({k: np.asarray(v) for k, v in history.items()}),
                meta=ocp.args.JsonSave(meta),
            ),
            force=True,
        )
        mgr.wait_until_finished()
        self._last_done = done
        self._last_time = time.monotonic()

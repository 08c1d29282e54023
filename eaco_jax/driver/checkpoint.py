"""Checkpoints of a whole run, written atomically with orbax, for exact resume.

A checkpoint holds everything a run needs to continue as if it had never stopped:

* ``state``: the colony pytree (PRNG key included, stored as raw key data and re-wrapped with
  the template's key implementation on restore), hence the iteration counter;
* the per-iteration statistics: not in the step but in the folder's append-only
  :class:`~eaco_jax.driver.history.HistoryLog` (``history/``), one segment per save; the step
  stores the digest chain over the segments of its prefix (so a save costs the same at
  iteration 100 and 1,000,000, and the folder holds one copy of the history, not ``keep``);
* ``meta`` (JSON): the run's identity - checkpoint format, package version, problem name and a
  content hash of its array leaves, strategy class and static fields, hyper-parameter hash,
  seeds, iteration and evaluation budgets - plus ``done`` (iterations completed), ``finished``,
  the ``chunk`` length the run was compiled with (reused on resume, so how often a run saves is
  not part of its identity), a ``digest`` (sha256) of the saved state and history chain, and the
  caller's ``run_info`` (for ``eaco resume``: the command name and its arguments).

Checkpoints are written between compiled chunks only (see :func:`eaco_jax.driver.minimize.run`),
with the step number = iterations done; the driver cuts chunks short so saves land on
multiples of ``every``. A resumed run executes the same compiled chunk program on the same
state as an unbroken one, and its results are bit-identical.

Atomicity and integrity: orbax writes each step into ``<step>.orbax-checkpoint-tmp-*`` and
renames it when it is complete, so a process killed mid-write leaves at most a temporary folder
that is never listed as a step. Restore takes the newest step whose files read back and match
their digest; a step that does not is moved aside into ``<dir>/corrupt/`` (never deleted) with
a warning, and the next older one is tried (a corrupt history segment is moved aside with the
steps that need it). History segments past the restored step (iterations the resumed run
will compute again) are removed; segments no step refers to (an earlier run's, left in the
folder: a fresh run, or a step that does not chain through them) are moved into
``<dir>/old/``. A lock file (``<dir>/.lock``, ``flock``) keeps a second process from writing
the same folder. ``<dir>/run.json`` holds the caller's ``run_info`` as plain JSON (written at
the first save), so ``eaco resume`` can name the command that starts the run again even when
every step is corrupt. Mismatched runs and incompatible versions raise
:class:`CheckpointError` (one line) before anything in the folder is written or moved.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import re
import shutil
import sys
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jax
import numpy as np

from eaco_jax._version import __version__
from eaco_jax.driver.history import HistoryCorrupt, HistoryLog, chain, merge_history
from eaco_jax.errors import CheckpointError, ConfigError
from eaco_jax.outputs import to_jsonable

#: bumped whenever the on-disk layout changes; other formats are refused on restore.
#: 2: problem data and telemetry left the colony state (eaco_jax 0.2).
#: 3: the history moved out of the steps into an append-only log (eaco_jax 0.2).
FORMAT = 3




# --------------------------------------------------------------------------- identity
def _is_key(x: Any) -> bool:
    return hasattr(x, "dtype") and jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)


def _leaf_bytes(x: Any) -> tuple[str, bytes]:
    if _is_key(x):
        x = jax.random.key_data(x)
    a = np.asarray(jax.device_get(x))
    return f"{a.dtype}{a.shape}", np.ascontiguousarray(a).tobytes()


def tree_hash(tree: Any, by_index: bool = False) -> str:
    """sha256 over every leaf's path, dtype, shape and bytes.

    Only leaf paths enter, not the treedef: a problem's static fields may hold functions
    whose repr changes from process to process. ``by_index``: each path as the flat index a
    pytree node without field names gives (``[<flat index i>]``), the hash such a node had.
    """
    h = hashlib.sha256()
    for i, (path, leaf) in enumerate(jax.tree_util.tree_leaves_with_path(tree)):
        head, data = _leaf_bytes(leaf)
        if by_index:
            path = (jax.tree_util.FlattenedIndexKey(i),)
        h.update(f"{jax.tree_util.keystr(path)}:{head};".encode())
        h.update(data)
    return h.hexdigest()[:16]


#: identity entry (not compared itself): the problem's hash by leaf index, which a checkpoint
#: written while its problem class flattened without field names (ConstrainedProblem before it
#: was a dataclass) stored as the problem's hash
HASH_BY_INDEX = "problem_hash_by_index"
#: the strategy's dataclass defaults, stored beside the identity: a checkpoint written before
#: the strategy had a field resumes where that field is at its default (new fields default to
#: the behaviour before them)
FIELD_DEFAULTS = "strategy_field_defaults"


def run_identity(
    problem: Any,
    strategy: Any,
    initial_params: Any,
    seeds: list[int],
    total: int,
    chunk: int | None = None,
    max_evaluations: int | None = None,
) -> dict[str, Any]:
    """What must match between a checkpoint and the run that wants to resume from it.

    The chunk length is not part of it (it is stored beside it and reused on resume).
    """
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
            "fields": to_jsonable(fields),
            "params_hash": tree_hash(initial_params),
            "seeds": [int(s) for s in seeds],
            "total": int(total),
            "max_evaluations": None if max_evaluations is None else int(max_evaluations),
        },
        HASH_BY_INDEX: tree_hash(problem, by_index=True),
        FIELD_DEFAULTS: to_jsonable({f.name: f.default for f in dataclasses.fields(strategy)
                                     if f.default is not dataclasses.MISSING}),
    }


def _added_at_default(old: Any, new: Any, defaults: Any) -> bool:
    """Strategy fields stored by a version that lacked some: every stored field equal, every
    field added since at its default."""
    if not (isinstance(old, dict) and isinstance(new, dict) and isinstance(defaults, dict)):
        return False
    added = set(new) - set(old)
    return (set(old) <= set(new) and all(old[k] == new[k] for k in old)
            and all(k in defaults and new[k] == defaults[k] for k in added))


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
        # the stored section through today's rule: one written by an older rule (a non-finite
        # float kept as NaN/Infinity) compares equal where the configuration is the same
        old, new = to_jsonable(stored.get(section, {})), current[section]
        for name in new:
            if name == "max_evaluations" and name not in old and new[name] is None:
                continue  # written before the evaluation budget was stored
            if (section, name) == ("problem", "hash") and old.get(name) is not None \
                    and old.get(name) == current.get(HASH_BY_INDEX):
                continue  # the same leaves, hashed before the problem's fields had names
            if (section, name) == ("config", "fields") and _added_at_default(
                    old.get(name), new[name], current.get(FIELD_DEFAULTS)):
                continue  # written before the strategy had some fields, now at defaults
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


class OtherLayout(CheckpointError):
    """A step that reads back but holds the colony state of another layout (other fields):
    written by a version of eaco_jax whose state had other fields. Not corrupt: left where
    it is."""


def _fields(tree: Any) -> set[str]:
    """The top-level field names of a state as orbax stores it."""
    out = set()
    for path, _ in jax.tree_util.tree_flatten_with_path(_to_disk(tree))[0]:
        k = path[0]
        out.add(str(getattr(k, "name", getattr(k, "key", getattr(k, "idx", k)))))
    return out


def _check_layout(where: Path, template: Any, step: int) -> None:
    """Raise :class:`OtherLayout` when the step's stored fields (its ``_METADATA``, read as
    JSON) differ from ``template``'s; a step without readable metadata is left to the
    restore (which calls it corrupt if it does not read back)."""
    try:
        stored = json.loads((where / "state" / "_METADATA").read_text())["tree_metadata"]
        saved = {m.group(1) for k in stored if (m := re.match(r"^\('([^']*)'", k))}
    except (OSError, ValueError, KeyError, TypeError):
        return
    now = _fields(template)
    if saved and saved != now:
        missing, extra = sorted(now - saved), sorted(saved - now)
        raise OtherLayout(
            f"checkpoint step {step} in {where.parent} holds a colony state of another layout "
            f"(fields this eaco_jax needs and it lacks: {', '.join(missing) or 'none'}; "
            f"fields it has and this one does not: {', '.join(extra) or 'none'}): written by "
            "another eaco_jax version; resume it with that version or use a new "
            "--checkpoint-dir")


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
        # uncommitted, as strong_types leaves a fresh state: the same compiled chunk serves
        # both, and a strategy's sharding constraints (Islands) place it inside the program
        return r if _is_key(t) else jax.device_put(np.asarray(r))

    return jax.tree.map(fix, template, restored)


def strong_types(tree: Any) -> Any:
    """Copy of ``tree`` with plain (non-weak) dtypes, as a restored state has.

    Applied to a fresh state too, so fresh and resumed runs compile the same program.
    """
    return jax.tree.map(lambda x: x if _is_key(x) else jax.device_put(np.asarray(x)), tree)


@dataclasses.dataclass
class Restored:
    """A checkpoint read back: state, iterations done, stored metadata (the history stays
    in the log: :meth:`RunCheckpointer.history`)."""

    state: Any
    done: int
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
    steps = all_steps(directory)
    return steps[0] if steps else None


def all_steps(directory: str | Path) -> list[int]:
    """Complete steps in ``directory``, newest first."""
    directory = Path(directory)
    if not directory.is_dir():
        return []
    with _quiet_logs():  # orbax logs an ERROR for a step whose own metadata is garbled
        return sorted(_manager(directory, None, read_only=True).all_steps(), reverse=True)


@contextlib.contextmanager
def _quiet_logs() -> Iterator[None]:
    """Silence orbax's (absl) and asyncio's error logs while a possibly corrupt step is read:
    a corrupt step is reported as one warning line, not dozens of logged tracebacks."""
    import logging

    loggers = [logging.getLogger(name) for name in ("absl", "asyncio", "orbax")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    # tensorstore's callbacks print "Event loop is closed" tracebacks straight to fd 2 after a
    # failed read; they are noise here (the failure itself becomes one warning line)
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    failed = False
    try:
        yield
    except BaseException:
        failed = True
        raise
    finally:
        if failed:
            import gc

            time.sleep(0.3)  # let the failed read's callbacks finish while fd 2 is quiet
            gc.collect()  # and its abandoned coroutines be collected (they print when they are)
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


class _Corrupt(Exception):
    """A step whose files do not read back, or do not match their digest (``path``: a
    corrupt history segment to move aside with it)."""

    def __init__(self, message: str, path: Path | None = None) -> None:
        super().__init__(message)
        self.path = path


def _read_step_meta(directory: Path, step: int) -> dict[str, Any]:
    import orbax.checkpoint as ocp

    try:
        with _quiet_logs():
            out = _manager(directory, None, read_only=True).restore(
                step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))
        meta = dict(out["meta"])
    except Exception as err:  # noqa: BLE001 - orbax raises many types for unreadable files
        raise _Corrupt(f"its metadata does not read back ({type(err).__name__})") from None
    if "config" not in meta or "done" not in meta:
        raise _Corrupt("it has no run metadata")
    stored = meta.pop("meta_digest", None)
    if stored is not None and stored != _meta_digest(meta):
        raise _Corrupt("its metadata does not match the digest saved with it")
    return meta


def _meta_digest(meta: dict[str, Any]) -> str:
    text = json.dumps(meta, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def read_meta(directory: str | Path) -> dict[str, Any]:
    """The JSON metadata of the newest checkpoint whose metadata reads back (for ``eaco
    resume``); corrupt steps are left for :meth:`RunCheckpointer.restore` to move aside."""
    directory = Path(directory)
    steps = all_steps(directory)
    if not steps:
        raise CheckpointError(f"no checkpoint in {directory}")
    reasons = []
    for step in steps:
        try:
            return _read_step_meta(directory, step)
        except _Corrupt as err:
            reasons.append(f"step {step}: {err}")
    raise CheckpointError(
        f"every checkpoint in {directory} is corrupt ({'; '.join(reasons[:3])}); start again "
        "with a new --checkpoint-dir")


def state_digest(state_on_disk: Any, history_chain: str) -> str:
    """sha256 over the saved state (key data as stored) and the history's digest chain: saved
    in the metadata, compared on restore, so a changed byte is caught."""
    return tree_hash({"state": state_on_disk,
                      "history_chain": np.frombuffer(history_chain.encode(), np.uint8)})


class _Lock:
    """An exclusive ``flock`` on ``<dir>/.lock`` for as long as a run writes the folder."""

    def __init__(self, directory: Path) -> None:
        self.path = directory / ".lock"
        self.fd: int | None = None

    def acquire(self) -> None:
        import fcntl

        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise CheckpointError(
                f"checkpoint folder {self.path.parent} is not writable ({err.strerror}); use "
                "another --checkpoint-dir") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            try:
                holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "?"
            finally:
                os.close(fd)
            raise CheckpointError(
                f"checkpoint folder {self.path.parent} is in use by another run ({holder}); "
                "wait for it to finish or use another --checkpoint-dir") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} since {time.strftime('%H:%M:%S')}".encode(), 0)
        self.fd = fd

    def release(self) -> None:
        if self.fd is not None:
            import fcntl

            fcntl.flock(self.fd, fcntl.LOCK_UN)
            os.close(self.fd)
            self.fd = None


def check_writable(directory: Path, what: str) -> None:
    """Create ``directory`` if needed and prove it writable (one line if not)."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        probe = directory / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as err:
        raise CheckpointError(
            f"{what} {directory} is not writable ({err.strerror or type(err).__name__}); "
            "choose another folder") from None


# --------------------------------------------------------------------------- the checkpointer
class RunCheckpointer:
    """Saves a run every ``every`` iterations and/or ``seconds`` seconds, keeping the last ``keep``.

    Used by :func:`eaco_jax.driver.minimize.run`: :meth:`restore` once before the run (it takes
    the folder's lock), :meth:`after_chunk` at every chunk boundary, :meth:`close` at the end.
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
        chunk: int | None = None,
    ) -> None:
        if every is not None and (isinstance(every, bool) or int(every) != every or every < 1):
            raise ConfigError(f"checkpoint_every must be an integer >= 1, got {every!r}")
        if seconds is not None and not seconds > 0:
            raise ConfigError(f"checkpoint_seconds must be > 0, got {seconds}")
        if isinstance(keep, bool) or int(keep) != keep or keep < 1:
            raise ConfigError(f"keep must be an integer >= 1, got {keep!r}")
        self.directory = Path(directory).absolute()
        self.identity = identity
        self.every = every
        self.seconds = seconds
        self.keep = int(keep)
        self.run_info = to_jsonable(run_info or {})
        self.axis = 1 if batched else 0
        self.chunk = chunk
        self._last_done = 0
        self._last_time = time.monotonic()
        self._mgr = None
        self._lock = _Lock(self.directory)
        self.log = HistoryLog(self.directory / "history", self.axis)
        self._chain = ""  # digest chain of the logged history, [0, _last_done)
        self._run_info_written = False

    def _writer(self):
        if self._mgr is None:
            self._mgr = _manager(self.directory, self.keep)
        return self._mgr

    def open(self) -> None:
        """Check the folder writable and take its lock (a second run is refused)."""
        if self._lock.fd is None:
            if self.directory.exists() and not self.directory.is_dir():
                raise CheckpointError(f"checkpoint folder {self.directory} is a file")
            check_writable(self.directory, "checkpoint folder")
            self._lock.acquire()

    def close(self) -> None:
        """Release the folder's lock."""
        self._lock.release()

    def _move_aside(self, step: int, reason: str) -> None:
        where = self.directory / "corrupt"
        where.mkdir(exist_ok=True)
        target = where / f"{step}-{time.strftime('%Y%m%d-%H%M%S')}"
        shutil.move(str(self.directory / str(step)), str(target))
        warnings.warn(
            f"checkpoint step {step} in {self.directory} is corrupt ({reason}); moved to "
            f"{target} and falling back to the previous step", stacklevel=4)

    def _set_aside_history(self, paths: list[Path], why: str) -> None:
        """Move an earlier run's history segments out of the log (a fresh run or a resumed
        one would otherwise find two segments starting at one iteration)."""
        if not paths:
            return
        target = self.log.set_aside(paths, self.directory / "old")
        warnings.warn(
            f"{len(paths)} history segment(s) in {self.log.directory} belong to an earlier run "
            f"({why}); moved to {target}", stacklevel=4)

    def _read(self, step: int, template: Any) -> Restored:
        with _quiet_logs():
            return self._read_unquiet(step, template)

    def _read_unquiet(self, step: int, template: Any) -> Restored:
        import orbax.checkpoint as ocp

        meta = _read_step_meta(self.directory, step)
        where = self.directory / str(step)
        _check_layout(where, template, step)
        try:
            out = _manager(self.directory, None, read_only=True).restore(
                step, args=ocp.args.Composite(state=ocp.args.StandardRestore(_to_disk(template))))
        except Exception as err:  # noqa: BLE001 - truncated / garbled array files
            raise _Corrupt(f"its arrays do not read back ({type(err).__name__})") from None
        history_chain = str(meta.get("history_chain", ""))
        if state_digest(out["state"], history_chain) != meta.get("digest"):
            raise _Corrupt("its arrays do not match the digest saved with them")
        try:
            state = _from_disk(out["state"], template, where)
        except CheckpointError as err:
            raise _Corrupt(str(err)) from None
        done = int(meta["done"])
        try:
            self.log.read(done, history_chain, visit=lambda _arrays: None)  # verify only
        except HistoryCorrupt as err:
            raise _Corrupt(str(err), err.path) from None
        return Restored(state, done, bool(meta.get("finished", False)), meta)

    def restore(self, template: Any, on_segment: Any = None) -> Restored | None:
        """The newest intact checkpoint of this same run, or None if the folder has none.

        Takes the folder's lock first. A step that does not read back or fails its digest (or
        whose history segments do) is moved into ``corrupt/`` with a warning, and the next
        older step is tried. ``on_segment(arrays)`` sees each history segment of the restored
        prefix once, in order (the history itself is not kept in memory).
        """
        self.open()
        steps = all_steps(self.directory)
        if not steps:
            self._set_aside_history([p for _s, _e, p in self.log.segments()],
                                    "no checkpoint refers to them")
            self.log.truncate(0)
            return None
        check_identity(read_meta(self.directory), self.identity, self.directory)
        for step in steps:
            try:
                restored = self._read(step, template)
            except _Corrupt as err:
                if err.path is not None and err.path.exists():
                    self.log.move_aside(err.path, self.directory / "corrupt")
                self._move_aside(step, str(err))
                continue
            check_identity(restored.meta, self.identity, self.directory)
            stored_chunk = restored.meta.get("chunk", restored.meta["config"].get("chunk"))
            if stored_chunk:
                self.chunk = int(stored_chunk)
            self._last_done = restored.done
            self._last_time = time.monotonic()
            self._chain = str(restored.meta.get("history_chain", ""))
            used = {p for _s, _e, p in self.log.chained(restored.done, self._chain)}
            self._set_aside_history(
                [p for _s, e, p in self.log.segments() if e <= restored.done and p not in used],
                f"step {restored.done} does not chain through them")
            self.log.truncate(restored.done)
            if on_segment is not None:  # verified above: a second pass hands it over
                self.log.read(restored.done, self._chain, visit=on_segment)
            return restored
        command = self.run_info.get("command")
        again = f"start again with: {command}" if command else "run again to start from scratch"
        raise CheckpointError(
            f"every checkpoint in {self.directory} was corrupt (moved to "
            f"{self.directory / 'corrupt'}); {again}")

    def history(self) -> dict[str, np.ndarray]:
        """The logged history: the iterations up to the last save or restore."""
        if self._last_done == 0:
            return {}
        return self.log.read(self._last_done, self._chain) or {}

    def due(self, done: int) -> bool:
        by_iters = self.every is not None and done - self._last_done >= self.every
        by_iters = by_iters or (self.every is not None and done % self.every == 0
                                and done > self._last_done)
        by_time = self.seconds is not None and time.monotonic() - self._last_time >= self.seconds
        return by_iters or by_time

    def after_chunk(
        self, state: Any, done: int, pending: list[dict[str, Any]], finished: bool,
        force: bool = False,
    ) -> bool:
        """Save if a checkpoint is due (always at the end of the run, or with ``force``);
        ``pending`` is the history since the last save. Returns whether it saved (the caller
        then drops ``pending``: it is in the log)."""
        if not (finished or force or self.due(done)):
            return False
        if done == 0 or (force and done == self._last_done):
            return False  # nothing run since the start or the last save
        return self.save(state, done, merge_history(pending, self.axis), finished)

    def save(self, state: Any, done: int, pending: dict[str, Any], finished: bool) -> bool:
        """Append ``pending`` (iterations since the last save) to the history log, then write
        the step. Returns False if the step exists already (nothing written).

        A write the disk refuses (full, quota, read-only) is one :class:`CheckpointError` line
        naming the step and the last good one; the partial step is removed, the saved ones are
        untouched."""
        self.open()
        mgr = self._writer()
        if done in mgr.all_steps():  # e.g. the final save of a run resumed at its last step
            return False
        try:
            with _quiet_logs():  # a refused write is one line, not orbax's logged tracebacks
                self._write(mgr, state, done, pending, finished)
        except Exception as err:  # noqa: BLE001 - orbax reports a failed write as ValueError
            reason = _write_failure(err)
            if reason is None:
                raise
            for partial in self.directory.glob(f"{done}.orbax-checkpoint-tmp*"):
                shutil.rmtree(partial, ignore_errors=True)
            raise CheckpointError(self._cannot_write(done, reason)) from None
        return True

    def _write(self, mgr: Any, state: Any, done: int, pending: dict[str, Any],
               finished: bool) -> None:
        import orbax.checkpoint as ocp

        history_chain = self._chain
        if done > self._last_done:
            history_chain = chain(history_chain, self.log.append(self._last_done, done, pending))
        if not self._run_info_written and self.run_info:
            write_run_info(self.directory, self.run_info)
            self._run_info_written = True
        on_disk = _to_disk(state)
        meta = dict(self.identity)
        meta.update(
            done=int(done),
            finished=bool(finished),
            chunk=None if self.chunk is None else int(self.chunk),
            history_chain=history_chain,
            digest=state_digest(on_disk, history_chain),
            run_info=self.run_info,
            saved_at=time.time(),
            writer=f"eaco_jax {__version__}",
        )
        meta["meta_digest"] = _meta_digest(meta)
        mgr.save(
            done,
            args=ocp.args.Composite(
                state=ocp.args.StandardSave(on_disk),
                meta=ocp.args.JsonSave(meta),
            ),
            force=True,
        )
        mgr.wait_until_finished()
        self._chain = history_chain
        self._last_done = done
        self._last_time = time.monotonic()

    def _cannot_write(self, done: int, reason: str) -> str:
        """The one line for a step the disk refused: what to free and how to go on."""
        head = f"could not write checkpoint step {done} in {self.directory} ({reason})"
        command = self.run_info.get("command")
        if self._last_done == 0:
            again = f"start again with: {command}" if command else "start the run again"
            return f"{head}; no step was saved yet: free space, then {again}"
        how = (f"eaco resume {self.directory}" if self.run_info.get("kind")
               else "call minimize() again with the same Checkpointing")
        return f"{head}; the last good step is {self._last_done}: free space, then {how}"


_OS_ERROR_CODE = re.compile(r"os_error_code='?(\d+)")


def _write_failure(err: BaseException) -> str | None:
    """The operating system's reason a write failed (``No space left on device``), or None
    for anything else (a bug, which keeps its traceback). orbax/tensorstore report the OS
    error inside a ValueError's text (``[os_error_code='28']``)."""
    if isinstance(err, OSError):
        return err.strerror or type(err).__name__
    found = _OS_ERROR_CODE.search(str(err))
    return os.strerror(int(found[1])) if found else None


RUN_INFO = "run.json"


def write_run_info(directory: Path, run_info: dict[str, Any]) -> None:
    """``<dir>/run.json``: the run's ``run_info`` (kind, settings, command) as plain JSON,
    beside the steps, so ``eaco resume`` can name the command even when every step is
    corrupt. Written atomically (tmp file, fsync, rename)."""
    target = directory / RUN_INFO
    tmp = directory / f".tmp-{os.getpid()}-{RUN_INFO}"
    try:
        with open(tmp, "w") as f:
            json.dump(to_jsonable(run_info), f, sort_keys=True)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def read_run_info(directory: str | Path) -> dict[str, Any]:
    """The ``run_info`` saved in ``<dir>/run.json`` ({} if absent or unreadable: data only)."""
    try:
        info = json.loads((Path(directory) / RUN_INFO).read_text())
    except (OSError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}

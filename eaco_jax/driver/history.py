"""A run's history: per-iteration metrics, recorded chunk by chunk and merged once.

A checkpointed run does not keep its history in memory nor write it into every checkpoint:
each save appends the iterations since the previous save to :class:`HistoryLog`, one small
file per save (``<checkpoint dir>/history/<start>-<end>.npz``), so memory and the cost of a
save stay flat however long the run is, and the folder grows by the history's own size once
(not ``keep`` copies of it). Each segment carries a digest of its arrays; a checkpoint stores
the digest chain over the segments that make up its prefix, so a flipped byte, a missing or a
foreign segment is caught on restore.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np


def merge_history(history: list[dict[str, Any]], axis: int) -> dict[str, np.ndarray]:
    """Concatenate per-chunk history dicts along the iteration axis (1 with a row axis);
    empty dicts (nothing logged yet) are skipped."""
    history = [h for h in history if h]
    if not history:
        return {}
    return {
        k: np.concatenate([np.asarray(h[k]) for h in history], axis=axis) for k in history[0]
    }


def arrays_digest(arrays: dict[str, np.ndarray]) -> str:
    """sha256 over names, dtypes, shapes and bytes (file-format independent)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype}{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


def chain(previous: str, segment_digest: str) -> str:
    """The digest chain after appending a segment (``""`` before the first)."""
    return hashlib.sha256(f"{previous}|{segment_digest}".encode()).hexdigest()[:32]


_NAME = re.compile(r"^(\d{12})-(\d{12})\.npz$")
_DIGEST = "__digest__"


class HistoryCorrupt(Exception):
    """A segment that does not read back or does not match its digest (or the chain)."""

    def __init__(self, message: str, path: Path | None = None) -> None:
        super().__init__(message)
        self.path = path


class HistoryLog:
    """Append-only history segments in ``directory`` (iterations ``[start, end)`` each)."""

    def __init__(self, directory: str | Path, axis: int) -> None:
        self.directory = Path(directory)
        self.axis = axis

    def segments(self) -> list[tuple[int, int, Path]]:
        """``(start, end, path)`` of every segment file, in order of start."""
        if not self.directory.is_dir():
            return []
        out = []
        for p in self.directory.iterdir():
            m = _NAME.match(p.name)
            if m:
                out.append((int(m[1]), int(m[2]), p))
        return sorted(out)

    def append(self, start: int, end: int, rows: dict[str, np.ndarray]) -> str:
        """Write iterations ``[start, end)`` atomically (tmp file, fsync, rename; the tmp file
        is removed if the write fails); returns the segment's digest."""
        self.directory.mkdir(parents=True, exist_ok=True)
        rows = {k: np.asarray(v) for k, v in rows.items()}
        digest = arrays_digest(rows)
        target = self.directory / f"{start:012d}-{end:012d}.npz"
        tmp = self.directory / f".tmp-{os.getpid()}-{start}-{end}.npz"
        try:
            with open(tmp, "wb") as f:
                np.savez_compressed(f, **rows,
                                    **{_DIGEST: np.frombuffer(digest.encode(), np.uint8)})
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, target)
        finally:  # a failed write (a full disk) leaves no partial file behind
            tmp.unlink(missing_ok=True)
        return digest

    def _load(self, path: Path) -> tuple[dict[str, np.ndarray], str]:
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except Exception as err:  # noqa: BLE001 - zip, zlib, EOF and format errors alike
            raise HistoryCorrupt(f"history segment {path.name} does not read back "
                                 f"({type(err).__name__})", path) from None
        stored = arrays.pop(_DIGEST, None)
        digest = arrays_digest(arrays)
        if stored is None or bytes(stored).decode(errors="replace") != digest:
            raise HistoryCorrupt(f"history segment {path.name} does not match its digest", path)
        return arrays, digest

    def read(self, done: int, expected_chain: str,
             visit: Callable[[dict[str, np.ndarray]], None] | None = None,
             ) -> dict[str, np.ndarray] | None:
        """The history of iterations ``[0, done)``, checked against ``expected_chain``.

        With ``visit``, each segment is passed to it in order and nothing is kept (returns
        None): a resumed run does not hold the history it restored in memory. Where two
        segments start at one iteration (an older run's left in the folder), the ones whose
        digests chain to ``expected_chain`` are read. Raises :class:`HistoryCorrupt` naming
        the segment.
        """
        parts, digest_chain = [], ""
        for start, end, path in self.chained(done, expected_chain):
            arrays, digest = self._load(path)
            self._check_length(arrays, start, end, path)
            digest_chain = chain(digest_chain, digest)
            if visit is None:
                parts.append(arrays)
            else:
                visit(arrays)
        if digest_chain != expected_chain:
            raise HistoryCorrupt("the history segments do not match the checkpoint's digest chain")
        return merge_history(parts, self.axis) if visit is None else None

    def chained(self, done: int, expected_chain: str) -> list[tuple[int, int, Path]]:
        """The segments that make up ``[0, done)``, in order: the only ones there are, or,
        where several start at one iteration, the sequence whose digests chain to
        ``expected_chain`` (found by digests alone). Raises :class:`HistoryCorrupt`."""
        by_start: dict[int, list[tuple[int, Path]]] = {}
        for s, e, p in self.segments():
            if e <= done:
                by_start.setdefault(s, []).append((e, p))
        if all(len(c) == 1 for c in by_start.values()):
            out, pos = [], 0
            while pos < done:
                if pos not in by_start:
                    raise HistoryCorrupt(
                        f"history segment starting at iteration {pos} is missing")
                end, path = by_start[pos][0]
                out.append((pos, end, path))
                pos = end
            return out
        return self._search(done, expected_chain, by_start)

    def _search(self, done: int, expected_chain: str,
                by_start: dict[int, list[tuple[int, Path]]]) -> list[tuple[int, int, Path]]:
        """Depth-first over the candidate segments at each start; each file is read once."""
        digests: dict[Path, str | None] = {}
        first_error: list[HistoryCorrupt] = []

        def digest_of(start: int, end: int, path: Path) -> str | None:
            if path not in digests:
                try:
                    arrays, digest = self._load(path)
                    self._check_length(arrays, start, end, path)
                    digests[path] = digest
                except HistoryCorrupt as err:
                    first_error.append(err)
                    digests[path] = None
            return digests[path]

        stack: list[tuple[int, str, list[tuple[int, int, Path]]]] = [(0, "", [])]
        while stack:
            pos, digest_chain, path_so_far = stack.pop()
            if pos == done:
                if digest_chain == expected_chain:
                    return path_so_far
                continue
            for end, path in by_start.get(pos, []):
                digest = digest_of(pos, end, path)
                if digest is not None:
                    stack.append((end, chain(digest_chain, digest),
                                  [*path_so_far, (pos, end, path)]))
        if first_error:
            raise first_error[0]
        raise HistoryCorrupt("no sequence of history segments matches the checkpoint's digest "
                             "chain")

    def _check_length(self, arrays: dict[str, np.ndarray], start: int, end: int,
                      path: Path) -> None:
        lengths = {v.shape[self.axis] for v in arrays.values()} or {0}
        if lengths != {end - start}:
            raise HistoryCorrupt(f"history segment {path.name} holds {lengths} iterations", path)

    def move_aside(self, path: Path, where: Path) -> Path:
        """Move a corrupt segment into ``where`` (never deleted)."""
        where.mkdir(parents=True, exist_ok=True)
        target = where / f"history-{path.stem}-{time.strftime('%Y%m%d-%H%M%S')}.npz"
        shutil.move(str(path), str(target))
        return target

    def set_aside(self, paths: list[Path], where: Path) -> Path:
        """Move segments no checkpoint refers to (an earlier run's) into a new folder
        ``where/history-<time>`` with their names (never deleted); returns the folder."""
        stamp = time.strftime("%Y%m%d-%H%M%S")
        target, n = where / f"history-{stamp}", 1
        while target.exists():
            n += 1
            target = where / f"history-{stamp}-{n}"
        target.mkdir(parents=True)
        for path in paths:
            shutil.move(str(path), str(target / path.name))
        return target

    def truncate(self, done: int) -> None:
        """Remove the segments past iteration ``done`` (a resumed run writes them again) and
        any temporary file a killed save left."""
        for _start, end, path in self.segments():
            if end > done:
                path.unlink()
        if self.directory.is_dir():
            for p in self.directory.glob(".tmp-*"):
                p.unlink(missing_ok=True)

"""Compiled chunks (and initial states) kept on disk as exported programs, so a fresh process
skips tracing.

JAX's persistent compilation cache keeps the compiled executable, but every new process still
traces and lowers the chunk before it can look the executable up: on an H100, 1.3 s of tracing
and 0.8 s of lowering for a pcb442 colony with local search, against 0.7 s to load the cached
executable (``experiments/startup_phases.py``). Here the first process also writes the traced
chunk as a ``jax.export`` artifact; a later process with the same code, versions, device,
strategy and shapes deserialises it (milliseconds), lowers the small wrapper and gets the
executable from JAX's cache. The driver sends its two programs through :func:`compiled`: the
chunk of iterations and the initialiser of the state.

On whenever JAX's persistent cache is (``jax_compilation_cache_dir``, as ``eaco`` sets it), in
``<that folder>/eaco_programs``; :func:`set_folder` chooses another folder or turns it off.
A program that cannot be exported (host callbacks: the native local search on a CPU) is
marked once and traced as before. An entry is keyed by a digest of everything that shapes the
program, the package's source included, so a code change never loads a stale program; for
that reason only programs built of this package's own strategies and problems are kept (a
user's own class, or a function held in a problem, is traced in every process, as a sharded
program is). A damaged entry is traced and written again, with a warning.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
from jax import export

_SUFFIX, _MARK = ".jaxexport", ".traced"
_UNSET = object()
_folder: Any = _UNSET
#: custom calls whose serialised form JAX does not promise to keep stable across versions;
#: safe here because an entry is only read back by the same jax/jaxlib and device
_UNSTABLE_TARGETS = ("triton_kernel_call", "__gpu$xla.gpu.triton")


def set_folder(folder: str | Path | None) -> None:
    """Keep exported chunks in ``folder`` (None: off; default: follow JAX's persistent
    cache)."""
    global _folder
    _folder = None if folder is None else Path(folder)


def folder() -> Path | None:
    """Where exported chunks live now, or None when the cache is off."""
    if _folder is not _UNSET:
        return _folder if _folder is None or _can_serialize() else None
    if os.environ.get("EACO_PROGRAM_CACHE", "").lower() in ("0", "off", "no", "false"):
        return None
    base = jax.config.jax_compilation_cache_dir
    if not base or not _can_serialize():
        return None
    return Path(base) / "eaco_programs"


@functools.cache
def _can_serialize() -> bool:
    """jax.export writes flatbuffers (a declared dependency); without it: traced, once said."""
    try:
        import flatbuffers  # noqa: F401
    except ImportError:
        warnings.warn("eaco_jax program cache off: the 'flatbuffers' package is missing "
                      "(pip install flatbuffers)", stacklevel=4)
        return False
    return True


@functools.cache
def source_digest() -> str:
    """sha256 of the package's Python source: a program exported by other code is not used."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def program_key(parts: tuple) -> str | None:
    """The entry's digest for these program-shaping ``parts`` (None: not cacheable, e.g. a
    strategy whose repr holds a function's address, which differs in every process)."""
    import jaxlib

    text = repr((parts, jax.__version__, jaxlib.__version__, jax.default_backend(),
                 [d.device_kind for d in jax.local_devices()[:1]]))
    if " at 0x" in text:
        return None
    return hashlib.sha256((source_digest() + text).encode()).hexdigest()[:32]


def _our_type(t: type) -> bool:
    module = getattr(t, "__module__", "") or ""
    return module.split(".")[0] in ("eaco_jax", "builtins", "collections", "jax", "jaxlib",
                                    "flax", "numpy")


def _our_value(value: Any, depth: int = 0) -> bool:
    """A strategy field's value, recursively: built of the package's own code only."""
    if depth > 8:
        return False
    if isinstance(value, str | bytes | int | float | bool | complex | type(None)):
        return True
    if isinstance(value, tuple | list | frozenset | set):
        return all(_our_value(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(_our_value(v, depth + 1) for v in value.values())
    if callable(value) and not dataclasses.is_dataclass(value):
        return _our_type(value) if isinstance(value, type) else (
            (getattr(value, "__module__", "") or "").split(".")[0] == "eaco_jax")
    if not _our_type(type(value)):
        return False
    if dataclasses.is_dataclass(value):
        return all(_our_value(getattr(value, f.name), depth + 1)
                   for f in dataclasses.fields(value))
    return True


def _treedef_ours(td: Any) -> bool:
    data = td.node_data()
    if data is not None and not (_our_type(data[0]) and _our_value(data[1])):
        return False
    return all(_treedef_ours(c) for c in td.children())


def package_code_only(strategy: Any, *trees: Any) -> bool:
    """Whether the strategy and every pytree node type of ``trees`` come from this package:
    only then does :func:`source_digest` cover the code that the program was traced from (a
    user's own problem or strategy is traced in every process, never loaded stale)."""
    return _our_value(strategy) and all(_treedef_ours(jax.tree.structure(t)) for t in trees)


def single_device(tree: Any) -> bool:
    """Whether every array leaf lives on one device (sharded programs are not exported)."""
    for x in jax.tree.leaves(tree):
        if isinstance(x, jax.Array) and len(x.sharding.device_set) > 1:
            return False
    return True


def compiled(fn: Callable, args: tuple, key: str | None) -> tuple[Callable, str]:
    """``jax.jit``-ed ``fn`` compiled for ``args``, through the on-disk program cache when
    it is on and ``key`` is given. Returns the callable and how it was obtained:
    ``"loaded"`` (from an exported entry: no tracing), ``"exported"`` (traced, exported and
    written), ``"traced"`` (the cache is off, or the program cannot be exported)."""
    where = folder()
    if where is None or key is None:
        return fn.lower(*args).compile(), "traced"
    leaves, in_def = jax.tree.flatten(args)
    in_keys = _key_impls(leaves)
    plain = _key_data(leaves, in_keys)  # PRNG keys cross the exported interface as uint32
    entry, mark = where / f"{key}{_SUFFIX}", where / f"{key}{_MARK}"
    if entry.is_file():
        try:
            blob = pickle.loads(entry.read_bytes())
            exp = export.deserialize(bytearray(blob["exported"]))
            out_def, out_keys = blob["out_tree"], blob["out_keys"]
        except Exception as err:  # noqa: BLE001 - a damaged entry is rebuilt, as JAX's cache does
            warnings.warn(f"eaco_jax program cache: {entry.name} unreadable ({err}); "
                          "tracing again", stacklevel=3)
            entry.unlink(missing_ok=True)
        else:
            call = jax.jit(exp.call).lower(*plain).compile()
            return _wrap(call, in_keys, out_def, out_keys), "loaded"
    if mark.is_file():
        return fn.lower(*args).compile(), "traced"
    box: dict[str, Any] = {}

    def flat(*xs):
        xs = _wrap_keys(xs, in_keys)
        out, box["out_tree"] = jax.tree.flatten(fn(*jax.tree.unflatten(in_def, xs)))
        box["out_keys"] = _key_impls(out)
        return _key_data(out, box["out_keys"])

    checks = [export.DisabledSafetyCheck.custom_call(t) for t in _UNSTABLE_TARGETS]
    try:
        exp = export.export(jax.jit(flat), disabled_checks=checks)(*plain)
        data = exp.serialize()
    except NotImplementedError as err:  # host callbacks have no serialised form
        _write(mark, str(err).encode())
        return fn.lower(*args).compile(), "traced"
    _write(entry, pickle.dumps({"exported": bytes(data), "out_tree": box["out_tree"],
                                "out_keys": box["out_keys"]}))
    call = jax.jit(exp.call).lower(*plain).compile()
    return _wrap(call, in_keys, box["out_tree"], box["out_keys"]), "exported"


def _key_impls(leaves: list) -> list[str | None]:
    """The PRNG implementation of each typed-key leaf (None for other leaves)."""
    return [str(jax.random.key_impl(x))
            if jax.dtypes.issubdtype(getattr(x, "dtype", None), jax.dtypes.prng_key) else None
            for x in leaves]


def _key_data(leaves: list, impls: list) -> list:
    return [jax.random.key_data(x) if impl else x for x, impl in zip(leaves, impls, strict=True)]


def _wrap_keys(leaves: Any, impls: list) -> list:
    return [jax.random.wrap_key_data(x, impl=impl) if impl else x
            for x, impl in zip(leaves, impls, strict=True)]


def _wrap(call: Callable, in_keys: list, out_def: Any, out_keys: list) -> Callable:
    def run(*args):
        out = call(*_key_data(jax.tree.leaves(args), in_keys))
        return jax.tree.unflatten(out_def, _wrap_keys(out, out_keys))

    return run


def _write(path: Path, data: bytes) -> None:
    """Write atomically (a concurrent reader sees the old entry or the whole new one)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except OSError as err:  # an unwritable cache folder costs speed, not the run
        warnings.warn(f"eaco_jax program cache: cannot write {path} ({err})", stacklevel=3)

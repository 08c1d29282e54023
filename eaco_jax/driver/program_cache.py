"""Compiled chunks (and initial states) kept on disk as exported programs, so a fresh process
skips tracing.

JAX's persistent compilation cache keeps the compiled executable, but every new process still
traces and lowers the chunk before it can look the executable up, which for a colony with local
search takes longer than loading the executable (``experiments/startup_phases.py`` times the
phases). Here the first process also writes the traced chunk as a ``jax.export`` artifact; a
later process with the same code, versions, device, strategy and shapes deserialises it
(milliseconds), lowers the small wrapper and gets the executable from JAX's cache. The driver
sends its two programs through :func:`compiled`: the chunk of iterations and the initialiser
of the state.

On whenever JAX's persistent cache is (``jax_compilation_cache_dir``, as ``eaco`` sets it), in
``<that folder>/eaco_programs``; :func:`set_folder` chooses another folder or turns it off.
A program that cannot be exported (host callbacks: the native local search on a CPU) is
marked once and traced as before. An entry is keyed by a digest of everything that shapes the
program, the package's source included, so a code change never loads a stale program; for
that reason only programs built of this package's own strategies and problems are kept (a
user's own class, or a function held in a problem, is traced in every process, as a sharded
program is).

An entry is data, never code: a magic line, the sha256 of the rest, a one-line JSON header
(format, key, argument signature, which leaves are PRNG keys, the output pytree described by
node type names and JSON aux data, resolved only among built-in containers and this package's
own classes) and the ``jax.export`` bytes. Nothing read from the folder is unpickled, so a
writer of a shared cache cannot run code as its readers, and the key covers the JAX
configuration read while tracing (:func:`trace_flags`). An entry that fails to verify,
deserialise, lower or make its first call is removed with one warning and traced again.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import json
import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
from jax import export

from eaco_jax.driver.memory import tree_nbytes

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


#: parts of JAX option names that never change a traced program: where caches, logs and
#: dumps go, and how errors are reported
_NOT_TRACE = ("cache", "log", "dump", "pprint", "traceback", "explain", "timeout",
              "transfer_guard", "visible_devices", "pgle")


def trace_flags() -> tuple[tuple[str, str], ...]:
    """The JAX options in effect (this thread's, as tracing reads them) that may shape a
    traced program: every option but those naming caches, logs, dumps and error reporting.
    A list of options that matter would miss the next one JAX adds (a stale program with
    another answer); an extra option only costs a trace."""
    return tuple((name, repr(getattr(jax.config, name, value)))
                 for name, value in sorted(jax.config.values.items())
                 if not any(part in name for part in _NOT_TRACE))


def program_key(parts: tuple) -> str | None:
    """The entry's digest for these program-shaping ``parts`` and the JAX options that shape
    a trace (None: not cacheable, e.g. a strategy whose repr holds a function's address,
    which differs in every process)."""
    import jaxlib

    text = repr((parts, jax.__version__, jaxlib.__version__, jax.default_backend(),
                 [d.device_kind for d in jax.local_devices()[:1]], trace_flags()))
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
    signature = _arg_signature(plain)
    entry, mark = where / f"{key}{_SUFFIX}", where / f"{key}{_MARK}"
    if entry.is_file():
        try:
            header, data = _unpack(entry.read_bytes())
            if header.get("key") != key:
                raise ValueError(f"it holds the program of key {str(header.get('key'))[:32]}")
            if header.get("args") != signature or header.get("in_keys") != in_keys:
                raise ValueError("its arguments differ from this call's")
            out_def, out_keys = _tree_from_data(header["out_tree"]), list(header["out_keys"])
            if out_def.num_leaves != len(out_keys):
                raise ValueError("its output description is inconsistent")
            exp = export.deserialize(bytearray(data))
            call = jax.jit(exp.call).lower(*plain).compile()
        except Exception as err:  # noqa: BLE001 - any damage: rebuilt, as JAX's cache does
            _discard(entry, err)
        else:
            return _checked_first_call(_wrap(call, in_keys, out_def, out_keys), fn, entry), \
                "loaded"
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
    call = jax.jit(exp.call).lower(*plain).compile()
    run = _wrap(call, in_keys, box["out_tree"], box["out_keys"])
    try:
        out_tree = _tree_to_data(box["out_tree"])
    except ValueError as err:  # an output node of a type not ours: kept in this process only
        _write(mark, str(err).encode())
        return run, "traced"
    _write(entry, _pack({"format": _FORMAT, "key": key, "args": signature, "in_keys": in_keys,
                         "out_keys": box["out_keys"], "out_tree": out_tree}, bytes(data)))
    return run, "exported"


def _discard(entry: Path, err: BaseException) -> None:
    """One warning for a rejected entry, which is removed so the next run writes it anew."""
    reason = (str(err).strip().splitlines() or [type(err).__name__])[0][:200]
    try:
        entry.unlink(missing_ok=True)
        done = "removed it, tracing again"
    except OSError as why:
        done = f"tracing again; cannot remove it ({why.strerror}): delete it by hand"
    warnings.warn(f"eaco_jax program cache: entry {entry} unreadable ({reason}); {done}",
                  stacklevel=4)


def _checked_first_call(run: Callable, fn: Callable, entry: Path) -> Callable:
    """``run``, whose first call falls back to ``fn`` traced and compiled for the same
    arguments if the loaded program fails (one warning, the entry removed)."""
    box: dict[str, Callable] = {}

    def first(*args):
        if "run" in box:
            return box["run"](*args)
        try:
            out = run(*args)
        except Exception as err:  # noqa: BLE001 - a program that does not fit its call
            _discard(entry, err)
            box["run"] = fn.lower(*args).compile()
            return box["run"](*args)
        box["run"] = run
        return out

    if getattr(run, "out_nbytes", None) is not None:
        first.out_nbytes = run.out_nbytes
    return first


_MAGIC, _FORMAT = b"eaco_jax exported program\n", 1


def _pack(header: dict, data: bytes) -> bytes:
    """An entry: the magic line, the sha256 of everything after its line, the header as one
    JSON line, then the serialised program."""
    body = json.dumps(header, sort_keys=True, separators=(",", ":")).encode() + b"\n" + data
    return _MAGIC + hashlib.sha256(body).hexdigest().encode() + b"\n" + body


def _unpack(raw: bytes) -> tuple[dict, bytes]:
    """The header and program bytes of an entry, verified (ValueError if anything is off)."""
    if not raw.startswith(_MAGIC):
        raise ValueError("not an eaco_jax program entry")
    digest, _, body = raw[len(_MAGIC):].partition(b"\n")
    if hashlib.sha256(body).hexdigest().encode() != digest:
        raise ValueError("its sha256 does not match its contents")
    line, _, data = body.partition(b"\n")
    header = json.loads(line)
    if not isinstance(header, dict) or header.get("format") != _FORMAT:
        raise ValueError("unknown entry format")
    return header, data


def _arg_signature(plain: list) -> list[str]:
    """Shape, dtype and weak type of each flat argument: what the program was exported for."""
    avals = [jax.typeof(x) for x in plain]
    return [f"{a.shape}:{a.dtype}:{int(a.weak_type)}" for a in avals]


_BUILTIN_NODES: dict[str, type] = {"tuple": tuple, "list": list, "dict": dict,
                                   "None": type(None)}


def _aux_to_data(value: Any) -> Any:
    """A node's aux data as JSON (tuples tagged); ValueError for anything else."""
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, tuple):
        return {"tuple": [_aux_to_data(v) for v in value]}
    if isinstance(value, list):
        return [_aux_to_data(v) for v in value]
    raise ValueError(f"output pytree aux data of type {type(value).__name__} is not data")


def _aux_from_data(value: Any) -> Any:
    if isinstance(value, dict):
        return tuple(_aux_from_data(v) for v in value["tuple"])
    if isinstance(value, list):
        return [_aux_from_data(v) for v in value]
    return value


def _tree_to_data(td: Any) -> Any:
    """A treedef as JSON: None for a leaf, else ``[type name, aux, children]``, where the
    type is a built-in container or a class of this package (ValueError otherwise)."""
    node = td.node_data()
    if node is None:
        return None
    kind, aux = node
    name = next((n for n, t in _BUILTIN_NODES.items() if t is kind), None)
    if name is None:
        module = getattr(kind, "__module__", "") or ""
        if module.split(".")[0] != "eaco_jax":
            raise ValueError(f"output pytree node {kind!r} is not of this package")
        name = f"{module}:{kind.__qualname__}"
    return [name, _aux_to_data(aux), [_tree_to_data(c) for c in td.children()]]


def _tree_from_data(data: Any) -> Any:
    """The treedef :func:`_tree_to_data` described; a class is looked up only in this
    package's modules, never called or unpickled here."""
    if data is None:
        return jax.tree.structure(0)
    name, aux, children = data
    kind = _BUILTIN_NODES.get(name)
    if kind is None:
        module, _, qualname = name.partition(":")
        if module != "eaco_jax" and not module.startswith("eaco_jax."):
            raise ValueError(f"output node type {name[:80]} is not of this package")
        kind = importlib.import_module(module)
        for part in qualname.split("."):
            kind = getattr(kind, part)
        if not isinstance(kind, type):
            raise ValueError(f"output node type {name[:80]} is not a class")
    return jax.tree_util.PyTreeDef.from_node_data_and_children(
        jax.tree_util.default_registry, (kind, _aux_from_data(aux)),
        [_tree_from_data(c) for c in children])


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

    leaves = jax.tree.leaves(getattr(call, "out_info", None))
    if len(leaves) == len(out_keys):  # PRNG keys (key data here) are not counted
        run.out_nbytes = tree_nbytes([a for a, k in zip(leaves, out_keys, strict=True)
                                      if not k])
    return run


def out_nbytes(program: Callable) -> int | None:
    """Bytes of a compiled or loaded program's outputs, PRNG keys not counted (None where the
    program does not tell): a colony state's size without tracing its initialiser again."""
    known = getattr(program, "out_nbytes", None)
    if known is not None:
        return int(known)
    info = getattr(program, "out_info", None)
    return None if info is None else tree_nbytes(info)


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

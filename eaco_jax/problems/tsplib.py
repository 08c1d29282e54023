"""TSPLIB reader and the TSPLIB95 distance functions.

Distances follow Reinelt's TSPLIB95 specification exactly, because published optima (e.g.
att48 = 10628, ulysses22 = 7013) are only reproducible with its integer rounding rules:

* ``EUC_2D``:  ``nint(sqrt(dx^2 + dy^2))`` with ``nint(x) = int(x + 0.5)``;
* ``CEIL_2D``: ``ceil(sqrt(dx^2 + dy^2))``;
* ``ATT``:     pseudo-Euclidean ``r = sqrt((dx^2 + dy^2) / 10)``, ``t = nint(r)``,
  ``d = t + 1 if t < r else t``;
* ``GEO``:     coordinates are ``DDD.MM`` (degrees.minutes);
  ``lat = PI * (deg + 5 * min / 3) / 180`` with ``deg`` the integer part (truncated, as in
  the TSPLIB FAQ and Concorde), ``PI = 3.141593``,
  and ``d = int(RRR * acos(0.5 * ((1 + q1) q2 - (1 - q1) q3)) + 1)`` with ``RRR = 6378.388``.

``EXPLICIT`` instances (``FULL_MATRIX``, ``UPPER_ROW``, ``LOWER_ROW``, ``UPPER_DIAG_ROW``,
``LOWER_DIAG_ROW``) are read as well. Anything else raises :class:`ProblemError` naming the file.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from pathlib import Path

import numpy as np

from eaco_jax.problems.base import ProblemError

COORD_TYPES = ("EUC_2D", "CEIL_2D", "ATT", "GEO")
EXPLICIT_FORMATS = ("FULL_MATRIX", "UPPER_ROW", "LOWER_ROW", "UPPER_DIAG_ROW", "LOWER_DIAG_ROW")
_SECTIONS = (
    "NODE_COORD_SECTION",
    "EDGE_WEIGHT_SECTION",
    "DISPLAY_DATA_SECTION",
    "TOUR_SECTION",
    "DEPOT_SECTION",
    "DEMAND_SECTION",
    "FIXED_EDGES_SECTION",
)

GEO_PI = 3.141593
GEO_RRR = 6378.388


@dataclasses.dataclass(frozen=True)
class TsplibInstance:
    """One symmetric TSPLIB instance.

    Attributes:
      name / comment: the header fields (``name`` falls back to the file stem).
      dimension: number of cities ``n``.
      edge_weight_type: ``EUC_2D``, ``CEIL_2D``, ``ATT``, ``GEO`` or ``EXPLICIT``.
      coords: ``(n, 2)`` float64 node coordinates ordered by node id (for ``EXPLICIT`` the
        ``DISPLAY_DATA_SECTION`` if present, else ``None``).
      edge_weights: ``(n, n)`` int64 matrix for ``EXPLICIT`` instances, else ``None``.
      path: the file read.
    """

    name: str
    comment: str
    dimension: int
    edge_weight_type: str
    coords: np.ndarray | None
    edge_weights: np.ndarray | None = None
    path: str = ""


def _fail(path: Path, message: str, line: int | None = None) -> ProblemError:
    where = f"{path}:{line}" if line is not None else str(path)
    return ProblemError(f"{where}: {message}")


def _parse_header(raw: str) -> tuple[str, str] | None:
    """``KEY : VALUE`` / ``KEY: VALUE`` -> (KEY, VALUE); None for a non-header line."""
    if ":" not in raw:
        return None
    key, value = raw.split(":", 1)
    key = key.strip().upper()
    if not key or " " in key:
        return None
    return key, value.strip()


def memory_bytes() -> int:
    """Physical memory of this machine in bytes (a bound for what a problem may allocate)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # not POSIX: assume plenty
        return 2**50


#: host bytes per city of a coordinate instance on the sparse path (coordinates, candidate
#: lists and the k-d tree's work arrays, with room to spare)
SPARSE_CITY_BYTES = 1024


def check_dimension(n: int, where: str, matrix: bool = True) -> None:
    """Refuse a city count whose distance matrices (float64 + float32, n x n) do not fit, or
    (``matrix=False``, coordinates for the sparse path) whose per-city arrays do not."""
    need = 16 * n * n if matrix else SPARSE_CITY_BYTES * n
    if need > memory_bytes() // 2:
        what = "its distance matrix" if matrix else "its coordinates and candidate lists"
        raise ProblemError(
            f"{where}: DIMENSION {n} needs {need / 2**30:.1f} GiB for {what}, more "
            f"than half of this machine's {memory_bytes() / 2**30:.1f} GiB")


def _read_coords(path: Path, lines: list[tuple[int, str]], n: int, section: str) -> np.ndarray:
    """Parse ``id x y`` rows of a coordinate section into an ``(n, 2)`` array ordered by id."""
    if not lines:
        raise _fail(path, f"{section} is empty (DIMENSION is {n})")
    if len(lines) != n:  # before allocating anything of size n
        raise _fail(path, f"{section} has {len(lines)} nodes but DIMENSION is {n}")
    coords = np.full((n, 2), np.nan)
    seen = np.zeros(n, bool)
    for lineno, raw in lines:
        parts = raw.split()
        if len(parts) != 3:
            raise _fail(
                path, f"{section} row must be 'id x y' (3 fields), got {raw.strip()!r}", lineno
            )
        try:
            node = int(parts[0])
        except ValueError:
            raise _fail(path, f"node id {parts[0]!r} is not an integer", lineno) from None
        try:
            x, y = float(parts[1]), float(parts[2])
        except ValueError:
            raise _fail(path, f"non-numeric coordinate in {raw.strip()!r}", lineno) from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise _fail(path, f"non-finite coordinate in {raw.strip()!r}", lineno)
        if not 1 <= node <= n:
            raise _fail(path, f"node id {node} outside 1..{n} (DIMENSION is {n})", lineno)
        if seen[node - 1]:
            raise _fail(path, f"duplicate node id {node}", lineno)
        seen[node - 1] = True
        coords[node - 1] = (x, y)
    if len(lines) != n or not seen.all():
        raise _fail(path, f"{section} has {len(lines)} nodes but DIMENSION is {n}")
    return coords


def _read_explicit(path: Path, lines: list[tuple[int, str]], n: int, fmt: str) -> np.ndarray:
    """Parse an ``EDGE_WEIGHT_SECTION`` of the given format into a symmetric int64 matrix."""
    counts = {"FULL_MATRIX": n * n, "UPPER_ROW": n * (n - 1) // 2, "LOWER_ROW": n * (n - 1) // 2,
              "UPPER_DIAG_ROW": n * (n + 1) // 2, "LOWER_DIAG_ROW": n * (n + 1) // 2}
    found = sum(len(raw.split()) for _, raw in lines)
    if found != counts[fmt]:  # before allocating the n x n matrix
        raise _fail(
            path,
            f"EDGE_WEIGHT_SECTION ({fmt}) has {found} numbers, expected {counts[fmt]}"
            f" for DIMENSION {n}",
        )
    values: list[float] = []
    for lineno, raw in lines:
        for token in raw.split():
            try:
                values.append(float(token))
            except ValueError:
                raise _fail(path, f"non-numeric edge weight {token!r}", lineno) from None
    if fmt == "FULL_MATRIX":
        mask = np.ones((n, n), bool)
    else:
        strict = fmt in ("UPPER_ROW", "LOWER_ROW")
        upper = fmt.startswith("UPPER")
        k = 1 if strict else 0
        mask = np.triu(np.ones((n, n), bool), k) if upper else np.tril(np.ones((n, n), bool), -k)
    rows, cols = np.nonzero(mask)  # row-major order = the order TSPLIB lists them
    expected = int(mask.sum())
    if len(values) != expected:
        raise _fail(
            path,
            f"EDGE_WEIGHT_SECTION ({fmt}) has {len(values)} numbers, expected {expected}"
            f" for DIMENSION {n}",
        )
    w = np.asarray(values)
    if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w != np.round(w)):
        raise _fail(path, "EDGE_WEIGHT_SECTION must hold non-negative integers")
    d = np.zeros((n, n))
    d[rows, cols] = w
    if fmt == "FULL_MATRIX":
        if not np.array_equal(d, d.T):
            raise _fail(path, "FULL_MATRIX is not symmetric (asymmetric TSP is not supported)")
    else:
        d = np.where(mask, d, d.T)
    np.fill_diagonal(d, 0)
    return d.astype(np.int64)


def read_tsplib(path: str | Path) -> TsplibInstance:
    """Read a symmetric TSPLIB ``.tsp`` file. Malformed input raises :class:`ProblemError`."""
    path = Path(path)
    if path.is_dir():
        raise ProblemError(f"{path}: is a directory, not a TSPLIB .tsp file")
    if not path.is_file():
        raise ProblemError(f"{path}: no such TSPLIB file")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise ProblemError(f"{path}: not a text file (expected a TSPLIB .tsp file)") from None
    fast = _read_coords_fast(path, text)
    if fast is not None:
        return fast
    lines = text.splitlines()
    if not any(line.strip() for line in lines):
        raise ProblemError(f"{path}: empty file (expected a TSPLIB .tsp file)")

    header: dict[str, str] = {}
    sections: dict[str, list[tuple[int, str]]] = {}
    current: str | None = None
    for lineno, raw in enumerate(lines, start=1):
        stripped = raw.strip()
        if not stripped:
            continue
        token = stripped.split(":")[0].strip().upper()
        if token == "EOF":
            break
        if token in _SECTIONS:
            current = token
            sections[current] = []
            continue
        if current is None:
            kv = _parse_header(stripped)
            if kv is None:
                raise _fail(path, f"expected 'KEY : VALUE' header line, got {stripped!r}", lineno)
            header[kv[0]] = kv[1]
            continue
        kv = _parse_header(stripped)
        if kv is not None and re.fullmatch(r"[A-Z_]+", kv[0]):
            # a header keyword after a section (allowed by TSPLIB) ends the section
            header[kv[0]] = kv[1]
            current = None
            continue
        sections[current].append((lineno, raw))

    kind = header.get("TYPE", "TSP").split()[0].upper() if header.get("TYPE") else "TSP"
    if kind != "TSP":
        raise _fail(path, f"TYPE {kind} is not supported (only symmetric TSP)")
    if "DIMENSION" not in header:
        raise _fail(path, "missing DIMENSION header")
    try:
        n = int(header["DIMENSION"])
    except ValueError:
        raise _fail(path, f"DIMENSION {header['DIMENSION']!r} is not an integer") from None
    if n < 3:
        raise _fail(path, f"DIMENSION {n} is too small (a tour needs at least 3 cities)")
    ewt = header.get("EDGE_WEIGHT_TYPE", "").upper()
    check_dimension(n, str(path), matrix=ewt not in COORD_TYPES)
    name = header.get("NAME", path.stem).removesuffix(".tsp") or path.stem
    comment = header.get("COMMENT", "")

    if ewt in COORD_TYPES:
        if "NODE_COORD_SECTION" not in sections:
            raise _fail(path, f"missing NODE_COORD_SECTION (needed for EDGE_WEIGHT_TYPE {ewt})")
        coords = _read_coords(path, sections["NODE_COORD_SECTION"], n, "NODE_COORD_SECTION")
        return TsplibInstance(name, comment, n, ewt, coords, None, str(path))
    if ewt == "EXPLICIT":
        fmt = header.get("EDGE_WEIGHT_FORMAT", "").upper()
        if fmt not in EXPLICIT_FORMATS:
            raise _fail(
                path,
                f"EDGE_WEIGHT_FORMAT {fmt or '(missing)'} is not supported; use one of"
                f" {', '.join(EXPLICIT_FORMATS)}",
            )
        if "EDGE_WEIGHT_SECTION" not in sections:
            raise _fail(path, "missing EDGE_WEIGHT_SECTION (needed for EDGE_WEIGHT_TYPE EXPLICIT)")
        weights = _read_explicit(path, sections["EDGE_WEIGHT_SECTION"], n, fmt)
        coords = None
        if sections.get("DISPLAY_DATA_SECTION"):
            coords = _read_coords(path, sections["DISPLAY_DATA_SECTION"], n, "DISPLAY_DATA_SECTION")
        return TsplibInstance(name, comment, n, ewt, coords, weights, str(path))
    raise _fail(
        path,
        f"EDGE_WEIGHT_TYPE {ewt or '(missing)'} is not supported; use one of"
        f" {', '.join(COORD_TYPES)}, EXPLICIT",
    )


_COORD_SECTION = re.compile(r"^[ \t]*NODE_COORD_SECTION[ \t]*:?[ \t]*$", re.M)
_KEYWORD_LINE = re.compile(r"^[ \t]*[A-Za-z]", re.M)
_ROW = re.compile(r"^[ \t]*\S+[ \t]+\S+[ \t]+\S+[ \t]*\r?$", re.M)


def _read_coords_fast(path: Path, text: str) -> TsplibInstance | None:
    """A coordinate instance (header, NODE_COORD_SECTION, EOF) parsed with numpy: no Python
    loop over the cities (a 100,000-city file in a fraction of a second). None for anything
    else, or anything malformed: the line-by-line reader then reads it, or names the fault."""
    section = _COORD_SECTION.search(text)
    if section is None:
        return None
    header: dict[str, str] = {}
    for raw in text[: section.start()].splitlines():  # the header: a few lines
        stripped = raw.strip()
        if not stripped:
            continue
        kv = _parse_header(stripped)
        if kv is None or kv[0] in _SECTIONS or kv[0] == "EOF":
            return None
        header[kv[0]] = kv[1]
    rest = text[section.end():]
    end = _KEYWORD_LINE.search(rest)
    block = rest if end is None else rest[: end.start()]
    if end is not None and rest[end.start():].strip().split(":")[0].strip().upper() != "EOF":
        return None
    kind = header.get("TYPE", "TSP").split()[0].upper() if header.get("TYPE") else "TSP"
    ewt = header.get("EDGE_WEIGHT_TYPE", "").upper()
    try:
        n = int(header.get("DIMENSION", ""))
    except ValueError:
        return None
    if kind != "TSP" or ewt not in COORD_TYPES or n < 3:
        return None
    check_dimension(n, str(path), matrix=False)
    tokens = block.split()
    if len(tokens) != 3 * n or len(_ROW.findall(block)) != n:  # n rows of 3 fields
        return None
    try:
        ids = np.array(tokens[0::3], dtype=np.int64)
        xy = np.stack([np.array(tokens[1::3], dtype=np.float64),
                       np.array(tokens[2::3], dtype=np.float64)], axis=1)
    except (ValueError, OverflowError):
        return None
    if ids.min() < 1 or ids.max() > n or not np.all(np.isfinite(xy)):
        return None
    coords = np.full((n, 2), np.nan)
    coords[ids - 1] = xy
    if np.isnan(coords).any():  # a repeated id leaves another row unset
        return None
    name = header.get("NAME", path.stem).removesuffix(".tsp") or path.stem
    return TsplibInstance(name, header.get("COMMENT", ""), n, ewt, coords, None, str(path))


def _nint(x: np.ndarray) -> np.ndarray:
    return np.floor(x + 0.5)


def _geo_radians(v: np.ndarray) -> np.ndarray:
    deg = np.trunc(v)
    minutes = v - deg
    return GEO_PI * (deg + 5.0 * minutes / 3.0) / 180.0


def coord_distances(coords: np.ndarray, metric: str) -> np.ndarray:
    """``(n, n)`` int64 TSPLIB distances between ``coords`` under ``metric``."""
    metric = metric.upper()
    xy = np.asarray(coords, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ProblemError(f"coords must have shape (n, 2), got {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ProblemError("coords contain NaN or infinite values")
    if metric == "GEO":
        lat, lon = _geo_radians(xy[:, 0]), _geo_radians(xy[:, 1])
        q1 = np.cos(lon[:, None] - lon[None, :])
        q2 = np.cos(lat[:, None] - lat[None, :])
        q3 = np.cos(lat[:, None] + lat[None, :])
        arg = np.clip(0.5 * ((1.0 + q1) * q2 - (1.0 - q1) * q3), -1.0, 1.0)
        d = np.trunc(GEO_RRR * np.arccos(arg) + 1.0)
    else:
        diff = xy[:, None, :] - xy[None, :, :]
        sq = (diff**2).sum(-1)
        if metric == "EUC_2D":
            d = _nint(np.sqrt(sq))
        elif metric == "CEIL_2D":
            d = np.ceil(np.sqrt(sq))
        elif metric == "ATT":
            r = np.sqrt(sq / 10.0)
            t = _nint(r)
            d = np.where(t < r, t + 1.0, t)
        else:
            raise ProblemError(
                f"metric {metric!r} is not supported; use one of {', '.join(COORD_TYPES)}"
            )
    d = d.astype(np.int64)
    np.fill_diagonal(d, 0)
    return d


def pair_distances(a: np.ndarray, b: np.ndarray, metric: str,
                   rounded: bool = True) -> np.ndarray:
    """float64 TSPLIB distances between coordinates ``a`` and ``b`` (..., 2), broadcast:
    the formulas of :func:`coord_distances` for one pair at a time (O(pairs) memory);
    ``rounded=False`` the real Euclidean distance."""
    metric = metric.upper()
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if metric == "GEO":
        lat_a, lon_a = _geo_radians(a[..., 0]), _geo_radians(a[..., 1])
        lat_b, lon_b = _geo_radians(b[..., 0]), _geo_radians(b[..., 1])
        q1, q2, q3 = np.cos(lon_a - lon_b), np.cos(lat_a - lat_b), np.cos(lat_a + lat_b)
        arg = np.clip(0.5 * ((1.0 + q1) * q2 - (1.0 - q1) * q3), -1.0, 1.0)
        return np.trunc(GEO_RRR * np.arccos(arg) + 1.0)
    dx = a[..., 0] - b[..., 0]
    dy = a[..., 1] - b[..., 1]
    sq = dx**2 + dy**2
    if not rounded:
        return np.sqrt(sq)
    if metric == "EUC_2D":
        return _nint(np.sqrt(sq))
    if metric == "CEIL_2D":
        return np.ceil(np.sqrt(sq))
    if metric == "ATT":
        r = np.sqrt(sq / 10.0)
        t = _nint(r)
        return np.where(t < r, t + 1.0, t)
    raise ProblemError(f"metric {metric!r} is not supported; use one of {', '.join(COORD_TYPES)}")


def distance_matrix(instance: TsplibInstance) -> np.ndarray:
    """``(n, n)`` int64 distance matrix of ``instance``, by the TSPLIB95 rules."""
    if instance.edge_weight_type == "EXPLICIT":
        return np.array(instance.edge_weights, dtype=np.int64)
    return coord_distances(instance.coords, instance.edge_weight_type)

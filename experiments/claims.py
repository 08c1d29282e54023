"""The claims manifest (``experiments/claims.toml``): every number that README.md and docs/
state, with the command that produces it, the result file it is read from, the machine, and
the seeds used to choose a setting and to report it.

    python experiments/claims.py list                  # id, machine, rerun cost, stated figure
    python experiments/claims.py check [ID ...]        # stated figure == the file's (all: none)
    python experiments/claims.py run ID                # rerun one claim's command, then check it
    python experiments/claims.py cpu --max-seconds 90  # rerun every CPU claim below the bound

The manifest is data (TOML, read with ``tomllib``); this module reads it with the standard
library only, so the docs generator and the tests can import it without JAX.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shlex
import subprocess
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = Path(__file__).with_name("claims.toml")
AREAS = {"tsp": "TSP", "constrained": "Constrained problems (CEC2006, paper tables)",
         "gait": "Gait", "path": "Path planning", "speed": "Speed and startup",
         "resume": "Checkpoints, resume and soak",
         "multiobjective": "Multi-objective (Pareto fronts against NSGA-II)"}
MACHINES = ("cpu-2core", "h100", "h200", "h200x2")
PROVENANCE = ("device", "versions", "date", "command")
REQUIRED = ("id", "area", "text", "command", "result", "field", "value", "decimals", "machine",
            "select_seeds", "report_seeds", "cpu_rerun_seconds")
ID_RE = re.compile(r"^[a-z0-9]+(-[a-z0-9.]+)*$")
# where result files keep their provenance: these keys at the top level or one level down
_PROVENANCE_KEYS = {
    "device": ("device", "device_kind"),
    "versions": ("jax", "versions"),
    "date": ("date", "created", "timestamp"),
    "command": ("command", "commands", "argv"),
}


class ManifestError(ValueError):
    """The manifest is malformed or a claim does not match its file."""


@dataclass(frozen=True)
class Claim:
    """One stated number: where it comes from and how to read it from its file."""

    id: str
    area: str
    text: str
    command: str
    result: str
    field: tuple
    value: float
    decimals: int
    machine: str
    select_seeds: str
    report_seeds: str
    cpu_rerun_seconds: float
    unit: str = ""
    scale: float = 1.0
    op: str = ""
    family: tuple = ()
    note: str = ""
    headline: str = ""
    provenance: dict = field(default_factory=dict)

    @property
    def stated(self) -> str:
        """The figure as the docs print it (the manifest's value at its rounding, with unit)."""
        return format_value(self.value, self.decimals) + self.unit

    @property
    def on_cpu(self) -> bool:
        return self.machine.startswith("cpu")


def format_value(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` places and thousands separators from 10,000 on."""
    text = f"{value:,.{decimals}f}" if abs(value) >= 10_000 else f"{value:.{decimals}f}"
    return text.replace("-", "\u2212") if value < 0 else text


def load(path: Path = MANIFEST) -> list[Claim]:
    """Every claim of the manifest, validated (unique kebab-case ids, known areas and
    machines, existing result files, complete provenance or an explicit "unknown")."""
    data = tomllib.loads(path.read_text())
    claims, seen = [], set()
    for raw in data.get("claim", []):
        missing = [k for k in REQUIRED if k not in raw]
        if missing:
            raise ManifestError(f"claim {raw.get('id', '?')!r} lacks {', '.join(missing)}")
        cid = raw["id"]
        if not ID_RE.match(cid):
            raise ManifestError(f"claim id {cid!r} is not kebab-case")
        if cid in seen:
            raise ManifestError(f"claim id {cid!r} appears twice")
        seen.add(cid)
        if raw["area"] not in AREAS:
            raise ManifestError(f"claim {cid}: area {raw['area']!r} not in {sorted(AREAS)}")
        if raw["machine"] not in MACHINES:
            raise ManifestError(f"claim {cid}: machine {raw['machine']!r} not in {MACHINES}")
        unknown = set(raw) - set(REQUIRED) - {"unit", "scale", "op", "family", "note",
                                              "headline", "provenance"}
        if unknown:
            raise ManifestError(f"claim {cid}: unknown keys {sorted(unknown)}")
        claim = Claim(**{**raw, "field": tuple(raw["field"]),
                         "family": tuple(raw.get("family", ())),
                         "value": float(raw["value"]),
                         "provenance": dict(raw.get("provenance", {}))})
        if not (ROOT / claim.result).is_file():
            raise ManifestError(f"claim {cid}: result file {claim.result} does not exist")
        if claim.op not in ("", "holm", "ratio"):
            raise ManifestError(f"claim {cid}: op {claim.op!r} is not holm or ratio")
        provenance(claim)  # raises where an item is neither in the file nor in the manifest
        claims.append(claim)
    return claims


def by_id(claims: list[Claim]) -> dict[str, Claim]:
    return {c.id: c for c in claims}


def read_json(relpath: str) -> Any:
    return json.loads((ROOT / relpath).read_text())


def lookup(data: Any, path: tuple) -> Any:
    """Follow ``path`` into ``data``: a string is a key, an integer a list index, a table the
    one list element whose items all equal it, ``"*"`` every element (a list comes back, with
    None for an element that lacks the rest of the path)."""
    for i, step in enumerate(path):
        if step == "*":
            return [_lookup_or_none(item, path[i + 1:]) for item in data]
        if isinstance(step, dict):
            hits = [row for row in data if all(row.get(k) == v for k, v in step.items())]
            if len(hits) != 1:
                raise ManifestError(f"{step} matches {len(hits)} rows, not one")
            data = hits[0]
        elif isinstance(step, int):
            data = data[step]
        else:
            if step not in data:
                raise ManifestError(f"no key {step!r} (have {sorted(data)[:12]})")
            data = data[step]
    return data


def _lookup_or_none(data: Any, path: tuple) -> Any:
    try:
        return lookup(data, path)
    except ManifestError:
        return None


def holm(pvalues: list[float]) -> list[float]:
    """Holm's step-down adjustment, in the input order."""
    order = sorted(range(len(pvalues)), key=lambda i: pvalues[i])
    adjusted, running = [0.0] * len(pvalues), 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(pvalues) - rank) * pvalues[i]))
        adjusted[i] = running
    return adjusted


def figure(claim: Claim) -> float:
    """The claim's figure as its result file gives it (scaled, before rounding)."""
    data = read_json(claim.result)
    value = lookup(data, claim.field)
    if claim.op == "ratio":
        value = value / lookup(data, claim.family)
    elif claim.op == "holm":
        family = [p for p in lookup(data, claim.family) if p is not None]
        value = holm(family)[family.index(value)]
    return float(value) * claim.scale


def matches(claim: Claim) -> bool:
    """Whether the stated value is the file's figure at the stated rounding."""
    got = figure(claim)
    return math.isclose(round(got, claim.decimals), claim.value, abs_tol=1e-9)


def _find(data: Any, keys: tuple[str, ...]) -> Any:
    if not isinstance(data, dict):
        return None
    for key in keys:
        if data.get(key) not in (None, "", []):
            return data[key]
    for value in data.values():
        if isinstance(value, dict):
            for key in keys:
                if value.get(key) not in (None, "", []):
                    return value[key]
    return None


def provenance(claim: Claim) -> dict[str, str]:
    """Device, versions, date and command of the claim's result file: from the file where it
    records them, else from the manifest's ``provenance`` table ("unknown" where nobody
    knows: the claim's provenance is then incomplete)."""
    data = read_json(claim.result)
    out = {}
    for item in PROVENANCE:
        found = _find(data, _PROVENANCE_KEYS[item])
        if item in claim.provenance:
            out[item] = str(claim.provenance[item])
        elif found is not None:
            out[item] = " ".join(found) if isinstance(found, list) and item == "command" and \
                all(isinstance(x, str) for x in found) else str(found)
            if item == "command" and isinstance(found, list) and found and "--" in found[0]:
                out[item] = "argv: " + out[item]
        else:
            raise ManifestError(f"claim {claim.id}: {claim.result} records no {item}; add "
                                f"provenance.{item} (or \"unknown\") to the manifest entry")
    return out


def incomplete(claim: Claim) -> list[str]:
    """The provenance items nobody knows for this claim's file."""
    return [k for k, v in provenance(claim).items() if v == "unknown"]


def rerun(claim: Claim) -> int:
    """Run the claim's command from the repository root (``python`` and ``eaco`` resolve to
    this interpreter's environment; CPU claims run with ``JAX_PLATFORMS=cpu``)."""
    argv = shlex.split(claim.command)
    if argv[0] == "python":
        argv[0] = sys.executable
    elif (Path(sys.executable).parent / argv[0]).exists():
        argv[0] = str(Path(sys.executable).parent / argv[0])
    env = {**os.environ, **({"JAX_PLATFORMS": "cpu"} if claim.on_cpu else {})}
    print("$ " + claim.command, flush=True)
    return subprocess.run(argv, cwd=ROOT, env=env).returncode


def check(claims: list[Claim]) -> list[str]:
    """One line per claim whose file no longer gives its stated figure."""
    bad = []
    for c in claims:
        try:
            ok = matches(c)
        except (ManifestError, KeyError, IndexError, TypeError) as err:
            bad.append(f"{c.id}: {c.result}: {err}")
            continue
        if not ok:
            bad.append(f"{c.id}: stated {c.stated}, {c.result} gives "
                       f"{format_value(figure(c), c.decimals + 2)}{c.unit}")
    return bad


# ---------------------------------------------------------------- numbers in the docs

# the generated docs (their numbers come from code or files) and nothing else is exempt
GENERATED_DOCS = ("bad_inputs.md", "sweeps.md", "results.md", "evidence.md")
_UNITS = (r"%|×|ms|s|m/s|m|MB|GiB|GB|W|°/s|tours/s|steps/s|evaluations|iterations|seeds?"
          r"|runs|falls|ants|minutes|SIGKILLs|M")
MEASURED = re.compile(r"(?<![\w.±~<>≤≥=+-])\d[\d,]*(\.\d+)?\s?(" + _UNITS + r")(?![\w/])")
BARE_CELL = re.compile(r"^\s*\**[−-]?\d[\d,]*(\.\d+)?\**\s*$")
REFERENCE = re.compile(r"\[\^([a-z0-9.-]+)\]|\((?:docs/)?results\.md#([a-z0-9.-]+)\)")


def _strip_code(text: str) -> str:
    """Drop fenced code blocks, HTML comments, inline code and link targets other than
    claim references: commands, flags, file names and versions live there."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    text = re.sub(r"`[^`]*`", "", text)
    return re.sub(r"\]\((?!(?:docs/)?results\.md#)[^)]*\)", "]", text)


def blocks(text: str) -> list[str]:
    """Paragraphs, list items and table rows of a markdown text, code removed."""
    out: list[str] = []
    for para in re.split(r"\n\s*\n", _strip_code(text)):
        current: list[str] = []
        for line in para.splitlines():
            if line.lstrip().startswith("|") or re.match(r"\s*([-*]|\d+\.)\s", line) \
                    or line.lstrip().startswith("#"):
                if current:
                    out.append("\n".join(current))
                current = [line]
                if line.lstrip().startswith(("|", "#")):
                    out.append(line)
                    current = []
            else:
                current.append(line)
        if current:
            out.append("\n".join(current))
    return [b for b in out if b.strip()]


def measured_numbers(block: str) -> list[str]:
    """The measured numbers of one block: digits with a unit of measure, or (in a table
    row that is not the header's separator) a cell that is a bare number."""
    found = [m.group(0) for m in MEASURED.finditer(block)]
    if block.lstrip().startswith("|") and not re.match(r"^\s*\|[\s|:-]+\|\s*$", block):
        found += [c.strip() for c in block.strip().strip("|").split("|") if BARE_CELL.match(c)]
    return found


def references(block: str) -> list[str]:
    return [a or b for a, b in REFERENCE.findall(block)]


def unresolved(text: str, claims: list[Claim]) -> list[str]:
    """One line per block of ``text`` that states a measured number without a claim
    reference, cites an unknown id, or cites claims none of whose stated figure it shows."""
    index = by_id(claims)
    problems = []
    for block in blocks(text):
        numbers, refs = measured_numbers(block), references(block)
        first = " ".join(block.split())[:90]
        unknown = [r for r in refs if r not in index]
        if unknown:
            problems.append(f"unknown claim id {unknown}: {first}")
        elif numbers and not refs:
            problems.append(f"{numbers[:3]} without a claim reference: {first}")
        elif refs and not any(format_value(index[r].value, index[r].decimals) in block
                              for r in refs):
            problems.append(f"none of {refs}'s figures appears: {first}")
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("list")
    p_check = sub.add_parser("check")
    p_check.add_argument("ids", nargs="*")
    p_run = sub.add_parser("run")
    p_run.add_argument("id")
    p_cpu = sub.add_parser("cpu")
    p_cpu.add_argument("--max-seconds", type=float, default=90.0)
    args = ap.parse_args(argv)
    claims = load()
    index = by_id(claims)
    if args.cmd == "list":
        for c in claims:
            print(f"{c.id:44s} {c.machine:10s} {c.cpu_rerun_seconds:>7.0f} s  {c.stated}")
        return 0
    if args.cmd == "check":
        chosen = [index[i] for i in args.ids] if args.ids else claims
        bad = check(chosen)
        print("\n".join(bad) or f"{len(chosen)} claims: each file gives the stated figure")
        return 1 if bad else 0
    if args.cmd == "run":
        if args.id not in index:
            print(f"error: no claim {args.id!r}; `python experiments/claims.py list`")
            return 2
        chosen = [index[args.id]]
    else:
        chosen = [c for c in claims if c.on_cpu and c.cpu_rerun_seconds <= args.max_seconds]
    status = 0
    done: set[str] = set()
    for c in chosen:
        if c.command not in done:
            done.add(c.command)
            if rerun(c) != 0:
                status = 1
        got = format_value(figure(c), c.decimals) + c.unit
        ok = matches(c)
        status |= 0 if ok else 1
        print(f"{c.id}: stated {c.stated}, rerun gives {got}: {'same' if ok else 'DIFFERS'}")
    return status


if __name__ == "__main__":
    sys.exit(main())

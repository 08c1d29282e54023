"""Device time of a compiled call, kernel by kernel, from a ``jax.profiler`` trace.

``kernel_table(fn, repeats)`` runs ``fn`` (warm) ``repeats`` times under the profiler, reads
the trace back with ``jax.profiler.ProfileData`` and sums the duration of every event on the
device planes by (line, name): the kernels that a timing of the whole call cannot tell apart.
The first stats of each name (the HLO op, the JAX op path where the backend records them)
come along so a fusion's name can be traced to the code.
"""

from __future__ import annotations

import tempfile
from collections import defaultdict
from pathlib import Path

import jax


def _block(out):
    return jax.block_until_ready(out)


def kernel_table(fn, repeats: int = 3, top: int = 40) -> dict:
    """{"planes": [...], "rows": [{line, name, ms_per_call, count_per_call, stats}], ...}."""
    from jax.profiler import ProfileData

    _block(fn())
    with tempfile.TemporaryDirectory() as tmp:
        with jax.profiler.trace(tmp):
            for _ in range(repeats):
                _block(fn())
        files = sorted(Path(tmp).rglob("*.xplane.pb"))
        if not files:
            return {"error": "no trace written"}
        data = ProfileData.from_file(str(files[-1]))
    total = defaultdict(float)
    count = defaultdict(int)
    stats = {}
    planes = []
    for plane in data.planes:
        planes.append(plane.name)
        if not plane.name.startswith("/device:"):
            continue
        for line in plane.lines:
            for ev in line.events:
                key = (line.name, ev.name)
                total[key] += ev.duration_ns
                count[key] += 1
                if key not in stats:
                    stats[key] = {str(k): str(v)[:200] for k, v in ev.stats}
    lines = defaultdict(float)
    for (line, _), ns in total.items():
        lines[line] += ns / repeats / 1e6
    rows = [{"line": line, "name": name, "ms_per_call": ns / repeats / 1e6,
             "count_per_call": count[(line, name)] / repeats, "stats": stats[(line, name)]}
            for (line, name), ns in sorted(total.items(), key=lambda kv: -kv[1])]
    return {"planes": planes, "line_ms_per_call": dict(lines), "rows": rows[:top],
            "distinct_events": len(rows)}

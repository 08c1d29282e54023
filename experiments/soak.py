"""Soak test (not CI): a checkpointed run killed with SIGKILL again and again, then resumed.

    python experiments/soak.py --minutes 60 --iterations 1400000 --every 2000 \
        --parallel-reference                           # the one-hour soak (two cores)
    python experiments/soak.py --minutes 8 --iterations 20000   # a short one

A child process runs ``minimize`` with checkpoints every ``--every`` iterations (a few seconds
on a CPU) and ``keep`` = 3; the parent kills it with SIGKILL at random moments, samples its
resident memory (``/proc/<pid>/status``) and the checkpoint folder's size, and starts it again
(it resumes from the newest intact step) until the run finishes. The final result is compared
with an unbroken run of the same settings (before the soak, or beside it on another core
with ``--parallel-reference``; each process is pinned to one core). Memory is judged per
process: a process started at iteration 1,000,000 must peak no higher than one started at 0
(the fit of peak RSS against the iteration it resumed at is reported in kB per 100,000
iterations); disk is split into the ``keep`` steps and the append-only history log. Prints
one JSON record (and writes ``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path


def child(args: argparse.Namespace) -> None:
    """Run (or resume) the soak run; write the final result as JSON."""
    import jax
    import numpy as np

    import eaco_jax as ea
    from eaco_jax.strategies.graph_eaco import GraphEACO

    if args.cpu >= 0:
        os.sched_setaffinity(0, {args.cpu})

    jax.config.update("jax_compilation_cache_dir", args.cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    problem = ea.problems.load_tsplib(args.instance)
    ck = None
    if args.dir:
        ck = ea.Checkpointing(args.dir, every=args.every, keep=args.keep)
    res = ea.minimize(problem, GraphEACO(num_ants=args.ants, local_search="none"),
                      seed=[0, 1], iterations=args.iterations, chunk_size=args.every,
                      checkpointing=ck)
    Path(args.result).write_text(json.dumps({
        "best_cost": np.asarray(res.best_cost).tolist(),
        "best_solution": np.asarray(res.best_solution).tolist(),
        "history_best": np.asarray(res.history["best_cost"]).tolist(),
        "evaluations": np.asarray(res.evaluations).tolist(),
    }))


def _rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def _disk_mb(folder: Path) -> float:
    """Bytes under ``folder`` in MiB (orbax renames folders while it writes: retry)."""
    for _ in range(5):
        try:
            total = 0
            for root, _dirs, files in os.walk(folder):
                for name in files:
                    try:
                        total += (Path(root) / name).stat().st_size
                    except FileNotFoundError:
                        continue
            return total / 2**20
        except FileNotFoundError:
            time.sleep(0.05)
    return float("nan")


def _steady(samples: list[dict], cycles: list[dict]) -> list[float] | None:
    """RSS of the last (longest-lived) process: [first, last, max] after its first quarter."""
    if not cycles:
        return None
    span = cycles[-1]["alive_s"]
    last = [x["rss_mb"] for x in samples if x["t"] >= samples[-1]["t"] - span + span / 4]
    last = [v for v in last if v > 0]
    return [last[0], last[-1], max(last)] if last else None


def _spawn(args: argparse.Namespace, directory: str, result: Path, cpu: int = -1
           ) -> subprocess.Popen:
    cmd = [sys.executable, __file__, "--child", "--dir", directory, "--result", str(result),
           "--instance", args.instance, "--ants", str(args.ants), "--iterations",
           str(args.iterations), "--every", str(args.every), "--keep", str(args.keep),
           "--cache", args.cache, "--cpu", str(cpu)]
    log = open(Path(args.work) / "child.log", "a")  # noqa: SIM115 - a file, never a full pipe
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log, text=True)


def parent(args: argparse.Namespace) -> dict:
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    ck = work / "ck"
    rng = random.Random(args.seed)
    t_start = time.time()
    # the unbroken reference (also warms the persistent compilation cache)
    ref_file = work / "unbroken.json"
    t0 = time.time()
    cpus = sorted(os.sched_getaffinity(0))
    ref = _spawn(args, "", ref_file, cpus[-1] if args.parallel_reference else -1)
    unbroken_seconds = None
    if not args.parallel_reference:
        ref.wait()
        if ref.returncode != 0:
            raise SystemExit(f"unbroken run failed: see {work / 'child.log'}")
        unbroken_seconds = time.time() - t0
    soak_cpu = cpus[0] if args.parallel_reference else -1
    t_soak = time.time()
    kills, samples, cycles = 0, [], []
    result = work / "soak.json"
    deadline = time.time() + 60 * args.minutes
    while True:
        resumed_at = max((int(p.name) for p in ck.iterdir() if p.name.isdigit()),
                         default=0) if ck.exists() else 0
        proc = _spawn(args, str(ck), result, soak_cpu)
        wait = rng.uniform(args.min_kill, args.max_kill)
        born = time.time()
        if born + wait > deadline:
            wait = float("inf")  # past the soak time: sample until the run finishes
        peak = 0.0
        while proc.poll() is None and time.time() - born < wait:
            rss = _rss_mb(proc.pid)
            if rss is not None:
                peak = max(peak, rss)
                samples.append({"t": round(time.time() - t_start, 1), "rss_mb": round(rss, 1),
                                "disk_mb": round(_disk_mb(ck), 3) if ck.exists() else 0.0})
            time.sleep(0.5)
        finished = proc.poll() is not None
        if not finished and time.time() < deadline:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            kills += 1
        elif not finished:
            proc.wait()  # past the soak time: let it finish
        if proc.returncode not in (0, -signal.SIGKILL):
            raise SystemExit(f"child failed ({proc.returncode}): see {work / 'child.log'}")
        steps = sorted(int(p.name) for p in ck.iterdir() if p.name.isdigit()) if ck.exists() \
            else []
        cycles.append({"resumed_at": resumed_at,
                       "alive_s": round(time.time() - born, 1), "peak_rss_mb": round(peak, 1),
                       "disk_mb": round(_disk_mb(ck), 3) if ck.exists() else 0.0,
                       "history_mb": round(_disk_mb(ck / "history"), 3)
                       if (ck / "history").exists() else 0.0,
                       "steps": steps, "killed": not finished})
        if result.exists():
            break
    soak_seconds = time.time() - t_soak
    if args.parallel_reference:
        ref.wait()
        if ref.returncode != 0:
            raise SystemExit(f"unbroken run failed: see {work / 'child.log'}")
        unbroken_seconds = time.time() - t0
    same = json.loads(result.read_text()) == json.loads(ref_file.read_text())
    peaks = [c["peak_rss_mb"] for c in cycles if c["peak_rss_mb"]]
    # killed processes that resumed (the first one compiles into an empty cache)
    killed = [c for c in cycles if c["killed"] and c["peak_rss_mb"] and c["resumed_at"] > 0]
    slope = None
    if len(killed) >= 3:  # peak RSS of a killed process against the iteration it started at
        import numpy as np

        x = np.array([c["resumed_at"] for c in killed], float)
        y = np.array([c["peak_rss_mb"] for c in killed], float)
        slope = float(np.polyfit(x / 1e5, y * 1024, 1)[0])
    history_dir = ck / "history"
    leftovers = [p.name for p in ck.iterdir() if "tmp" in p.name] if ck.exists() else []
    return {
        "instance": args.instance, "iterations": args.iterations, "every": args.every,
        "keep": args.keep, "minutes": args.minutes, "kills": kills, "cycles": len(cycles),
        "parallel_reference": bool(args.parallel_reference),
        "unbroken_seconds": round(unbroken_seconds, 1),
        "soak_seconds": round(soak_seconds, 1),
        "identical_to_unbroken": same,
        "peak_rss_mb_first_last_max": [peaks[0], peaks[-1], max(peaks)] if peaks else None,
        "killed_peak_rss_mb_min_max": [min(c["peak_rss_mb"] for c in killed),
                                       max(c["peak_rss_mb"] for c in killed)] if killed else None,
        "peak_rss_kb_per_100k_iterations": None if slope is None else round(slope, 1),
        "final_history_log_mb": round(_disk_mb(history_dir), 3) if history_dir.exists() else 0,
        "final_steps_mb": round(_disk_mb(ck) - (_disk_mb(history_dir)
                                                if history_dir.exists() else 0), 3),
        "last_cycle_rss_mb_after_warmup": _steady(samples, cycles),
        "max_steps_on_disk": max(len(c["steps"]) for c in cycles),
        "max_disk_mb": max(c["disk_mb"] for c in cycles),
        "tmp_leftovers_at_end": leftovers,
        "corrupt_moved_aside": len(list((ck / "corrupt").iterdir()))
        if (ck / "corrupt").exists() else 0,
        "cycle_log": cycles, "samples": samples[:: max(1, len(samples) // 200)],
    }


def plot_record(record: dict, path: Path) -> None:
    """Resident memory and checkpoint-folder size over the soak (a line per process; kills as
    ticks), from a record's samples."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [x["t"] / 60 for x in record["samples"]]
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    a.plot(t, [x["rss_mb"] or float("nan") for x in record["samples"]], ".", ms=2)
    a.set_ylabel("resident memory (MB)")
    b.plot(t, [x["disk_mb"] for x in record["samples"]], ".", ms=2)
    b.set_ylabel("checkpoint folder (MB)")
    b.set_xlabel("minutes since the start")
    a.set_title(f"soak: {record['iterations']:,} iterations, {record['kills']} SIGKILLs, "
                f"identical to unbroken: {record['identical_to_unbroken']}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0, help="kill/resume phase length")
    ap.add_argument("--instance", default="eil51")
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--iterations", type=int, default=200_000)
    ap.add_argument("--every", type=int, default=500, help="iterations between checkpoints")
    ap.add_argument("--keep", type=int, default=3)
    ap.add_argument("--min-kill", type=float, default=20.0)
    ap.add_argument("--max-kill", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work", default="out/soak")
    ap.add_argument("--out", default=None, help="write the JSON record here")
    ap.add_argument("--cache", default=None, help="persistent compilation cache folder")
    ap.add_argument("--parallel-reference", action="store_true",
                    help="run the unbroken reference beside the soak (pinned to another core)")
    ap.add_argument("--cpu", type=int, default=-1, help=argparse.SUPPRESS)
    ap.add_argument("--plot", default=None, metavar="RECORD.json",
                    help="only draw RECORD.png from a stored record")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--dir", default="", help=argparse.SUPPRESS)
    ap.add_argument("--result", default="", help=argparse.SUPPRESS)
    args = ap.parse_args()
    args.cache = args.cache or str(Path(args.work).absolute() / "jax-cache")
    if args.plot:
        plot_record(json.loads(Path(args.plot).read_text()), Path(args.plot).with_suffix(".png"))
        return
    if args.child:
        child(args)
        return
    record = parent(args)
    text = json.dumps(record)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text + "\n")
        plot_record(record, Path(args.out).with_suffix(".png"))
    summary = {k: v for k, v in record.items() if k not in ("cycle_log", "samples")}
    print(json.dumps(summary))
    os._exit(0)


if __name__ == "__main__":
    main()

"""SIGKILL a checkpointing run at random moments (also mid-write), resume it, compare bit for bit.

The run lives in a subprocess; it is killed either at a random time or the moment orbax starts
writing a checkpoint (a ``*.orbax-checkpoint-tmp-*`` folder appears), then started again with the
same arguments, which resumes from the newest complete checkpoint. The resumed result (best
cost, best solution, final PRNG key and the full history) must equal an unbroken run's.
"""

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

TESTS = Path(__file__).parent

SCRIPT = """
import sys
import jax, jax.numpy as jnp, numpy as np
from test_driver import RandomSearch, Sphere
import eaco_jax as ea

out, ck = sys.argv[1], sys.argv[2]
res = ea.minimize(Sphere(lower=-jnp.ones(4), upper=jnp.ones(4)), RandomSearch(num_ants=16),
                  seed=[3, 4], iterations=60, chunk_size=3,
                  checkpointing=ea.Checkpointing(ck, every=3, keep=2))
np.savez(out, best_cost=res.best_cost, best_solution=res.best_solution,
         key=jax.random.key_data(res.state.key), iterations=res.iterations,
         **{"h_" + k: v for k, v in res.history.items()})
"""


def _env() -> dict:
    env = dict(os.environ, JAX_PLATFORMS="cpu", PYTHONPATH=f"{TESTS}{os.pathsep}"
               + os.environ.get("PYTHONPATH", ""))
    env.pop("XLA_FLAGS", None)
    return env


def _start(out: Path, ck: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", SCRIPT, str(out), str(ck)], env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _finish(out: Path, ck: Path) -> dict:
    proc = _start(out, ck)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err.decode()[-2000:]
    return dict(np.load(out))


def _writing(ck: Path) -> bool:
    try:
        return any(".orbax-checkpoint-tmp" in name for name in os.listdir(ck))
    except FileNotFoundError:
        return False


def _kill_and_resume(
    tmp: Path, trial: int, mid_write: bool, window: float, rng: random.Random
) -> tuple[dict, str]:
    ck, out = tmp / f"ck{trial}", tmp / f"out{trial}.npz"
    # Retry until the kill lands in the wanted phase: a loaded machine may finish the run first,
    # or a write may begin between the last look and the signal. The phase is read after the
    # kill, from the disk: an unfinished orbax temp folder stays behind only if a write was cut.
    for _attempt in range(12):
        shutil.rmtree(ck, ignore_errors=True)
        out.unlink(missing_ok=True)
        proc = _start(out, ck)
        while not ck.exists() and proc.poll() is None:  # interpreter + JAX start-up
            time.sleep(0.005)
        if mid_write:  # wait for the n-th checkpoint write to begin, kill inside it
            n, seen = rng.randint(1, 6), 0
            while proc.poll() is None and seen < n:
                while proc.poll() is None and not _writing(ck):
                    time.sleep(0.001)
                seen += 1
                if seen < n:
                    while proc.poll() is None and _writing(ck):
                        time.sleep(0.001)
        else:  # a random moment outside a write: while computing a chunk or between chunks
            time.sleep(rng.uniform(0.0, window))
            while proc.poll() is None and _writing(ck):
                time.sleep(0.001)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        during_write = _writing(ck)
        if proc.returncode == -signal.SIGKILL and during_write == mid_write:
            break
        if proc.returncode != -signal.SIGKILL:
            window *= 0.5
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    assert during_write == mid_write, "no kill landed in the wanted phase in 12 tries"
    assert not out.exists()
    steps = sorted(int(p) for p in os.listdir(ck) if p.isdigit()) if ck.exists() else []
    got = _finish(out, ck)
    return got, f"trial {trial}: killed {'mid-write' if during_write else 'between writes'}" \
        f" with complete steps {steps[-2:]}"


def _trials(tmp_path: Path, n: int) -> list[str]:
    rng = random.Random(1234 + n)
    out, ck = tmp_path / "ref.npz", tmp_path / "ref_ck"
    proc = _start(out, ck)
    while not ck.exists() and proc.poll() is None:
        time.sleep(0.005)
    t0 = time.perf_counter()
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err.decode()[-2000:]
    window = 0.7 * (time.perf_counter() - t0)  # kill times: within the run's working phase
    ref = dict(np.load(out))
    assert int(ref["iterations"]) == 60
    notes = []
    for trial in range(n):
        got, note = _kill_and_resume(tmp_path, trial, trial % 2 == 0, window, rng)
        assert got.keys() == ref.keys()
        for k in ref:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=f"{note}: {k}")
        notes.append(note)
    print("\n".join(notes))
    assert any("mid-write" in n for n in notes)
    assert any("between writes" in n for n in notes)
    return notes


def test_sigkill_resume_identical_ci(tmp_path):
    _trials(tmp_path, 2)


@pytest.mark.slow
def test_sigkill_resume_identical_10_of_10(tmp_path):
    notes = _trials(tmp_path, 10)
    assert len(notes) == 10

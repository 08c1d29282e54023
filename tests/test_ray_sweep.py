"""The Ray backend on a local two-worker Ray instance gives the local sweep's table.

One worker is killed (SIGKILL, after its cell's run and checkpoint) the first time any cell
finishes; Ray retries that task, the cell resumes from its checkpoint, and the table is still
the same as the local one.
"""

import json
import os
import signal
from pathlib import Path

import pytest

ray = pytest.importorskip("ray")

from eaco_jax import sweep as sw  # noqa: E402

TESTS = Path(__file__).parent


def _dying_metrics(built, result, row):
    """test_sweep's toy metrics; the first finished cell kills its own worker process once."""
    from test_sweep import _metrics

    marker = os.environ.get("EACO_TEST_DIE_ONCE")
    if marker and row == 0:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            pass
        else:
            os.close(fd)
            os.kill(os.getpid(), signal.SIGKILL)
    return _metrics(built, result, row)


def _dying_kind():
    import dataclasses

    from test_sweep import TOY

    return dataclasses.replace(TOY, row_metrics=_dying_metrics)


DYING = _dying_kind()

SPEC = {
    "name": "toy-ray",
    "kind": "test_ray_sweep:DYING",
    "args": {"iterations": 10},
    "seeds": 2,
    "grid": {"scale": [0.25, 1.0]},
    "checkpoint_every": 5,
}


def test_ray_sweep_equals_local_sweep(tmp_path):
    local = sw.run_sweep(SPEC, tmp_path / "local")
    assert local["groups"] == 1
    marker = tmp_path / "died"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {
                 "PYTHONPATH": f"{TESTS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
                 "JAX_PLATFORMS": "cpu", "EACO_TEST_DIE_ONCE": str(marker)}})
    try:
        remote = sw.run_sweep(SPEC, tmp_path / "ray", backend="ray")
    finally:
        ray.shutdown()
    assert marker.exists(), "no worker was killed: the retry path was not exercised"
    a = json.loads((tmp_path / "local" / "table.json").read_text())
    b = json.loads((tmp_path / "ray" / "table.json").read_text())
    assert a == b
    assert (tmp_path / "local" / "table.csv").read_text() == (
        tmp_path / "ray" / "table.csv").read_text()
    assert remote["runs"] == local["runs"] == 4
    # every Ray cell left its checkpoint (the retried one resumed from it)
    assert len(list((tmp_path / "ray" / "checkpoints").iterdir())) == 2

"""Ctrl-C / SIGTERM: one line, a final checkpoint and how to resume; no traceback."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

CMD = [sys.executable, "-m", "eaco_jax", "--no-compile-cache", "tsp", "burma14", "--ants", "8",
       "--iterations", "200000", "--local-search", "none", "--quiet"]


def _wait_for(predicate, seconds: float = 240.0) -> None:
    end = time.time() + seconds
    while not predicate():
        if time.time() > end:
            raise AssertionError("timed out")
        time.sleep(0.2)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_checkpointed_run_saves_and_says_how_to_resume(tmp_path, sig):
    ck = tmp_path / "ck"
    proc = subprocess.Popen([*CMD, "--checkpoint-dir", str(ck), "--checkpoint-every", "50"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: any(p.name.isdigit() for p in ck.glob("*")))
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert f"interrupted ({sig.name})" in lines[0] and f"eaco resume {ck}" in lines[0]
    step = int(lines[0].split("checkpoint saved at step ")[1].split()[0])
    assert (ck / str(step)).is_dir() and not list(ck.glob("*orbax-checkpoint-tmp*"))


def test_second_run_on_the_same_folder_is_refused(tmp_path):
    ck = tmp_path / "ck"
    first = subprocess.Popen([*CMD, "--checkpoint-dir", str(ck), "--checkpoint-every", "50"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: (ck / ".lock").exists() and (ck / ".lock").read_text())
        second = subprocess.run([*CMD, "--checkpoint-dir", str(ck)], capture_output=True,
                                text=True, timeout=240)
        assert second.returncode == 2
        assert second.stderr.strip().startswith("error: checkpoint folder") and (
            "in use by another run (pid" in second.stderr), second.stderr
        assert len(second.stderr.strip().splitlines()) == 1
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=120)
    assert first.returncode == 130


def test_out_pointing_at_a_file_is_refused_before_the_run(tmp_path):
    target = tmp_path / "result.json"
    target.write_text("{}")
    res = subprocess.run([*CMD[:-5], "--iterations", "5", "--out", str(target)],
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 2 and "is an existing file" in res.stderr
    assert Path(target).read_text() == "{}"

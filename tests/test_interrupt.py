"""Ctrl-C / SIGTERM: one line, a final checkpoint and how to resume; no traceback."""

from __future__ import annotations

import os
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
    assert len(lines) == 2 and "Traceback" not in err, err
    assert lines[0].startswith(f"{sig.name}: stopping after the current chunk (iteration ")
    assert f"interrupted ({sig.name})" in lines[1] and f"eaco resume {ck}" in lines[1]
    step = int(lines[1].split("checkpoint saved at step ")[1].split()[0])
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


def test_first_sigterm_during_a_long_chunk_says_so_at_once(tmp_path):
    """The first SIGTERM in the middle of a chunk of seconds prints one line at once (not when
    the chunk ends), then the run stops at the chunk's end with its checkpoint."""
    ck = tmp_path / "ck"
    cmd = [*CMD[:8], "--iterations", "4000000", *CMD[10:], "--checkpoint-dir", str(ck),
           "--checkpoint-every", "40000"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: (ck / "40000").is_dir())
        t0 = time.time()
        proc.send_signal(signal.SIGTERM)
        first = proc.stderr.readline()
        said = time.time() - t0
        rest = proc.communicate(timeout=120)[1]
        ended = time.time() - t0
    finally:
        proc.kill()
    assert proc.returncode == 130
    step = int(first.split("(iteration ")[1].split(")")[0])
    assert first == (f"SIGTERM: stopping after the current chunk (iteration {step}); send "
                     "again to stop now\n")
    assert step > 40000 and (ck / str(step)).is_dir()
    assert rest.strip().startswith(f"interrupted (SIGTERM) after {step} of 4000000")
    assert said < 1.0 and said < ended / 2, (said, ended)  # at once; the chunk ran on


_INTERRUPT_AT_IMPORT = """
import os, signal, sys
sys.argv = ["eaco", "--version"]


class InterruptAt:  # Ctrl-C exactly when `{module}` starts importing
    def find_spec(self, name, path=None, target=None):
        if name == "{module}":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None


sys.meta_path.insert(0, InterruptAt())
from eaco_jax.cli import main
main()
"""


@pytest.mark.parametrize("module", ["jax", "typer"])
def test_ctrl_c_while_the_command_imports_is_one_line(module):
    """Ctrl-C while `eaco` still imports (jax inside the package, typer inside the CLI): the
    line 'interrupted' and exit 130, no KeyboardInterrupt traceback."""
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    proc = subprocess.run([sys.executable, "-c", _INTERRUPT_AT_IMPORT.format(module=module)],
                          capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 130, proc.stderr[-2000:]
    assert proc.stderr.strip() == "interrupted", proc.stderr[-2000:]
    assert proc.stdout == ""

"""Test-session setup: each pytest-xdist worker keeps its own JAX compilation cache.

The CLI turns on JAX's persistent compilation cache (``$EACO_COMPILE_CACHE`` or
``~/.cache/eaco_jax/jax``). Two workers compiling the same program at the same moment then
read and write the same cache entry, and JAX's cache has crashed the worker doing so (a
segfault reading, an abort writing, in tests/test_islands.py). One folder per worker and per
session keeps the workers apart; a test that sets ``EACO_COMPILE_CACHE`` itself still wins.
"""

from __future__ import annotations

import os
import tempfile

_worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
os.environ["EACO_COMPILE_CACHE"] = tempfile.mkdtemp(prefix=f"eaco-jax-cache-{_worker}-")

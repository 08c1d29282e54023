"""Suite-wide fixtures."""

import gc

import jax
import pytest

from eaco_jax.driver.programs import clear_compiled


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Free every compiled program after each test module. An xdist worker runs hundreds of
    tests in one process, and each XLA:CPU executable it keeps holds memory maps of its own:
    kept alive, they reached Linux's vm.max_map_count (65,530) and the worker died in XLA
    (a segfault or abort while compiling or serialising) far from the test that used them."""
    yield
    clear_compiled()
    jax.clear_caches()
    gc.collect()

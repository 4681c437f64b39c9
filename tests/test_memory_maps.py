"""The test processes' guard against running out of memory maps (conftest.release_compiled_programs):
every program XLA:CPU compiles holds memory maps while it is cached, and a worker past
vm.max_map_count crashes in its next compilation (docs/testing.md)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import max_map_count, memory_maps, release_compiled_programs


def test_release_compiled_programs_frees_the_maps_of_compiled_programs():
    if max_map_count() is None or memory_maps() == 0:
        pytest.skip("no /proc/self/maps or vm.max_map_count on this system")
    fs = [jax.jit(lambda x, i=i: jnp.sin(x) * i + jnp.cumsum(x)) for i in range(40)]
    before = memory_maps()
    for i, f in enumerate(fs):  # NumPy inputs: the jitted functions are the only programs compiled
        f(np.arange(8.0 + i)).block_until_ready()
    grown = memory_maps()
    assert grown - before >= 3 * len(fs)  # each compiled program holds its own memory maps
    assert not release_compiled_programs(limit=10 * grown)  # well below the limit: kept
    assert memory_maps() >= grown
    assert release_compiled_programs(limit=grown)  # above half of it: released
    assert memory_maps() < grown - 2 * len(fs)
    assert float(fs[1](jnp.arange(9.0))[2]) == pytest.approx(float(jnp.sin(2.0) + 3.0))  # compiles again

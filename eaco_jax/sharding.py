"""Split a colony's evaluation across devices (GPUs, or CPU devices in tests).

The colony's ask/tell are cheap and stay replicated; evaluating the ants (an MJX rollout per
ant, say) is what needs several accelerators. :class:`Sharded` wraps any problem so that its
``evaluate`` runs under ``jax.shard_map`` with the ant axis split over a 1-D device mesh: each
device rolls out ``num_ants / num_devices`` ants, results are gathered back. The wrapped problem
is still a pytree problem, so ``minimize`` runs it inside the same jitted ``lax.scan``.

The number of ants must be a multiple of the number of devices (a clear error says so).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax
import numpy as np
from flax import struct
from jax.sharding import Mesh
from jax.sharding import PartitionSpec as P

AXIS = "ants"


def ant_mesh(devices: Sequence[jax.Device] | None = None) -> Mesh:
    """A 1-D mesh over ``devices`` (default: every local device) named ``"ants"``."""
    devices = list(jax.local_devices() if devices is None else devices)
    if not devices:
        raise ValueError("ant_mesh needs at least one device")
    return Mesh(np.array(devices), (AXIS,))


@struct.dataclass
class Sharded:
    """``problem`` with its ``evaluate`` split over ``mesh`` along the ant axis."""

    problem: Any
    mesh: Mesh = struct.field(pytree_node=False)

    @property
    def kind(self) -> str:
        return self.problem.kind

    @property
    def name(self) -> str:
        return self.problem.name

    @property
    def num_devices(self) -> int:
        return self.mesh.devices.size

    def __getattr__(self, attr: str) -> Any:
        # bounds, optimum, ... of the wrapped problem stay reachable
        if attr in {"problem", "mesh"}:
            raise AttributeError(attr)
        return getattr(self.problem, attr)

    def evaluate(self, solutions: jax.Array) -> Any:
        m = solutions.shape[0]
        if m % self.num_devices:
            k = self.num_devices
            raise ValueError(
                f"{m} ants cannot be split evenly over {k} devices; "
                f"use a multiple of {k} ants (e.g. {k * -(-m // k)})"
            )
        problem = self.problem

        def local(problem_local: Any, x: jax.Array) -> Any:
            return problem_local.evaluate(x)

        fn = jax.shard_map(
            local,
            mesh=self.mesh,
            in_specs=(P(), P(AXIS)),
            out_specs=P(AXIS),
            check_vma=False,
        )
        return fn(problem, solutions)


def shard(problem: Any, devices: Sequence[jax.Device] | None = None) -> Sharded:
    """Wrap ``problem`` so its colony evaluation is split over ``devices`` (default: all)."""
    return Sharded(problem=problem, mesh=ant_mesh(devices))

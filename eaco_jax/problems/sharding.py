"""Split a colony's evaluation across devices (GPUs, or CPU devices in tests).

The colony's ask/tell are cheap and stay replicated; evaluating the ants (an MJX rollout per
ant, say) is what needs several accelerators. :class:`Sharded` wraps any problem so that its
``evaluate`` sees the colony constrained to be split along the ant axis over a 1-D device mesh
(``with_sharding_constraint``); XLA's partitioner then runs each device's share of the vmapped
rollout there and gathers the results for ``tell``. The wrapped problem is still a pytree
problem, so ``minimize`` runs it inside the same jitted ``lax.scan``.

(It constrains the sharding rather than running an explicit ``jax.shard_map`` of the MJX
rollout, which crashed on two GPUs under jax 0.11.2; the constraint form runs there: claim
``gait-two-gpu-speedup``.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np
from flax import struct
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from eaco_jax.errors import ConfigError

AXIS = "ants"


def ant_mesh(devices: Sequence[jax.Device] | None = None) -> Mesh:
    """A 1-D mesh over ``devices`` (default: every local device) named ``"ants"``."""
    devices = list(jax.local_devices() if devices is None else devices)
    if not devices:
        raise ConfigError("ant_mesh needs at least one device")
    return Mesh(np.array(devices), (AXIS,))


@struct.dataclass
class Sharded:
    """``problem`` with its ``evaluate`` split over ``mesh`` along the ant axis."""

    problem: Any
    mesh: Mesh = struct.field(pytree_node=False)

    @property
    def kind(self) -> str:
        """The wrapped problem's kind."""
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
        split = NamedSharding(self.mesh, P(AXIS))
        return self.problem.evaluate(jax.lax.with_sharding_constraint(solutions, split))


def shard(problem: Any, devices: Sequence[jax.Device] | None = None) -> Sharded:
    """Wrap ``problem`` so its colony evaluation is split over ``devices`` (default: all)."""
    return Sharded(problem=problem, mesh=ant_mesh(devices))


# --------------------------------------------------------------------------- island axis
# (strategies.islands shards its island axis with these: the same constraint form)
ISLANDS = "islands"


def island_mesh(islands: int, num_devices: int | None = None) -> Mesh:
    """A 2-D mesh ``("islands", "ants")`` over the first ``num_devices`` of *all* devices.

    Its ``"islands"`` axis has ``gcd(islands, devices)`` entries, so a state with ``islands``
    rows splits evenly over it (jit outputs cannot be split unevenly) and is replicated over
    ``"ants"``; a colony's ant axis is split over both axes, i.e. every device. With
    ``islands`` a multiple of the device count, every device holds ``islands / devices``
    islands. ``jax.devices()`` spans every process after ``jax.distributed.initialize``, so
    the mesh covers every host.
    """
    devices = jax.devices()
    if num_devices is not None:
        if not 1 <= num_devices <= len(devices):
            raise ConfigError(f"num_devices={num_devices} is not in 1..{len(devices)} "
                              f"(the devices JAX sees)")
        devices = devices[:num_devices]
    groups = math.gcd(int(islands), len(devices))
    return Mesh(np.array(devices).reshape(groups, -1), (ISLANDS, AXIS))


def split_leading(tree: Any, mesh: Mesh, axes: str | tuple[str, ...]) -> Any:
    """Constrain every array leaf of ``tree`` to be split along its first axis over the mesh
    axes ``axes`` (scalars: whole). Under ``vmap`` the batch axis stays unsplit."""
    split, whole = NamedSharding(mesh, P(axes)), NamedSharding(mesh, P())

    def one(x: Any) -> Any:
        return jax.lax.with_sharding_constraint(x, split if x.ndim else whole)

    return jax.tree.map(one, tree)


def replicated(tree: Any, mesh: Mesh) -> Any:
    """Constrain every leaf of ``tree`` to be whole on every device of ``mesh`` (what the
    host reads back each chunk: best-so-far, metrics; fetchable on every host)."""
    whole = NamedSharding(mesh, P())
    return jax.tree.map(lambda x: jax.lax.with_sharding_constraint(x, whole), tree)

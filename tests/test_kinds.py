"""One way to declare what a strategy solves and what a problem is: a ``ClassVar[str]`` class
constant on every concrete class (``problem_kind`` / ``kind``); a read-only property only on a
wrapper whose kind is its inner object's, the form the base (``Strategy.problem_kind``,
``Problem.kind``) declares. See ARCHITECTURE.md, "How to add"."""

from __future__ import annotations

import dataclasses

import pytest

from eaco_jax import strategies
from eaco_jax.problems import registry
from eaco_jax.problems.base import Problem
from eaco_jax.problems.sharding import Sharded, shard
from eaco_jax.strategies.base import Strategy
from eaco_jax.strategies.islands import Islands

KINDS = {"graph", "path", "continuous", "multiobjective", "qd"}
#: arguments for the registered problem families whose factory needs some
FAMILY_ARGS = {"tsp": {"name_or_path": "eil51"}, "cec2006": {"name": "g06"}}


def declaration(cls: type, name: str) -> tuple[type | None, str]:
    """The class of ``cls``'s MRO that declares ``name``, and how: ``classvar``, ``property``,
    ``field`` (a dataclass field), ``attribute`` (unannotated) or another annotation."""
    for owner in cls.__mro__:
        if name not in vars(owner):
            continue
        if isinstance(vars(owner)[name], property):
            return owner, "property"
        if dataclasses.is_dataclass(owner) and name in {f.name for f in
                                                         dataclasses.fields(owner)}:
            return owner, "field"
        note = vars(owner).get("__annotations__", {}).get(name)
        if note is None:
            return owner, "attribute"
        text = note if isinstance(note, str) else repr(note)
        return owner, "classvar" if text.replace("typing.", "").startswith("ClassVar[") else text
    return None, "missing"


@pytest.mark.parametrize("name", strategies.names())
def test_every_registered_strategy_declares_problem_kind_as_a_class_constant(name):
    cls = type(strategies.get(name))
    owner, how = declaration(cls, "problem_kind")
    assert how == "classvar" and owner is not Strategy, (cls.__name__, owner, how)
    assert cls.problem_kind in KINDS


def test_the_strategy_wrapper_delegates_through_the_bases_property():
    assert declaration(Strategy, "problem_kind") == (Strategy, "property")
    assert declaration(Islands, "problem_kind") == (Islands, "property")
    for name in ("eaco", "pso", "path-eaco"):
        inner = strategies.get(name)
        assert Islands(inner, islands=2).problem_kind == inner.problem_kind


def _problems():
    return [registry.get(family, **FAMILY_ARGS.get(family, {}))
            for family in registry.families()]


def test_every_registered_problem_declares_kind_as_a_class_constant():
    seen = set()
    for problem in _problems():
        owner, how = declaration(type(problem), "kind")
        assert how == "classvar", (type(problem).__name__, owner, how)
        assert problem.kind in KINDS
        seen.add(problem.kind)
        assert shard(problem).kind == problem.kind
    assert seen == KINDS


def test_the_problem_wrapper_delegates_through_the_protocols_property():
    assert declaration(Problem, "kind") == (Problem, "property")
    assert declaration(Sharded, "kind") == (Sharded, "property")

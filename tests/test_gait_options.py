"""``runs/gait.py`` repeats the gait problem's option lists (so ``eaco --help`` imports no
physics); these tests tie each list of choices, and each option named only in a help text, to
the values the library accepts, so neither can drift."""

from __future__ import annotations

import dataclasses
import re

import pytest

from eaco_jax.gait import fitness, walk_engine, worlds
from eaco_jax.ops import constraints
from eaco_jax.problems import gait as problem
from eaco_jax.runs import gait as runs

#: Settings field -> the values the library accepts for it
ACCEPTED = {
    "backend": problem.BACKENDS,
    "impl": problem.IMPLS,
    "aggregate": fitness.AGGREGATES,
    "ik": walk_engine.IK_CHOICES,
    "constraint_method": constraints.METHODS,
    "stream": tuple(worlds.STREAMS),
}
#: (Settings class, field) -> accepted values, for fields whose choices only the help names
IN_HELP = {
    (runs.GaitSettings, "turn"): fitness.TURNS,
    (runs.GaitSettings, "penalty"): problem.PENALTIES,
    (runs.GaitEvalSettings, "ik"): walk_engine.IK_CHOICES,
}
SETTINGS = (runs.GaitSettings, runs.GaitEvalSettings)


@pytest.mark.parametrize("settings", SETTINGS, ids=lambda s: s.__name__)
def test_every_list_of_choices_is_what_the_problem_accepts(settings):
    listed = {f.name: f.metadata["choices"] for f in dataclasses.fields(settings)
              if f.metadata.get("choices")}
    assert listed, settings
    for name, choices in listed.items():
        assert name in ACCEPTED, f"{settings.__name__}.{name}: tie its choices to the library"
        assert sorted(choices) == sorted(ACCEPTED[name]), (settings.__name__, name)


@pytest.mark.parametrize("key", list(IN_HELP), ids=lambda k: f"{k[0].__name__}.{k[1]}")
def test_choices_named_in_a_help_text_are_the_accepted_ones(key):
    settings, name = key
    field = {f.name: f for f in dataclasses.fields(settings)}[name]
    help_text = field.metadata["help"]
    named = set(re.findall(r"[a-z]+", help_text))
    accepted = {v for v in IN_HELP[key] if v is not None}
    assert accepted <= named, (settings.__name__, name, help_text)


def test_the_module_constants_are_the_problems():
    """The run module's own copies (it imports no physics for ``--help``)."""
    assert runs.BACKENDS == problem.BACKENDS
    assert runs.IMPLS == problem.IMPLS
    assert sorted(runs.AGGREGATES) == sorted(fitness.AGGREGATES)
    assert runs.IK_CHOICES == walk_engine.IK_CHOICES
    assert runs.CONSTRAINT_METHODS == constraints.METHODS
    assert sorted(runs.STREAM_NAMES) == sorted(worlds.STREAMS)

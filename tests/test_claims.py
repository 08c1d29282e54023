"""The claims manifest: it loads, every stated figure is its file's, and every measured number
in README.md and the hand-written docs/ cites a claim."""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


claims = _module(ROOT / "experiments" / "claims.py", "claims")
CLAIMS = claims.load()


def test_manifest_loads_with_unique_ids_and_honest_seed_fields():
    ids = [c.id for c in CLAIMS]
    assert len(ids) == len(set(ids)) and len(ids) >= 30
    for c in CLAIMS:
        assert c.select_seeds.strip() and c.report_seeds.strip(), c.id
        assert set(claims.provenance(c)) == set(claims.PROVENANCE), c.id


def test_every_stated_figure_is_its_files():
    assert claims.check(CLAIMS) == []


def test_a_changed_figure_is_caught(tmp_path):
    text = claims.MANIFEST.read_text().replace("value = 86\n", "value = 87\n", 1)
    (tmp_path / "claims.toml").write_text(text)
    bad = claims.check(claims.load(tmp_path / "claims.toml"))
    assert len(bad) == 1 and bad[0].startswith("soak-kills: stated 87")


def test_duplicate_id_is_refused(tmp_path):
    text = claims.MANIFEST.read_text().replace('id = "soak-identical"', 'id = "soak-kills"')
    (tmp_path / "claims.toml").write_text(text)
    with pytest.raises(claims.ManifestError, match="appears twice"):
        claims.load(tmp_path / "claims.toml")


def test_holm_adjustment():
    assert claims.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])


def _docs() -> list[Path]:
    return [ROOT / "README.md"] + sorted(
        p for p in (ROOT / "docs").glob("*.md") if p.name not in claims.GENERATED_DOCS)


@pytest.mark.parametrize("path", _docs(), ids=lambda p: p.name)
def test_every_measured_number_cites_a_claim(path):
    assert claims.unresolved(path.read_text(), CLAIMS) == []


def test_the_number_rule():
    text = "\n\n".join([
        "Runs 3.1 s on eil51.",                                    # a measured number, no id
        "Takes `--horizon 4` and writes `out/4.json`; Python 3.11.",  # code, versions: exempt
        "Reaches 426 [demo](docs/results.md#demo-eil51-200).",     # cited, figure shown
        "Reaches 425 [demo](docs/results.md#demo-eil51-200).",     # cited, figure not shown
        "| eil51 | 0.5 |",                                         # a bare number in a table
        "About 9% [x](results.md#no-such-claim).",                 # an unknown id
    ])
    problems = claims.unresolved(text, CLAIMS)
    assert len(problems) == 4
    for problem, start in zip(problems, ("['3.1 s'] without", "none of ['demo-eil51-200']",
                                         "['0.5'] without", "unknown claim id"), strict=True):
        assert problem.startswith(start), problem


def test_every_colony_default_row_names_a_claim():
    from eaco_jax.runs.tsp import (
        COLONY_DEFAULTS,
        GPU_ALLOCATOR_CLAIM,
        LS_FOCUS_CLAIM,
        SPARSE_DEFAULTS,
    )

    ids = {c.id for c in CLAIMS}
    assert COLONY_DEFAULTS and all(row.claim in ids for row in COLONY_DEFAULTS)
    assert SPARSE_DEFAULTS and all(row.claim in ids for row in SPARSE_DEFAULTS)
    assert all(row.from_claim in ids for row in SPARSE_DEFAULTS if row.from_cities)
    assert all(band.claim in ids for row in SPARSE_DEFAULTS for band in row.ants)
    assert all(band.claim in ids for row in SPARSE_DEFAULTS for band in row.paces)
    assert any(row.paces for row in SPARSE_DEFAULTS)
    assert LS_FOCUS_CLAIM in ids and GPU_ALLOCATOR_CLAIM in ids


def test_every_measured_default_names_a_claim():
    """The construction plan per backend, the kernel's block size and the heading controller's
    defaults cite existing claims."""
    from eaco_jax.ops.construction import AUTO_PLANS
    from eaco_jax.ops.construction_kernel import BLOCK_CLAIM

    ids = {c.id for c in CLAIMS}
    from eaco_jax.gait.steer import DEFAULTS_CLAIM

    cited = [row.claim for row in AUTO_PLANS] + [BLOCK_CLAIM, DEFAULTS_CLAIM]
    assert AUTO_PLANS and [c for c in cited if c not in ids] == []


def test_generated_results_and_headline_table_are_current():
    gen = _module(ROOT / "docs" / "generate.py", "generate")
    assert (ROOT / "docs" / "results.md").read_text() == gen.results_md() + "\n", "make docs"
    assert gen.headline_table() in (ROOT / "README.md").read_text(), "make docs"


def test_every_shipped_walk_library_names_existing_claims():
    """A shipped gait library's planning entry and the controller settings it chose for itself
    name the claims that measured them."""
    import json

    ids = {c.id for c in CLAIMS}
    named = []
    for f in sorted((ROOT / "eaco_jax" / "data" / "walk_gaits").glob("*.json")):
        data = json.loads(f.read_text())
        plan = data.get("planning") or {}
        named += [plan[k] for k in ("speed_claim", "yaw_claim") if k in plan]
        named += list((data.get("controller") or {}).get("claims", {}).values())
    assert len(named) >= 5 and not set(named) - ids, set(named) - ids

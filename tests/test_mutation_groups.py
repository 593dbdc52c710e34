"""The mutation groups (`mutation/run.py`) cover the whole package: every module of nuparquet/ is mutated by exactly
one group (a package's `__init__.py` that defines no function or class has nothing mutmut mutates), every pattern
and test a group names exists, the groups that reuse cached conversions mutate nothing a conversion runs, and every
hand-made mutant (`mutation/hand_mutants.toml`) still applies to the code."""

from __future__ import annotations

import importlib.util
import sys
from collections import Counter
from pathlib import Path

import pytest

from test_architecture import _graph

REPO = Path(__file__).resolve().parent.parent


def _load(name: str):
    """A module of mutation/ (not a package: the runner is run as a script)."""
    folder = str(REPO / "mutation")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    spec = importlib.util.spec_from_file_location(name, REPO / "mutation" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)
    spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="module")
def runner():
    return _load("run")


def _dotted(path: str) -> str:
    return path.removesuffix(".py").replace("/", ".").removesuffix(".__init__")


def test_every_module_is_in_exactly_one_group(runner):
    counts = Counter(m for group in runner.GROUPS for m in runner.group_modules(group))
    modules = [m for m in runner.package_modules() if not runner.nothing_to_mutate(REPO / m)]
    assert [m for m in modules if counts[m] == 0] == [], "modules of nuparquet/ in no mutation group"
    assert sorted(m for m, n in counts.items() if n > 1) == [], "modules in more than one mutation group"
    assert set(counts) <= set(modules)
    assert len(modules) > 200  # the whole package, not an empty tree


def test_only_init_files_without_code_are_exempt(runner, tmp_path):
    exempt = [m for m in runner.package_modules() if runner.nothing_to_mutate(REPO / m)]
    assert exempt and all(m.endswith("__init__.py") for m in exempt)
    lazy = tmp_path / "__init__.py"
    lazy.write_text('"""A front door."""\n\ndef __getattr__(name):\n    return name\n')
    assert not runner.nothing_to_mutate(lazy)  # a lazy front door has code: it belongs to a group
    lazy.write_text('"""Names."""\n\nfrom os import path\n\n__all__ = ["path"]\n')
    assert runner.nothing_to_mutate(lazy)


def test_every_pattern_matches_and_every_selected_test_exists(runner):
    for name, group in runner.GROUPS.items():
        for pattern in group.modules:
            assert list(REPO.glob(pattern.lstrip("!"))), f"{name}: {pattern} matches nothing"
        for test in group.tests:
            file, _, function = test.partition("::")
            assert (REPO / file).exists(), f"{name}: {file} does not exist"
            if function:
                assert f"def {function}(" in (REPO / file).read_text(), f"{name}: no test {test}"


def test_groups_that_reuse_cached_conversions_mutate_nothing_a_conversion_runs(runner):
    """A conversion made once by the unmutated first run would hide the mutants of any module it runs. The
    closure follows every import (function-level ones too) from nuparquet.conversion, except into the front door
    `nuparquet`, whose names load on first use (the conversion takes only `__version__` from it)."""
    graph = _graph()
    reached, stack = set(), [m for m in graph if m.startswith("nuparquet.conversion")]
    while stack:
        module = stack.pop()
        if module not in reached and module != "nuparquet":
            reached.add(module)
            stack += graph[module]
    assert "nuparquet.sources.tables" in reached and "nuparquet.engine.run" in reached
    for name, group in runner.GROUPS.items():
        if group.cache_conversions:
            assert sorted({_dotted(m) for m in runner.group_modules(name)} & reached) == [], name


def test_every_hand_mutant_applies_to_the_code_and_names_its_reason():
    hand = _load("hand")
    mutants = hand.load()  # checks: unique names, known groups, the original text found once in its file
    groups = Counter(m["group"] for m in mutants)
    for m in mutants:
        assert m["original"] != m["replacement"] and m["why"].strip() and m["kind"].strip(), m["name"]
    first_runs = {"geometry", "projection", "reader", "builders", "mosaic", "video"}  # mutated since 2026-11-24
    assert {g: groups[g] for g in _load("run").GROUPS if g not in first_runs and groups[g] < 3} == {}

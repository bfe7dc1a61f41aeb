"""Run the doctests of every installed trackfw module (small maths is documented by example)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import trackfw
import trackfw_plugins


def _modules() -> list[str]:
    names = []
    for package in (trackfw, trackfw_plugins):
        for info in pkgutil.walk_packages(package.__path__, prefix=f"{package.__name__}."):
            names.append(info.name)
    return sorted(names)


@pytest.mark.parametrize("name", _modules())
def test_doctests(name: str) -> None:
    try:
        module = importlib.import_module(name)
    except ImportError as error:  # optional extras (torch) are not installed everywhere
        pytest.skip(f"{name}: optional dependency missing ({error})")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    assert result.failed == 0, f"{result.failed} doctest(s) failed in {name}"

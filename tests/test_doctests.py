"""The examples in the docstrings run, and say what the code does (doctest)."""

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("daq", "dbc", "estimator", "sim_bridge")


def modules_with_examples() -> list[str]:
    """Every module of the packages whose source holds a ``>>>`` example."""
    names = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.name == "__main__.py" or ">>> " not in path.read_text(encoding="utf-8"):
                continue
            module = path.relative_to(ROOT).with_suffix("").as_posix().replace("/", ".")
            names.append(module.removesuffix(".__init__"))
    return names


@pytest.mark.parametrize("name", modules_with_examples())
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"

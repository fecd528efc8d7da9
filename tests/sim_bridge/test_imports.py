"""The simulator speaks CAN through the CAN layer (dbc/), never through the service (daq/)."""

import ast
from pathlib import Path

import sim_bridge


def _imported_modules(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def test_sim_bridge_imports_nothing_from_daq() -> None:
    package = Path(sim_bridge.__file__).parent
    offenders = {
        f"{path.relative_to(package)}: {module}"
        for path in package.rglob("*.py")
        for module in _imported_modules(path)
        if module == "daq" or module.startswith("daq.")
    }
    assert not offenders, sorted(offenders)
    # The check itself must see imports: the bridge does use the CAN layer.
    assert any(
        module.startswith("dbc")
        for path in package.rglob("*.py")
        for module in _imported_modules(path)
    )

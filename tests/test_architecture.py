"""The package's shape (ARCHITECTURE.md): imports point down, no cycles, small pieces."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "seqrank"
LOWER = ("agents", "envs", "feedback", "reward", "training")  # below the web app and the CLI


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """seqrank modules `path` imports anywhere (functions included), except for type
    checking only."""
    tree = ast.parse(path.read_text())
    type_only = {
        id(node)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and "TYPE_CHECKING" in ast.unparse(block.test)
        for node in ast.walk(block)
    }
    names = set()
    for node in ast.walk(tree):
        if id(node) in type_only:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("seqrank"):
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names if a.name.startswith("seqrank"))
    return names


GRAPH = {module_name(p): imported(p) for p in SRC.rglob("*.py")}


@pytest.mark.parametrize("layer", LOWER)
def test_lower_layers_import_nothing_from_the_web_app_or_the_cli(layer):
    for module, targets in GRAPH.items():
        if module.startswith(f"seqrank.{layer}"):
            above = [t for t in targets if t.startswith(("seqrank.labelling", "seqrank.cli"))]
            assert not above, f"{module} imports {above}"


def test_the_sb3_layer_sits_above_training_and_the_web_app_beside_the_cli():
    """`seqrank.sb3` uses training, feedback and labelling; nothing of seqrank imports it,
    and it imports nothing of the CLI."""
    for module, targets in GRAPH.items():
        if not module.startswith("seqrank.sb3"):
            assert not [t for t in targets if t.startswith("seqrank.sb3")], module
        else:
            assert not [t for t in targets if t.startswith("seqrank.cli")], module


def test_feedback_does_not_import_the_run_config():
    for module, targets in GRAPH.items():
        if module.startswith("seqrank.feedback"):
            assert "seqrank.config" not in targets, module


def test_there_is_no_import_cycle():
    state: dict[str, str] = {}

    def visit(module: str, path: list[str]) -> None:
        state[module] = "open"
        for target in sorted(GRAPH.get(module, ())):
            if state.get(target) == "open":
                raise AssertionError(" -> ".join([*path, module, target]))
            if target in GRAPH and target not in state:
                visit(target, [*path, module])
        state[module] = "done"

    for module in sorted(GRAPH):
        if module not in state:
            visit(module, [])


def test_modules_and_functions_stay_small():
    big = []
    for path in SRC.rglob("*.py"):
        source = path.read_text()
        if source.count("\n") > 400:
            big.append(f"{path.name}: {source.count(chr(10))} lines")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > 60:
                    big.append(f"{path.name}:{node.lineno} {node.name} is {length} lines")
    assert not big, big

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


MODULES = {module_name(p) for p in SRC.rglob("*.py")}


def imported(path: Path, type_checking: bool = False) -> set[str]:
    """seqrank modules `path` imports anywhere (functions included; `from seqrank import
    rules` names the module), and with `type_checking` those imported for type
    checking only too."""
    tree = ast.parse(path.read_text())
    type_only = {
        id(node)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and "TYPE_CHECKING" in ast.unparse(block.test)
        for node in ast.walk(block)
    }
    names = set()
    for node in ast.walk(tree):
        if id(node) in type_only and not type_checking:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("seqrank"):
            names.add(node.module)
            names.update(m for a in node.names if (m := f"{node.module}.{a.name}") in MODULES)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names if a.name.startswith("seqrank"))
    return names


GRAPH = {module_name(p): imported(p) for p in SRC.rglob("*.py")}
# with the imports made for type checking only: a cycle there is a cycle of the design
TYPED_GRAPH = {module_name(p): imported(p, type_checking=True) for p in SRC.rglob("*.py")}


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


ABOVE_FEEDBACK = ("seqrank.config", "seqrank.choices", "seqrank.envs")  # config: the package


def test_feedback_stays_below_configuration_and_environments():
    for module, targets in TYPED_GRAPH.items():
        if module.startswith("seqrank.feedback"):
            above = [t for t in targets if t.startswith(ABOVE_FEEDBACK)]
            assert not above, f"{module} imports {above}"


def cycle_in(graph: dict[str, set[str]]) -> str | None:
    state: dict[str, str] = {}

    def visit(module: str, path: list[str]) -> str | None:
        state[module] = "open"
        for target in sorted(graph.get(module, ())):
            if state.get(target) == "open":
                return " -> ".join([*path, module, target])
            if target in graph and target not in state:
                found = visit(target, [*path, module])
                if found:
                    return found
        state[module] = "done"
        return None

    for module in sorted(graph):
        if module not in state and (found := visit(module, [])):
            return found
    return None


def test_there_is_no_import_cycle_not_even_for_type_checking():
    assert cycle_in(GRAPH) is None
    assert cycle_in(TYPED_GRAPH) is None


def test_the_cycle_search_finds_a_cycle():
    assert cycle_in({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == "a -> b -> c -> a"
    assert cycle_in({"a": {"b"}, "b": set()}) is None


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

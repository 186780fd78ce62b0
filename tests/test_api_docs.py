"""Every public name of `import seqrank`, and `seqrank.sb3`'s, is documented
for the site's Python API page (docs/reference/api.md renders the docstrings): a Google-style
docstring with `Args:` for what it takes, `Attributes:` for a dataclass, `Returns:` for what
it returns and an `Examples:` section whose doctests run as written."""

from __future__ import annotations

import dataclasses
import doctest
import enum
import inspect
import io
from typing import Any

import pytest

import seqrank

VALUES = ("SCHEMES", "__version__")  # documented in the module docstring of seqrank
NAMES = [name for name in seqrank.__all__ if name not in VALUES]
SB3 = "PreferenceFeedback"
SB3_BUFFER = "PreferenceReplayBuffer"
SB3_MEMBERS = ("save", "load", "reward", "labels")
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def public(name: str) -> Any:
    if name in (SB3, SB3_BUFFER):
        pytest.importorskip("stable_baselines3")
        from seqrank import sb3

        return getattr(sb3, name)
    return getattr(seqrank, name)


def takes_parameters(function: Any) -> bool:
    parameters = inspect.signature(function).parameters
    return any(name not in ("self", "cls") for name in parameters)


def returns_something(function: Any) -> bool:
    annotation = inspect.signature(function).return_annotation
    return annotation not in ("None", None, inspect.Signature.empty)


def needed_sections(value: Any) -> list[str]:
    """A dataclass documents its attributes, a class that takes arguments (not an enum nor
    a protocol) and a function their arguments, a function what it returns; a property
    reads as an attribute."""
    if isinstance(value, property):
        return []
    if dataclasses.is_dataclass(value):
        return ["Attributes:"]
    if inspect.isclass(value):
        plain = not issubclass(value, enum.Enum) and not getattr(value, "_is_protocol", False)
        own_init = plain and "__init__" in vars(value)
        return ["Args:"] if own_init and takes_parameters(value.__init__) else []
    return ["Args:"] * takes_parameters(value) + ["Returns:"] * returns_something(value)


def problems(name: str, value: Any) -> list[str]:
    """What the docstring of `value` lacks, as `name: what`."""
    doc = inspect.getdoc(value) or ""
    missing = [f"{name}: no {s}" for s in ["Examples:", *needed_sections(value)] if s not in doc]
    if "Examples:" in doc and ">>> " not in doc.split("Examples:", 1)[1]:
        missing.append(f"{name}: an Examples section without a >>> line")
    return missing


def documented() -> list[tuple[str, Any]]:
    """(name, object) of every name that needs a docstring: functions, classes and the
    public members of PreferenceFeedback."""
    found = [(name, public(name)) for name in NAMES]
    try:
        feedback = public(SB3)
    except pytest.skip.Exception:
        return found
    found += [(SB3, feedback), (SB3_BUFFER, public(SB3_BUFFER))]
    found += [
        (f"{SB3}.{member}", inspect.getattr_static(feedback, member)) for member in SB3_MEMBERS
    ]
    return [(name, getattr(value, "__func__", value)) for name, value in found]


def test_every_public_name_has_a_docstring_with_its_arguments_and_an_example():
    assert NAMES, "seqrank.__all__ names no function or class"
    missing = [problem for name, value in documented() for problem in problems(name, value)]
    assert not missing, f"undocumented: {missing}"


def test_the_values_are_documented_in_the_module_docstring():
    doc = seqrank.__doc__ or ""
    assert all(f"`{value}`" in doc for value in VALUES), doc
    assert "Examples:" in doc and ">>> " in doc


@pytest.mark.parametrize("name", ["seqrank", *NAMES, SB3, SB3_BUFFER])
def test_the_examples_run(name, tmp_path, monkeypatch):
    value = seqrank if name == "seqrank" else public(name)
    monkeypatch.chdir(tmp_path)  # examples write their runs and folders here
    tests = doctest.DocTestFinder().find(value, name, globs={})
    assert sum(len(test.examples) for test in tests), f"{name} has no example"
    runner, report = doctest.DocTestRunner(optionflags=FLAGS), io.StringIO()
    for test in tests:
        runner.run(test, out=report.write)
    assert runner.failures == 0, report.getvalue()


def test_the_schemes_block_of_the_api_page_runs():
    """`seqrank.SCHEMES` is rendered from `SchemeName` (docs/reference/api.md)."""
    from seqrank.feedback.schemes import SchemeName

    tests = doctest.DocTestFinder().find(SchemeName, "SchemeName", globs={"SchemeName": SchemeName})
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in tests:
        runner.run(test)
    assert runner.tries >= 2 and runner.failures == 0

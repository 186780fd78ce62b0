from __future__ import annotations

import contextlib
import importlib
import pkgutil

import pytest


def _import_anyio_whole() -> None:
    """Import every anyio module now, in the main thread, before any test starts a server.

    anyio imports its parts on first use, parsing sources with `ast` as it goes, and
    pytest parses them again to rewrite asserts (anyio is a pytest plugin). A first use
    inside a test client's server thread then parses beside another thread, and CPython
    3.11's AST converter is not thread-safe: "SystemError: AST constructor recursion depth
    mismatch" (CPython issue 106905), seen in CI serving a clip.
    """
    import anyio

    for module in pkgutil.walk_packages(anyio.__path__, "anyio."):
        with contextlib.suppress(ImportError):  # an optional backend (trio), not installed
            importlib.import_module(module.name)


_import_anyio_whole()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked `gpu` are skipped where torch sees no CUDA device."""
    import torch

    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="gpu: needs a CUDA device")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)

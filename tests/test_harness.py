"""The test harness itself: what conftest.py does before any test runs."""

from __future__ import annotations

import sys


def test_anyio_is_imported_whole_before_any_server_thread_starts():
    # anyio loads these on first use; loaded in a server thread they race CPython 3.11's
    # thread-unsafe AST converter (see conftest._import_anyio_whole).
    for name in ("anyio._core._fileio", "anyio._core._sockets", "anyio.streams.memory"):
        assert name in sys.modules, name

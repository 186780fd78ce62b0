from __future__ import annotations

import contextlib
import importlib
import os
import pkgutil
import subprocess
import warnings
from pathlib import Path

import pytest

CHECKOUT = Path(__file__).resolve().parents[1]


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


def _mujoco_warnings_as_python_warnings() -> None:
    """MuJoCo appends its warnings (a deprecated attribute in HalfCheetah's model, say) to
    MUJOCO_LOG.TXT in the working directory, the checkout; in tests they become Python
    warnings instead, which pytest reports."""
    importlib.import_module("seqrank.envs.base")  # chooses headless GL before MuJoCo loads
    mujoco = importlib.import_module("mujoco")
    mujoco.set_mju_user_warning(lambda text: warnings.warn(f"MuJoCo: {text}", stacklevel=1))


_mujoco_warnings_as_python_warnings()


@pytest.fixture(autouse=True, scope="session")
def _cpu_path_measurements_kept_apart(tmp_path_factory: pytest.TempPathFactory):
    """`--path auto` keeps its CPU measurements in ~/.cache/seqrank; a test run keeps its
    own, so it neither reads the user's choice nor writes into their home."""
    before = os.environ.get("SEQRANK_CACHE")
    os.environ["SEQRANK_CACHE"] = str(tmp_path_factory.mktemp("seqrank-cache"))
    yield
    if before is None:
        os.environ.pop("SEQRANK_CACHE", None)
    else:
        os.environ["SEQRANK_CACHE"] = before


@pytest.fixture(autouse=True, scope="session")
def _minari_datasets_kept_apart(tmp_path_factory: pytest.TempPathFactory):
    """Minari's local datasets folder (~/.minari/datasets) is the test run's own: a
    dataset a test names by id is made there, never in the user's home."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(tmp_path_factory.mktemp("minari-datasets"))
    yield
    if before is None:
        os.environ.pop("MINARI_DATASETS_PATH", None)
    else:
        os.environ["MINARI_DATASETS_PATH"] = before


def _checkout_changes() -> set[str] | None:
    """What `git status` lists in the checkout (changed and untracked files, ignored ones
    left out); None outside a git checkout (the wheel's test run)."""
    try:
        listed = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=all"],
            cwd=CHECKOUT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    return set(listed.splitlines())


def _is_controller(session: pytest.Session) -> bool:
    return not hasattr(session.config, "workerinput")  # an xdist worker has it


def pytest_sessionstart(session: pytest.Session) -> None:
    if _is_controller(session):
        session.config.stash[_BEFORE] = _checkout_changes()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Tests write into tmp_path, never into the checkout: anything the run added to
    `git status` fails it."""
    if not _is_controller(session):
        return
    before, after = session.config.stash.get(_BEFORE, None), _checkout_changes()
    if before is None or after is None or not after - before:
        return
    written = ", ".join(sorted(line[3:] for line in after - before))
    writer = session.config.get_terminal_writer()
    writer.line()
    writer.line(f"tests wrote into the checkout: {written}", red=True)
    session.exitstatus = pytest.ExitCode.TESTS_FAILED


_BEFORE = pytest.StashKey[set[str] | None]()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked `gpu` are skipped where torch sees no CUDA device."""
    import torch

    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="gpu: needs a CUDA device")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)

"""`scripts/break_core.py` stays applicable: every break names a line that today's source
holds exactly once, and tests that exist (the script itself is run by hand: minutes)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_script():
    spec = importlib.util.spec_from_file_location("break_core", ROOT / "scripts/break_core.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_every_break_applies_to_todays_source_and_names_existing_tests():
    script = load_script()
    assert len(script.BREAKS) >= 16
    for entry in script.BREAKS:
        text = (ROOT / "src/seqrank" / entry.file).read_text()
        assert text.count(entry.old) == 1, entry.name
        assert entry.old != entry.new, entry.name
        assert all((ROOT / test).is_file() for test in entry.tests), entry.name

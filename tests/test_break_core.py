"""`scripts/break_core.py` stays applicable: every break names a line that today's source
holds exactly once, and tests that exist (the script itself is run by hand: minutes)."""

from __future__ import annotations

from pathlib import Path

from support.scripts import load_script

ROOT = Path(__file__).resolve().parents[1]


def test_every_break_applies_to_todays_source_and_names_existing_tests():
    script = load_script("break_core")
    assert len(script.BREAKS) >= 16
    for entry in script.BREAKS:
        text = (ROOT / "src/seqrank" / entry.file).read_text()
        assert text.count(entry.old) == 1, entry.name
        assert entry.old != entry.new, entry.name
        assert all((ROOT / test).is_file() for test in entry.tests), entry.name

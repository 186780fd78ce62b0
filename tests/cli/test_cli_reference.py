"""The command-line reference page is the parser's own account of itself."""

from __future__ import annotations

from pathlib import Path

from seqrank.cli import build_parser
from seqrank.cli.reference import parsers, reference_page

PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "cli.md"


def test_the_committed_page_is_what_the_parser_says_now():
    assert PAGE.read_text() == reference_page(), (
        "docs/reference/cli.md is stale: rewrite it with "
        "`python -m seqrank.cli.reference > docs/reference/cli.md`"
    )


def test_the_page_lists_every_sub_command_and_every_option():
    page = reference_page()
    commands = [(words, parser) for words, parser, _ in parsers(build_parser()) if words]
    assert {words[0] for words, _ in commands} >= {"train", "label", "sweep", "reward-bench"}
    for words, parser in commands:
        assert f"`seqrank {' '.join(words)}`" in page
        section = page.split(f"`seqrank {' '.join(words)}`\n", 1)[1].split("\n#", 1)[0]
        for action in parser._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}`" in section, f"seqrank {' '.join(words)} {option}"


def test_a_machine_dependent_default_is_shown_by_what_it_means():
    page = reference_page()
    assert "| the number of cores |" in page

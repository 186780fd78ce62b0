"""Every code block of README.md and the documentation site (docs/) works as written on a
CPU, and every command an evidence page (results/) records still parses.

Examples of commands that train or time (train, label online and study, sweep, bench) are
checked with `--dry-run`: every setting resolved and validated as the real command does it
(a budget that cannot be spent, a bad value), nothing written. Examples that read what
other commands made (a run, a label file, a folder of runs) run for real on small stand-ins;
the others (long, or needing a GPU or a person) are parsed. Placeholders (`<a run>`,
`...`, `RUN_OR_LABEL_DIR`) stand for a run directory made here. Python blocks run, at
tiny sizes where a page gives long ones (`SIZED`: a replacement that no longer matches
fails, so a page cannot drift from what is tested); the Stable-Baselines3 snippet runs in
tests/sb3/test_sb3_readme.py.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from seqrank.cli import build_parser, main
from seqrank.feedback.labels import LabelStore
from seqrank.training.runs import RunDir
from support.runs import tiny_config

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
# the site's pages, and the two files it includes whole (Design: architecture, security)
PAGES = [
    README,
    ROOT / "ARCHITECTURE.md",
    ROOT / "SECURITY.md",
    *sorted((ROOT / "docs").rglob("*.md")),
]
EVIDENCE = [*sorted((ROOT / "results").rglob("*.md"))]
RUN = "seqrank-out/runs/run"
DRY = (("train",), ("label", "online"), ("label", "study"), ("sweep",), ("bench",))
RUNS_FOR_REAL = (
    ("report",),
    ("labels", "export"),
    ("labels", "import"),
    ("theory",),
    ("simulate",),
)
PLACEHOLDERS = [
    (r"seqrank-out/runs/[^\s]*(\.\.\.|<a run>)", RUN),
    (r"RUN_OR_LABEL_DIR", RUN),
    (r"OTHER_LABEL_DIR", "other-labels"),
    (r"seqrank COMMAND", "seqrank train"),
]


def blocks(language: str, pages: list[Path] = PAGES) -> list[tuple[Path, str]]:
    """Every fenced block whose language matches `language` (a regex), with its page."""
    found = []
    for page in pages:
        opened, lines = None, []
        for line in page.read_text().splitlines():
            fence = re.match(r"\s*```(\w*)", line)
            if fence and opened is None:
                opened, lines = fence.group(1), []
            elif fence:
                if re.fullmatch(language, opened):
                    found.append((page, "\n".join(lines) + "\n"))
                opened = None
            elif opened is not None:
                lines.append(line)
    return found


def examples() -> list[str]:
    """Lines of ```bash blocks that start with `seqrank`, and inline `seqrank ... --...`."""
    text = "\n".join(page.read_text() for page in PAGES)
    found = []
    for _, block in blocks("bash"):
        found += [line for line in block.splitlines() if line.startswith("seqrank ")]
    found += [span for span in re.findall(r"`(seqrank [^`]*)`", text) if "--" in span]
    return list(dict.fromkeys(found))


def argv_of(example: str) -> list[str]:
    command = re.sub(r"\s+#.*$", "", example)
    for pattern, value in PLACEHOLDERS:
        command = re.sub(pattern, value, command)
    return shlex.split(command)[1:]


def sweep_file() -> str:
    """The sweep file the documentation shows (its only TOML block)."""
    (only,) = blocks("toml")
    return only[1]


def one_answer() -> LabelStore:
    """A label store of one session of one asked question (segments of cartpole's width)."""
    store = LabelStore()
    store.segments = [np.zeros((50, 6), np.float32), np.ones((50, 6), np.float32)]
    store.segment_returns, store.segment_rewards = [0.0, 50.0], [np.zeros(50), np.ones(50)]
    store.segment_states, store.segment_contexts = [None, None], [None, None]
    store.first, store.second, store.labels = [0], [1], [0.0]
    store.inferred, store.session = [False], [0]
    store.asked = [(0, "pairwise", 0, 1, "second", False)]
    return store


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """What the examples read: a run, the documented sweep file, a label file, a folder of
    runs where the report example looks."""
    root = tmp_path_factory.mktemp("readme")
    config = tiny_config()
    run = RunDir.create(root / RUN, config, "cpu")
    run.write_summary({"steps": config.steps})
    run.save_checkpoint({"labels": one_answer().state_dict()})  # all the export reads
    run.release()
    (root / "my-sweep.toml").write_text(sweep_file())
    # the own-environment example runs from the repository root
    (root / "examples").symlink_to(Path(__file__).parents[1] / "examples")
    features = [[0.0] * 6] * 50
    (root / "labels.jsonl").write_text(
        "\n".join(
            json.dumps(line)
            for line in (
                {"type": "header", "format": "seqrank-labels", "version": 1}
                | {"task": "dmc:cartpole_swingup"},  # 5 observations + 1 action
                {"type": "segment", "id": "a", "features": features, "rewards": [0.0] * 50},
                {"type": "segment", "id": "b", "features": features, "rewards": [1.0] * 50},
                {"type": "answer", "run": "r", "scheme": "pairwise", "session": 0, "index": 0}
                | {"first": "a", "second": "b", "answer": "second"},
            )
        )
        + "\n"
    )
    runs = root / "seqrank-out/sweeps/my-sweep/runs"
    for seed in (0, 1):
        folder = runs / f"root_seed{seed}"
        folder.mkdir(parents=True)
        (folder / "config.json").write_text(json.dumps({**config.as_dict(), "seed": seed}))
        row = {"step": 3200, "kind": "eval", "eval_return": 100.0 + seed}
        (folder / "metrics.jsonl").write_text(json.dumps(row) + "\n")
    (runs / "root_seed0" / "summary.json").write_text("{}")  # a partial sweep: one finished
    return root


def test_the_documentation_has_examples_of_every_command():
    commands = {argv_of(example)[0] for example in examples()}
    assert {"train", "label", "labels", "sweep", "report", "bench", "reward-bench"} <= commands
    assert {"watch", "study-report"} <= commands


@pytest.mark.parametrize("example", examples())
def test_a_documented_command_works(example, workspace, monkeypatch, capsys):
    monkeypatch.chdir(workspace)
    argv = argv_of(example)
    gpu = "cuda" in argv
    if argv == ["--help"]:
        code = main(argv)
    elif any(tuple(argv[: len(c)]) == c for c in DRY) and not gpu:
        code = main([*argv, "--dry-run"] if "--help" not in argv else argv)
    elif any(tuple(argv[: len(c)]) == c for c in RUNS_FOR_REAL):
        if argv[0] == "simulate" and "--sessions" in argv:  # the same, with fewer sessions
            argv[argv.index("--sessions") + 1] = "10"
        if argv[:2] == ["labels", "export"]:  # a new file, as on a reader's machine
            Path(argv[argv.index("-o") + 1]).unlink(missing_ok=True)
        code = main(argv)
    else:  # long, or on a GPU, or with a person at the page: parsed only
        build_parser().parse_args(argv)
        code = 0
    assert code == 0, capsys.readouterr().err


# Long python blocks, as tested: each `sized` text becomes `tiny`, and must be on the page.
SIZED = {
    "reference/api.md": {
        'seqrank.make_config("walker_walk", "small", scheme="root", steps=60_000)': (
            'seqrank.make_config("walker_walk", "small", scheme="root", steps=2_400, '
            "seed_steps=1_000, unsup_steps=200, feedback_frequency=400, max_feedback=6, "
            "reward_batch=3, hidden=32, batch=32, reward_hidden=32, reward_epochs=3, "
            "eval_every=2_400, eval_episodes=1, heldout_pairs=20, device='cpu')"
        ),
    },
}


def stand_ins() -> dict[str, object]:
    """What a block leaves to the reader (`my_ask`, `my_judge`, `observation`: "yours")."""
    import seqrank

    return {
        "my_ask": lambda first, second: seqrank.Answer.FIRST,
        "my_judge": lambda first, second: seqrank.Answer.SECOND,
        "observation": np.zeros(24, np.float32),
    }


def python_blocks() -> list[tuple[str, str]]:
    found = []
    for page, block in blocks("python"):
        if "stable_baselines3" in block:
            continue  # run sized by tests/sb3/test_sb3_readme.py
        found.append((page.relative_to(ROOT).as_posix().removeprefix("docs/"), block))
    return found


@pytest.mark.parametrize(("page", "code"), python_blocks(), ids=lambda v: str(v)[:30])
def test_a_python_block_runs(page, code, tmp_path, monkeypatch):
    for sized, tiny in SIZED.get(page, {}).items():
        code = code.replace(sized, tiny)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, page, "exec"), stand_ins())


def test_every_long_block_is_still_on_its_page():
    """Else a page gives long sizes that the test above no longer shrinks."""
    for page, sizes in SIZED.items():
        code = "".join(block for where, block in python_blocks() if where == page)
        missing = [sized for sized in sizes if sized not in code]
        assert not missing, f"{page} no longer has {missing}: update SIZED"


def evidence_commands() -> list[str]:
    """`seqrank` commands that the evidence pages record (continued lines joined)."""
    found = []
    for _, block in blocks("bash|", EVIDENCE):
        for line in block.replace("\\\n", " ").splitlines():
            match = re.search(r"(?:^|\s)(?:-m )?seqrank (\w.*)", line)
            if match and not line.lstrip().startswith("#"):
                found.append("seqrank " + up_to_a_shell_operator(match.group(1)).strip())
    return found


def up_to_a_shell_operator(line: str) -> str:
    """The line before its first `;`, `&`, `|` or `>` outside quotes (a quoted teacher list
    separates teachers with `;`)."""
    quote = ""
    for i, char in enumerate(line):
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char in "&|;>":
            return line[:i]
    return line


SHELL_VALUES = {"scheme": "root", "s": "root", "seed": "0"}


@pytest.mark.parametrize("command", evidence_commands())
def test_an_evidence_command_still_parses(command):
    """A results folder's command, run long ago, is still a valid command line."""
    for name, value in SHELL_VALUES.items():
        command = re.sub(rf"\$(\{{{name}\}}|{name}\b)", value, command)
    assert "$" not in command, f"a shell variable to add to SHELL_VALUES: {command}"
    build_parser().parse_args(argv_of(command))


def test_the_evidence_pages_record_commands():
    assert len(evidence_commands()) >= 10


def test_every_public_name_has_its_block_on_the_api_page():
    """A name added to `seqrank.__all__` without a `:::` block would be missing from the site."""
    import seqrank

    page = (ROOT / "docs/reference/api.md").read_text()
    documented = {
        line.removeprefix(":::").strip().rsplit(".", 1)[-1]
        for line in page.splitlines()
        if line.startswith(":::")
    }
    # a function or class has a block of its own; a value (SCHEMES, __version__) is named
    # in the module's block, whose text is the package docstring
    missing = [
        name
        for name in seqrank.__all__
        if name not in documented
        and (callable(getattr(seqrank, name)) or f"`{name}`" not in seqrank.__doc__ + page)
    ]
    assert not missing, f"docs/reference/api.md has no ::: block for {missing}"


@pytest.mark.parametrize("page", sorted({page for page, _ in blocks("python", EVIDENCE)}), ids=str)
def test_an_evidence_pages_python_runs_on_its_results(page, monkeypatch, capsys):
    """The snippets that recompute an evidence page's numbers from its committed results."""
    monkeypatch.chdir(ROOT)
    for _, code in blocks("python", [page]):
        exec(compile(code, str(page), "exec"), {})
    assert capsys.readouterr().out.strip(), "the snippet printed nothing"


def test_the_built_site_opens_from_a_file_offline():
    """README: "open `site/index.html` (offline)": from file:// a link to a folder
    (`guides/sb3/`) opens a directory listing, so the site links its pages as page.html."""
    import yaml

    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    assert config["use_directory_urls"] is False
    assert "open `site/index.html`" in (ROOT / "README.md").read_text()

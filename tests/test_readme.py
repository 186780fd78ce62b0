"""Every `seqrank ...` example in README.md works as written on a CPU.

Examples of commands that train or time (train, label online and study, sweep, bench) are
checked with `--dry-run`: every setting resolved and validated as the real command does it
(a budget that cannot be spent, a bad value), nothing written. Examples that read what
other commands made (a run, a label file, a folder of runs) run for real on small stand-ins;
the others (long, or needing a GPU or a person) are parsed. Placeholders (`<a run>`,
`...`, `RUN_OR_LABEL_DIR`) stand for a run directory made here.
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

README = Path(__file__).resolve().parents[1] / "README.md"
RUN = "seqrank-out/runs/run"
DRY = (("train",), ("label", "online"), ("label", "study"), ("sweep",), ("bench",))
RUNS_FOR_REAL = (("report",), ("labels", "export"), ("labels", "import"))
PLACEHOLDERS = [
    (r"seqrank-out/runs/[^\s]*(\.\.\.|<a run>)", RUN),
    (r"RUN_OR_LABEL_DIR", RUN),
    (r"OTHER_LABEL_DIR", "other-labels"),
]


def examples() -> list[str]:
    """Lines of ```bash blocks that start with `seqrank`, and inline `seqrank ... --...`."""
    text = README.read_text()
    found = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        found += [line for line in block.splitlines() if line.startswith("seqrank ")]
    found += [span for span in re.findall(r"`(seqrank [^`]*)`", text) if "--" in span]
    return list(dict.fromkeys(found))


def argv_of(example: str) -> list[str]:
    command = re.sub(r"\s+#.*$", "", example)
    for pattern, value in PLACEHOLDERS:
        command = re.sub(pattern, value, command)
    return shlex.split(command)[1:]


def sweep_file() -> str:
    """The sweep file the README shows."""
    return re.search(r"```toml\n(.*?)```", README.read_text(), re.S).group(1)


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
    """What the examples read: a run, the README's sweep file, a label file, a folder of
    runs where the README's report example looks."""
    root = tmp_path_factory.mktemp("readme")
    config = tiny_config()
    run = RunDir.create(root / RUN, config, "cpu")
    run.write_summary({"steps": config.steps})
    run.save_checkpoint({"labels": one_answer().state_dict()})  # all the export reads
    run.release()
    (root / "my-sweep.toml").write_text(sweep_file())
    # the README runs its own-environment example from the repository root
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


def test_the_readme_has_examples_of_every_command():
    commands = {argv_of(example)[0] for example in examples()}
    assert {"train", "label", "labels", "sweep", "report", "bench", "reward-bench"} <= commands
    assert {"watch", "study-report"} <= commands


@pytest.mark.parametrize("example", examples())
def test_a_readme_example_works(example, workspace, monkeypatch, capsys):
    monkeypatch.chdir(workspace)
    argv = argv_of(example)
    gpu = "cuda" in argv
    if any(tuple(argv[: len(c)]) == c for c in DRY) and not gpu:
        code = main([*argv, "--dry-run"] if "--help" not in argv else argv)
    elif any(tuple(argv[: len(c)]) == c for c in RUNS_FOR_REAL):
        code = main(argv)
    else:  # long, or on a GPU, or with a person at the page: parsed only
        build_parser().parse_args(argv)
        code = 0
    assert code == 0, capsys.readouterr().err

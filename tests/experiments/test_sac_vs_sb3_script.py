"""`scripts/sac_vs_sb3.py`: the seqrank side is the matched `seqrank train`, and the report's
table is the IQM and spread of each implementation's final returns. (Stable-Baselines3 is a
development-only dependency of the script: its side is not run here.)"""

from __future__ import annotations

import json
import re
import sys
from argparse import Namespace

import pytest

from seqrank.cli import main
from support.scripts import load_script


@pytest.fixture(scope="module")
def script():
    yield load_script("sac_vs_sb3")
    del sys.modules["sac_vs_sb3"]


def test_the_seqrank_side_is_a_valid_train_command_with_the_matched_settings(
    script, tmp_path, capsys
):
    job = script.Job("cheetah_run", "seqrank-alpha", 3, (("alpha_lr", "0.0005"),))
    args = Namespace(steps=50_000, eval_every=10_000, eval_episodes=10)
    command = script.seqrank_command(job, args, tmp_path / "run")
    assert command[1:4] == ["-m", "seqrank", "train"]
    options = command[4 : command.index("--out")]
    assert main(["train", *options, "--dry-run"]) == 0
    printed = capsys.readouterr().err
    settings = dict(re.findall(r"^\s+(\w+) = (.*)$", printed, re.M))
    expected = {
        "task": "cheetah_run",
        "reward": "true",
        "seed": "3",
        "steps": "50000",
        "hidden": "256",
        "layers": "2",
        "batch": "256",
        "actor_lr": "0.0005",
        "critic_lr": "0.0005",
        "init_temperature": "0.1",
        "target_update_every": "2",
        "seed_steps": "1000",
        "alpha_lr": "0.0005",  # the variant's own setting
    }
    assert {k: settings.get(k) for k in expected} == expected
    # a started run is continued, not begun again
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.json").write_text("{}")
    assert script.seqrank_command(job, args, tmp_path / "run")[4:6] == [
        "--resume",
        str(tmp_path / "run"),
    ]


def test_a_variant_without_settings_in_the_form_key_value_is_refused(script):
    args = Namespace(variant=["lr:alpha_lr"], seeds=1, tasks=["walker_walk"])
    with pytest.raises(SystemExit, match="NAME:KEY=VALUE"):
        script.jobs(args)
    args.variant = ["lr:alpha_lr=0.0005"]
    assert [j.impl for j in script.jobs(args)] == ["seqrank", "sb3", "seqrank-lr"]


def test_the_report_gives_each_implementations_iqm_and_spread_of_final_returns(
    script, tmp_path, monkeypatch
):
    finals = {"seqrank": [100.0, 200.0, 300.0, 400.0], "sb3": [50.0, 50.0, 80.0, 90.0]}
    for impl, values in finals.items():
        for seed, final in enumerate(values):
            folder = tmp_path / "runs" / "walker_walk" / f"{impl}_seed{seed}"
            folder.mkdir(parents=True)
            curve = {"curve": [[10_000, final / 2], [20_000, final]], "command": impl}
            (folder / "curve.json").write_text(json.dumps(curve))
    out = tmp_path / "out"
    argv = ["sac_vs_sb3.py", "report", "--runs", str(tmp_path / "runs"), "--out", str(out)]
    monkeypatch.setattr(sys, "argv", [*argv, "--bootstrap", "200"])
    script.main()
    lines = (out / "table.md").read_text().splitlines()
    rows = {line.split(" | ")[1]: line for line in lines if line.startswith("| walker_walk")}
    # IQM of four values: the mean of the middle two; sample std with n - 1
    assert rows["seqrank"].startswith("| walker_walk | seqrank | 4 | 250 [")
    assert rows["seqrank"].endswith("| 250 ± 129 |")
    assert rows["sb3"].startswith("| walker_walk | sb3 | 4 | 65 [")
    assert (out / "curves.png").stat().st_size > 0
    assert len(json.loads((out / "curves.json").read_text())) == 8

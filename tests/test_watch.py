"""`seqrank watch`: a run's saved policy as an mp4 and a contact sheet."""

from __future__ import annotations

import av
import pytest
import torch

from seqrank.cli import main
from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.training.agent_factory import load_policy
from seqrank.training.evaluation import evaluate_policy
from seqrank.training.state import episode_seed
from support.runs import run


@pytest.mark.parametrize("task", ["dmc:cartpole_swingup", "block:place"])
def test_watch_writes_the_episodes_the_policy_plays(tmp_path, capsys, task):
    settings = {"reward": "true", "steps": 600, "seed_steps": 300, "hidden": 32, "batch": 32}
    settings.update(eval_every=600, eval_episodes=1, device="cpu")
    config = resolve_config(task, "small", settings)
    run(tmp_path / "run", config)
    out = tmp_path / "look"
    args = ["watch", str(tmp_path / "run"), "--episodes", "1", "--size", "64", "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    env = make_env(task, config.seed)
    seeds = [episode_seed(config.seed, 2, 0)]
    expected = evaluate_policy(load_policy(tmp_path / "run", env), env, seeds, torch.Generator())
    for k, value in enumerate(expected.returns, 1):
        assert f"episode {k}: return {value:.1f}" in printed  # the same deterministic episodes
    with av.open(str(out / "watch.mp4")) as video:
        stream = video.streams.video[0]
        frames = sum(1 for _ in video.decode(stream))
        assert (stream.width, stream.height) == (64, 64 + 22)  # frame + caption
    assert frames == env.episode_length
    assert (out / "contact_sheet.png").read_bytes()[:4] == b"\x89PNG"


def test_watch_without_a_checkpoint_says_so(tmp_path, capsys):
    assert main(["watch", str(tmp_path / "nothing")]) == 2
    assert "no run directory" in capsys.readouterr().err

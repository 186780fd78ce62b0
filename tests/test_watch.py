"""`seqrank watch`: a run's saved policy as an mp4 and a contact sheet."""

from __future__ import annotations

import av
import numpy as np
import pytest
import torch

from seqrank.cli import main
from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.training.agent_factory import load_policy
from seqrank.training.evaluation import evaluate_policy
from seqrank.training.state import episode_seed
from seqrank.watch import _Captions, fit_caption
from support.runs import run

SIZES = (64, 256, 480)  # the smallest size `watch` takes, its default, and the largest


def _trained(path, task):
    settings = {"reward": "true", "steps": 600, "seed_steps": 300, "hidden": 32, "batch": 32}
    settings.update(eval_every=600, eval_episodes=1, device="cpu")
    config = resolve_config(task, "small", settings)
    run(path, config)
    return config


def _ink(pixels: np.ndarray) -> np.ndarray:
    return pixels.max(axis=-1) > 96  # white text on black, after H.264's blur


@pytest.mark.parametrize(
    ("task", "size"),
    [("dmc:cartpole_swingup", 64), ("gym:Hopper-v5", 64), *(("block:place", s) for s in SIZES)],
)
def test_watch_writes_the_episodes_the_policy_plays(tmp_path, capsys, task, size):
    config = _trained(tmp_path / "run", task)
    out = tmp_path / "look"
    args = ["watch", str(tmp_path / "run"), "--episodes", "1", "--size", str(size)]
    assert main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    env = make_env(task, config.seed)
    seeds = [episode_seed(config.seed, 2, 0)]
    expected = evaluate_policy(load_policy(tmp_path / "run", env), env, seeds, torch.Generator())
    for k, value in enumerate(expected.returns, 1):
        assert f"episode {k}: return {value:.1f}" in printed  # the same deterministic episodes
    # success only where the task has one (as reports score it): not DMControl or Hopper
    assert ("success" in printed) == (task == "block:place")
    with av.open(str(out / "watch.mp4")) as video:
        stream = video.streams.video[0]
        frames = [frame.to_ndarray(format="rgb24") for frame in video.decode(stream)]
    if env.has_terminals:  # Hopper falls: its episode ends where it does
        assert 0 < len(frames) <= env.episode_length
    else:
        assert len(frames) == env.episode_length
    assert (stream.width, stream.height) == (size, frames[0].shape[0]) and frames[0].shape[0] > size
    # under the frame, the caption's lines (even heights: H.264 takes no odd one), the text
    # ending inside the frame with a margin, not cut by its right edge
    caption = np.stack([frame[size:] for frame in frames])
    assert caption.shape[1] % 2 == 0 and _ink(caption).any()
    assert not _ink(caption[:, :, -2:]).any()
    assert (out / "contact_sheet.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("size", SIZES)
def test_the_longest_caption_fits_every_frame_size(size):
    """Each character in its own cell: a cell has ink exactly where the text has a
    character, and the text ends inside the frame."""
    fields = ["episode 1000", "step 1000", "return -12345.6", "success yes"]
    layout = fit_caption(size, [len(f) for f in fields])
    bar = _Captions(layout).render(fields)
    assert bar.shape == (layout.height, size, 3)
    texts = layout.texts(fields)
    assert "".join(texts).replace(" ", "") == "".join(fields).replace(" ", "")  # all of it
    high, cell = layout.line_height, layout.cell
    for k, text in enumerate(texts):
        assert len(text) * cell <= size  # the text's extent lies within the frame
        band = _ink(bar[k * high : (k + 1) * high])
        inked = [bool(band[:, j * cell : (j + 1) * cell].any()) for j in range(len(text))]
        assert inked == [char != " " for char in text], text
        assert not band[:, len(text) * cell :].any()
    assert layout.cell >= 4 and len(texts) <= 4


def test_watch_without_a_checkpoint_says_so(tmp_path, capsys):
    assert main(["watch", str(tmp_path / "nothing")]) == 2
    assert "no run directory" in capsys.readouterr().err

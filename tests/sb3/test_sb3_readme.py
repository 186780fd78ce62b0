"""The "Use with Stable-Baselines3" snippet (docs/guides/sb3.md, its first lines also in the
README) works as written: run at a tiny size (each size it gives replaced by a smaller one;
a replacement that no longer matches fails)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
GUIDE, README = ROOT / "docs" / "guides" / "sb3.md", ROOT / "README.md"
TINY = {
    "max_feedback=100, feedback_frequency=10_000)": "max_feedback=10, feedback_frequency=10_000, "
    "reward_batch=10, seed_steps=1_000, unsup_steps=50, steps=1_100, reward_epochs=5, "
    "heldout_pairs=50, device='cpu')",
    'SAC("MlpPolicy", feedback.env, seed=0,': 'SAC("MlpPolicy", feedback.env, seed=0, '
    "policy_kwargs=dict(net_arch=[32, 32]), batch_size=64,",
    "model.learn(60_000,": "model.learn(1_100,",
}


def snippet(page: Path = GUIDE) -> str:
    return re.search(r"```python\n(from stable_baselines3.*?)```", page.read_text(), re.S).group(1)


def test_the_readme_shows_the_guide_s_snippet():
    assert snippet().startswith(snippet(README))


def test_the_readme_snippet_runs(tmp_path, monkeypatch):
    code = snippet()
    for sized, tiny in TINY.items():
        assert sized in code, sized
        code = code.replace(sized, tiny)
    monkeypatch.chdir(tmp_path)
    names = {"observations": np.zeros((4, 24), np.float32), "actions": np.zeros((4, 6))}
    code = code.replace(
        "feedback.reward(observations, actions)", "rewards = feedback.reward(observations, actions)"
    )
    code = code.replace("len(feedback.labels) ", "pairs = len(feedback.labels) ")
    exec(compile(code, "docs/guides/sb3.md", "exec"), names)
    assert names["rewards"].shape == (4,) and names["pairs"] >= 10
    assert (tmp_path / "my-run" / "labels.jsonl").is_file()

"""Look at a trained agent: its saved policy plays N evaluation episodes, recorded as an
mp4 with the running true return (and success, on tasks that report it) under each frame,
and a contact sheet PNG of frames across the episodes (like the paper's Figures 5-10)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from seqrank.agents.protocol import Policy
from seqrank.envs import SimEnv, canonical_task, make_env
from seqrank.training.state import episode_seed
from seqrank.video import encode_mp4

BAR = 22  # pixels of the caption under each frame


@dataclass(frozen=True)
class Episode:
    frames: np.ndarray  # (T, size + BAR, size, 3) uint8, captioned
    total: float
    success: bool


def play(
    policy: Policy, env: SimEnv, seed: int, size: int, label: str, shows_success: bool
) -> Episode:
    """One deterministic episode, rendered step by step with a caption."""
    obs, _ = env.reset(seed=seed)
    frames, total, success, done, step = [], 0.0, False, False, 0
    generator = torch.Generator().manual_seed(seed % 2**31)
    caption = _Captions(size)
    while not done:
        frame = env.render_frame(size, size)
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, True, generator))
        total, step = total + float(reward), step + 1
        success = success or bool(info.get("success", False))
        done = bool(terminated or truncated)
        text = f"{label}  step {step}  return {total:.1f}"
        if shows_success:
            text += f"  success {'yes' if success else 'no'}"
        frames.append(np.concatenate([frame, caption.render(text)], axis=0))
    return Episode(np.stack(frames), total, success)


class _Captions:
    """White monospace text on black, `BAR` pixels high: each character is drawn once by
    matplotlib and kept, so a caption per frame costs only a concatenation."""

    CELL = 7  # pixels per character

    def __init__(self, width: int):
        self.width = width
        self.glyphs: dict[str, np.ndarray] = {}

    def glyph(self, char: str) -> np.ndarray:
        if char not in self.glyphs:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            figure = Figure(figsize=(self.CELL / 100, BAR / 100), dpi=100, facecolor="black")
            figure.text(
                0.5,
                0.5,
                char,
                color="white",
                fontsize=9,
                ha="center",
                va="center",
                family="monospace",
            )
            canvas = FigureCanvasAgg(figure)
            canvas.draw()
            pixels = np.asarray(canvas.buffer_rgba())[:BAR, : self.CELL, :3]
            self.glyphs[char] = pixels.copy()
        return self.glyphs[char]

    def render(self, text: str) -> np.ndarray:
        bar = np.zeros((BAR, self.width, 3), np.uint8)
        row = np.concatenate([self.glyph(c) for c in " " + text], axis=1)[:, : self.width]
        bar[:, : row.shape[1]] = row
        return bar


def contact_sheet(episodes: list[Episode], path: Path, title: str, per_episode: int = 6) -> Path:
    """Evenly spaced frames of each episode, one row per episode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = len(episodes)
    figure, axes = plt.subplots(
        rows, per_episode, figsize=(2 * per_episode, 2.2 * rows), squeeze=False
    )
    for axis_row, episode in zip(axes, episodes, strict=True):
        picks = np.linspace(0, len(episode.frames) - 1, per_episode).round().astype(int)
        for axis, index in zip(axis_row, picks, strict=True):
            axis.imshow(episode.frames[index])
            axis.set_axis_off()
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path


def watch(
    run_dir: Path, episodes: int, out: Path, size: int = 256, fps: int = 30
) -> tuple[list[Episode], Path, Path]:
    """Play `episodes` evaluation episodes of the run's saved policy; write `out/watch.mp4`
    and `out/contact_sheet.png`."""
    from seqrank.training.agent_factory import load_policy
    from seqrank.training.runs import RunDir

    config = RunDir.open(run_dir).read_config()
    env = make_env(config.task, config.seed)
    env.use_fast_rendering()  # no shadows: 7x faster, as the labelling clips
    policy = load_policy(run_dir, env)
    shows_success = canonical_task(config.task)[0] != "dmc"
    try:
        played = [
            play(
                policy,
                env,
                episode_seed(config.seed, 2, k),
                size,
                f"episode {k + 1}",
                shows_success,
            )
            for k in range(episodes)
        ]
    finally:
        env.close()  # the GL context goes before the interpreter does
    out.mkdir(parents=True, exist_ok=True)
    video = out / "watch.mp4"
    encode_mp4(np.concatenate([e.frames for e in played]), video, fps)
    returns = ", ".join(f"{e.total:.1f}" for e in played)
    sheet = contact_sheet(played, out / "contact_sheet.png", f"{config.task}: returns {returns}")
    return played, video, sheet

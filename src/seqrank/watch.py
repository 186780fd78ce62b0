"""Look at a trained agent: its saved policy plays N evaluation episodes, recorded as an
mp4 with the running true return (and success, on tasks that report it) under each frame,
and a contact sheet PNG of frames across the episodes (like the paper's Figures 5-10)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from seqrank.agents.protocol import Policy
from seqrank.envs import SimEnv, make_env
from seqrank.envs.scoring import Metric, task_metric
from seqrank.training.state import episode_seed
from seqrank.video import encode_mp4

CELL, LINE, FONT = 7, 22, 9  # pixels per character and per line, and points, at full size
SMALLEST_CELL = 4  # the narrowest characters a caption shrinks to before it wraps more
MOST_LINES = 2  # lines a caption may take at full size before its characters shrink
GAP = "  "  # between the fields of a line


@dataclass(frozen=True)
class Episode:
    frames: np.ndarray  # (T, size + caption height, size, 3) uint8, captioned
    total: float
    success: bool | None  # None where the task has no success signal (as reports score it)


@dataclass(frozen=True)
class _Played:
    frames: list[np.ndarray]  # (size, size, 3) each, uncaptioned
    captions: list[list[str]]  # each frame's fields: episode, step, return (, success)
    total: float
    success: bool


def play(
    policy: Policy, env: SimEnv, seed: int, size: int, label: str, shows_success: bool
) -> _Played:
    """One deterministic episode, rendered step by step, with each frame's caption."""
    obs, _ = env.reset(seed=seed)
    frames, captions, total, success, done, step = [], [], 0.0, False, False, 0
    generator = torch.Generator().manual_seed(seed % 2**31)
    while not done:
        frames.append(env.render_frame(size, size))
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, True, generator))
        total, step = total + float(reward), step + 1
        success = success or bool(info.get("success", False))
        done = bool(terminated or truncated)
        fields = [label, f"step {step}", f"return {total:.1f}"]
        captions.append(
            fields + ([f"success {'yes' if success else 'no'}"] if shows_success else [])
        )
    return _Played(frames, captions, total, success)


@dataclass(frozen=True)
class CaptionLayout:
    """Where a caption's fields go under a frame `width` pixels wide: `lines` (the fields'
    indices, line by line) of characters `cell` pixels wide. One layout serves a whole
    video, whose frames must share a height."""

    width: int
    cell: int
    lines: tuple[tuple[int, ...], ...]

    @property
    def line_height(self) -> int:
        """Even, so that the frame stays of an even height (H.264's yuv420p needs one)."""
        return 2 * round(LINE * self.cell / CELL / 2)

    @property
    def height(self) -> int:
        return self.line_height * len(self.lines)

    def texts(self, fields: list[str]) -> list[str]:
        """Each line's text, a space of margin first."""
        return [" " + GAP.join(fields[k] for k in line) for line in self.lines]


def fit_caption(width: int, longest: list[int]) -> CaptionLayout:
    """The layout of fields at most `longest` characters each: full-size characters in at
    most `MOST_LINES` lines where they fit; else the largest characters (down to
    `SMALLEST_CELL`) that fit as many lines as that; else a field a line, characters as
    wide as fit."""
    for cell in range(CELL, SMALLEST_CELL - 1, -1):
        lines = _pack(longest, width // cell - 1)
        if lines is not None and len(lines) <= MOST_LINES:
            return CaptionLayout(width, cell, lines)
    cell = max(1, min(SMALLEST_CELL, width // (max(longest) + 1)))
    return CaptionLayout(width, cell, tuple((k,) for k in range(len(longest))))


def _pack(longest: list[int], room: int) -> tuple[tuple[int, ...], ...] | None:
    """Fields in order, as many a line as `room` characters hold; None if one is longer."""
    if max(longest) > room:
        return None
    lines: list[list[int]] = [[]]
    used = 0
    for k, length in enumerate(longest):
        needed = length if not lines[-1] else used + len(GAP) + length
        if needed > room:
            lines.append([])
            needed = length
        lines[-1].append(k)
        used = needed
    return tuple(tuple(line) for line in lines)


class _Captions:
    """White monospace text on black under each frame, as `layout` places it: each
    character is drawn once by matplotlib and kept, so a caption per frame costs only a
    concatenation."""

    def __init__(self, layout: CaptionLayout):
        self.layout = layout
        self.glyphs: dict[str, np.ndarray] = {}

    def glyph(self, char: str) -> np.ndarray:
        if char not in self.glyphs:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            cell, high = self.layout.cell, self.layout.line_height
            figure = Figure(figsize=(cell / 100, high / 100), dpi=100, facecolor="black")
            size = FONT * cell / CELL
            figure.text(
                0.5,
                0.5,
                char,
                color="white",
                fontsize=size,
                ha="center",
                va="center",
                family="monospace",
            )
            canvas = FigureCanvasAgg(figure)
            canvas.draw()
            self.glyphs[char] = np.asarray(canvas.buffer_rgba())[:high, :cell, :3].copy()
        return self.glyphs[char]

    def render(self, fields: list[str]) -> np.ndarray:
        layout = self.layout
        bar = np.zeros((layout.height, layout.width, 3), np.uint8)
        for k, text in enumerate(layout.texts(fields)):
            row = np.concatenate([self.glyph(c) for c in text], axis=1)[:, : layout.width]
            bar[k * layout.line_height : (k + 1) * layout.line_height, : row.shape[1]] = row
        return bar


def captioned(played: list[_Played], size: int) -> list[Episode]:
    """The episodes with their captions under each frame, in one layout that fits the
    longest caption of them all (every frame of the video one height)."""
    fields = [fields for episode in played for fields in episode.captions]
    longest = [max(len(f[k]) for f in fields) for k in range(len(fields[0]))]
    captions = _Captions(fit_caption(size, longest))
    return [
        Episode(
            np.stack(
                [
                    np.concatenate([frame, captions.render(caption)], axis=0)
                    for frame, caption in zip(e.frames, e.captions, strict=True)
                ]
            ),
            e.total,
            e.success,
        )
        for e in played
    ]


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


def _has_success(task: str, rows: list[dict[str, Any]]) -> bool:
    """Whether success is shown: where `seqrank report` scores the task by it."""
    rates = [row.get("eval_success_rate") or 0.0 for row in rows if row.get("kind") == "eval"]
    return task_metric(task, rates) is Metric.SUCCESS


def watch(
    run_dir: Path, episodes: int, out: Path, size: int = 256, fps: int = 30
) -> tuple[list[Episode], Path, Path]:
    """Play `episodes` evaluation episodes of the run's saved policy; write `out/watch.mp4`
    and `out/contact_sheet.png`."""
    from seqrank.training.agent_factory import load_policy
    from seqrank.training.runs import RunDir

    run = RunDir.open(run_dir)
    config = run.read_config()
    env = make_env(config.task, config.seed)
    env.use_fast_rendering()  # no shadows: 7x faster, as the labelling clips
    policy = load_policy(run_dir, env)
    shows = _has_success(config.task, run.read_metrics())
    try:
        raw = [
            play(policy, env, episode_seed(config.seed, 2, k), size, f"episode {k + 1}", shows)
            for k in range(episodes)
        ]
    finally:
        env.close()  # the GL context goes before the interpreter does
    played = captioned(raw, size)
    if not shows:
        played = [replace(e, success=None) for e in played]
    out.mkdir(parents=True, exist_ok=True)
    video = out / "watch.mp4"
    encode_mp4(np.concatenate([e.frames for e in played]), video, fps)
    returns = ", ".join(f"{e.total:.1f}" for e in played)
    sheet = contact_sheet(played, out / "contact_sheet.png", f"{config.task}: returns {returns}")
    return played, video, sheet

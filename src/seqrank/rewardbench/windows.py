"""Pools that follow a learning policy (issue 46, item 2): `--window-steps N` cuts the
run that made a pool into windows of N steps, and session k of a cell asks only about the
episodes that ended in window k, as an online run sees its recent data; each budget's
row is scored on the next window, the data the policy goes on to collect.

An episode's end is the run's step count when it ended: the sum of the lengths of the
run's episodes up to it, in `origin` order (the pool's random-play episodes take no part).
Window k holds the episodes whose last step lies within steps [kN, (k+1)N), that is those
that ended after step kN and by step (k+1)N, as `--until-step` counts an episode ended by
a step. Window k is complete when the run reached step (k+1)N: the run's steps are those
its pool shows, the end of its last episode. Only complete windows are used.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from seqrank.episodes import EpisodeStore, Segments
from seqrank.rewardbench.order import CollectionOrder
from seqrank.rewardbench.pool import Pool


def episode_windows(pool: Pool, window_steps: int) -> list[np.ndarray]:
    """Each complete window's episodes (pool indices, in run order). A ValueError names a
    pool whose run episodes do not start at the run's start or skip some, and a window in
    which no episode ended."""
    run = _run_episodes(pool)
    ends = np.cumsum(pool.length[run])
    complete = int(ends[-1]) // window_steps
    place = (ends - 1) // window_steps  # the window of each episode's last step
    windows = [run[place == k] for k in range(complete)]
    for k, episodes in enumerate(windows):
        if not len(episodes):
            longest = int(pool.length[run].max())
            raise ValueError(
                f"--window-steps {window_steps}: no episode of the pool's run ended within "
                f"window {k} (steps {k * window_steps} to {(k + 1) * window_steps - 1}); its "
                f"episodes are up to {longest} steps long: give --window-steps {longest} "
                "or more"
            )
    return windows


def sessions_asked(budgets: Sequence[int], session_questions: int) -> int:
    """The sessions a scripted cell asks: full sessions, each cut short where it would
    pass a budget (as `bench._CellRun.ask_until` asks them); ceil(max budget / session
    questions) when every budget is a multiple of the session's questions."""
    sessions, asked = 0, 0
    for budget in budgets:
        while asked < budget:
            asked += min(session_questions, budget - asked)
            sessions += 1
    return sessions


def checked_windows(
    pool: Pool, window_steps: int, budgets: Sequence[int], session_questions: int
) -> list[np.ndarray]:
    """`episode_windows`, refused (a ValueError that says what the pool has and what the
    budgets need) when there are too few: one per session, and one more to score the last
    session's row on."""
    windows = episode_windows(pool, window_steps)
    sessions = sessions_asked(budgets, session_questions)
    if len(windows) < sessions + 1:
        run_steps = int(pool.length[_run_episodes(pool)].sum())
        widest = run_steps // (sessions + 1)
        raise ValueError(
            f"--window-steps {window_steps}: the pool's run ({run_steps} steps) has "
            f"{len(windows)} complete window{'s' * (len(windows) != 1)}, and budgets up to "
            f"{max(budgets)} at {session_questions} questions a session need {sessions + 1} "
            f"({sessions} session{'s' * (sessions != 1)}, one window each, and the next to "
            f"score on): give --window-steps {widest} or less, smaller budgets, or a pool of "
            "a longer run"
        )
    return windows


def _run_episodes(pool: Pool) -> np.ndarray:
    """The pool's run episodes in run order; a ValueError unless they are the run's
    episodes 0, 1, 2, ... with none missing (their end steps could not be known)."""
    run = np.flatnonzero(pool.origin >= 0)
    run = run[np.argsort(pool.origin[run], kind="stable")]
    origins = pool.origin[run]
    if not len(run):
        raise ValueError("--window-steps: the pool holds no episode of a run, only random play")
    first, last = int(origins[0]), int(origins[-1])
    if first != 0 or not np.array_equal(origins, np.arange(len(run))):
        missing = sorted(set(range(last + 1)) - set(origins.tolist()))
        shown = ", ".join(map(str, missing[:5])) + (", ..." if len(missing) > 5 else "")
        raise ValueError(
            f"--window-steps: the pool holds {len(run)} of its run's episodes {first} to "
            f"{last}, not all of 0 to {last} (missing: {shown}); windows count steps from "
            "the run's start and need every episode from 0 on (made from a run that kept "
            "only its last episodes: make the pool from a run with episodes_kept at least "
            "its episode count)"
        )
    return run


class WindowedEpisodes:
    """A cell's episodes under `--window-steps`: session k's from window k, the
    unlabelled ones (SURF's) from windows 0 to k, and the row after session k scored on a
    fixed sample of window k + 1."""

    def __init__(
        self,
        pool: Pool,
        windows: list[np.ndarray],
        collection: bool,
        segment_length: int,
        heldout_count: int,
    ) -> None:
        self.pool, self.windows, self.collection = pool, windows, collection
        self.segment_length, self.heldout_count = segment_length, heldout_count

    def for_session(self, session: int) -> EpisodeStore:
        which = self.windows[session]
        return CollectionOrder(self.pool, which) if self.collection else self.pool.store(which)

    def margin(self, session: int) -> float:
        """B-Pref's margin from the window's episodes, as a run's from its recent ones."""
        return self.pool.margin(self.windows[session], self.segment_length)

    def seen(self, sessions: int) -> EpisodeStore:
        return self.pool.store(np.concatenate(self.windows[:sessions]))

    def heldout(self, sessions: int) -> Segments:
        """The next window's: what the policy collects after the last session asked."""
        which = self.windows[sessions]
        return self.pool.heldout_segments(which, self.heldout_count, self.segment_length)

    def row_fields(self, sessions: int) -> dict[str, int]:
        return {"window": sessions - 1, "scored_window": sessions}

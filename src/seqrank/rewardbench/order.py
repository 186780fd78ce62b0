"""The order a session's new segments come in (issue 46, item 2): `uniform`, as a run
draws them (`EpisodeStore.sample_segments`: a uniform episode, a uniform start, in the
order drawn), or `collection`: the same segments, from the same draws of the same stream,
given in the order they were collected (the pool's `origin`: the episode's number in its
run, random play, -1, first; then the start within the episode). A stream in collection
order brings later, better segments to challenge an early root, as the paper's section
D.6 counts suggest its stream did."""

from __future__ import annotations

import copy

import numpy as np

from seqrank.episodes import EpisodeStore, Segments
from seqrank.rewardbench.pool import Pool


class CollectionOrder(EpisodeStore):
    """A pool's episodes `which`, cut as a run cuts them, each sample sorted by when its
    segments were collected."""

    def __init__(self, pool: Pool, which: np.ndarray) -> None:
        super().__init__(max(len(which), 1))
        for episode in pool.store(which).episodes:
            self.add(episode)
        self.origins = pool.origin[which]

    def sample_segments(
        self, count: int, length: int, rng: np.random.Generator, last: int = 0
    ) -> Segments:
        """`EpisodeStore.sample_segments`'s segments, in rising collection order: the
        draws it makes are read from a copy of `rng` first (an episode each, then a start
        each), which gives every segment's episode and start."""
        probe = copy.deepcopy(rng)
        cut = super().sample_segments(count, length, rng, last)
        episodes = list(self.episodes)[-last:] if last else list(self.episodes)
        origins = self.origins[-last:] if last else self.origins
        which = probe.integers(len(episodes), size=count)
        starts = np.array(
            [probe.integers(max(len(episodes[e].reward) - length, 0) + 1) for e in which]
        )
        order = np.lexsort((starts, which, origins[which]))  # by origin, episode, then start
        return Segments(
            cut.features[order],
            cut.rewards[order],
            [cut.states[k] for k in order],
            [cut.contexts[k] for k in order],
        )

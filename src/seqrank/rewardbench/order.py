"""The order a session's new segments come in (issue 46, item 2): `uniform`, as a run
draws them (`EpisodeStore.sample_segments`: a uniform episode, a uniform start, in the
order drawn), or `collection`: the same segments, from the same draws of the same stream,
given in the order they were collected (the pool's `origin`: the episode's number in its
run, random play, -1, first; then the start within the episode). A stream in collection
order brings later, better segments to challenge an early root, as the paper's section
D.6 counts suggest its stream did."""

from __future__ import annotations

import numpy as np

from seqrank.episodes import EpisodeStore
from seqrank.rewardbench.pool import Pool


class CollectionOrder(EpisodeStore):
    """A pool's episodes `which`, cut as a run cuts them, each sample sorted by when its
    segments were collected."""

    def __init__(self, pool: Pool, which: np.ndarray) -> None:
        super().__init__(max(len(which), 1))
        for episode in pool.store(which).episodes:
            self.add(episode)
        self.origins = pool.origin[which]

    def collected(self, which: np.ndarray, last: int = 0) -> np.ndarray:
        """The pool's `origin` of each episode (random play first, then the run's episodes
        by number): a pool's store is not in collection order."""
        origins = self.origins[-last:] if last else self.origins
        return np.asarray(origins[which])

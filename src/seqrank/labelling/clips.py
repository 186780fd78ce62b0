"""Clips for the page: segments re-rendered from saved physics states, as small H.264 mp4.

MuJoCo's headless GL context belongs to the thread that made it, so one worker thread owns
the simulator used for rendering and serves requests in priority order: a clip the page is
waiting for goes before clips rendered ahead of time. Clips are cached on disk by segment id
and written atomically, so a clip file is either complete or absent.

`close()` ends the worker, which frees its GL contexts itself: a context still current on a
live thread when the interpreter exits (MuJoCo's EGL calls eglTerminate at exit) crashes the
process with a segmentation fault.
"""

from __future__ import annotations

import itertools
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path

import numpy as np

from seqrank.video import encode_mp4

URGENT, AHEAD = 0, 1


# Frames for a segment id: (states, context) -> frames; built in the worker thread.
FrameSource = Callable[[int], np.ndarray]
# A frame source and what frees its simulator's GL contexts (called on the worker thread).
FrameMaker = Callable[[], tuple[FrameSource, Callable[[], None]]]
CLOSE_WAIT_S = 60.0  # a clip being rendered is finished first


class ClipRenderer:
    """Renders clips on one worker thread; `clip()` blocks, `ahead()` does not."""

    def __init__(self, directory: Path, make_frames: FrameMaker, fps: int = 30):
        self.directory, self.fps = Path(directory), fps
        self._make_frames = make_frames
        self._queue: queue.PriorityQueue[tuple[int, int, int, Future[Path]]] = queue.PriorityQueue()
        self._order = itertools.count()
        self._pending: dict[int, Future[Path]] = {}
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._work, name="clip-renderer", daemon=True)
        self._thread.start()

    def path(self, segment_id: int) -> Path:
        return self.directory / f"{segment_id}.mp4"

    def clip(self, segment_id: int, timeout: float = 120.0) -> Path:
        """The clip's file, rendered now if it is not cached (errors are raised here)."""
        return self._submit(segment_id, URGENT).result(timeout)

    def ahead(self, segment_ids: list[int]) -> None:
        for segment_id in segment_ids:
            self._submit(segment_id, AHEAD)

    def close(self) -> None:
        """End the worker (after the clip it is rendering) once its GL contexts are freed."""
        self._queue.put((-1, -1, -1, Future()))
        self._thread.join(timeout=CLOSE_WAIT_S)

    def _submit(self, segment_id: int, priority: int) -> Future[Path]:
        done: Future[Path] = Future()
        if self.path(segment_id).exists():
            done.set_result(self.path(segment_id))
            return done
        with self._lock:
            pending = self._pending.get(segment_id)
            if pending is not None and priority == AHEAD:
                return pending
            if pending is None:
                self._pending[segment_id] = done
            else:  # urgent request for a clip queued ahead: queue it again in front
                done = pending
        self._queue.put((priority, next(self._order), segment_id, done))
        return done

    def _work(self) -> None:
        made: tuple[FrameSource, Callable[[], None]] | None = None
        try:
            while True:
                priority, _, segment_id, done = self._queue.get()
                if priority < 0:
                    return
                if done.done():
                    continue
                try:
                    if not self.path(segment_id).exists():
                        if made is None:
                            made = self._make_frames()
                        encode_mp4(made[0](segment_id), self.path(segment_id), self.fps)
                    done.set_result(self.path(segment_id))
                except Exception as error:  # reported to whoever waits on this clip
                    done.set_exception(error)
                finally:
                    with self._lock:
                        self._pending.pop(segment_id, None)
        finally:
            if made is not None:  # on this thread, where its contexts are current
                made[1]()

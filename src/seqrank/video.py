"""Video files: RGB frames as an H.264 mp4 that browsers play."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import av
import numpy as np


def encode_mp4(frames: np.ndarray, path: Path, fps: int) -> None:
    """Write RGB frames (T, H, W, 3) as an H.264 mp4 that browsers play (yuv420p, faststart)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.part")
    height, width = frames.shape[1:3]
    with av.open(str(partial), mode="w", format="mp4", options={"movflags": "+faststart"}) as out:
        stream = out.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.options = {"crf": "20", "preset": "veryfast"}
        for frame in frames:
            image = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
            out.mux(stream.encode(image))
        out.mux(stream.encode(None))
    os.replace(partial, path)

"""`seqrank label offline --dataset`: the labelling page asks about a dataset's segments,
shows their clips (rendered from the physics states the dataset keeps) and saves the
answers in the label file."""

from __future__ import annotations

import httpx
import numpy as np

from seqrank.cli import main
from seqrank.feedback.label_file import read_label_file
from seqrank.offline.minari_io import load_dataset
from support.pages import start_command


def test_the_page_asks_about_a_datasets_segments(tmp_path, capsys):
    data = tmp_path / "data"
    code = main(["dataset", "make", "--task", "dmc:cartpole_swingup", "--source", "random",
                 "--episodes", "1", "--out", str(data)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    out = tmp_path / "labels"
    command = ["label", "offline", "--dataset", str(data), "--scheme", "root",
               "--questions", "3", "--port", "0", "--out", str(out)]  # fmt: skip
    process, url = start_command(command)
    try:
        for _ in range(3):
            question = _question(url)
            clip = httpx.get(url + question["left"]["clip"], timeout=120)
            assert clip.status_code == 200 and clip.content[4:8] == b"ftyp"  # an mp4
            reply = httpx.post(f"{url}/api/answer", json={"question_id": question["id"],
                               "choice": "left", "latency_ms": 5})  # fmt: skip
            assert reply.status_code == 200
        assert process.wait(60) == 0
    finally:
        if process.poll() is None:
            process.kill()
    labels = read_label_file(out / "labels.jsonl")
    assert len(labels.answers) == 3 and labels.header["task"] == "dmc:cartpole_swingup"
    rows = load_dataset(data)
    steps = np.concatenate([rows.observations, rows.actions], 1)
    for segment in labels.segments.values():  # each a window of the dataset's rows
        features = np.asarray(segment["features"], np.float32)
        start = int(np.flatnonzero((steps == features[0]).all(1))[0])
        np.testing.assert_array_equal(steps[start : start + len(features)], features)


def _question(url: str) -> dict:
    import time

    for _ in range(1200):
        state = httpx.get(f"{url}/api/state").json()
        if state["status"] == "question":
            return state["question"]
        time.sleep(0.05)
    raise AssertionError("no question was shown")

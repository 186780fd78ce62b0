"""Make docs/labelling-page.png: the page on walker_walk (root scheme), in headless Chromium.

Run from the repository root after `make install`:  .venv/bin/python scripts/screenshot_page.py
"""

from __future__ import annotations

import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
from playwright.sync_api import sync_playwright

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "labelling"))
from test_labelling_browser import CHROMIUM, CHROMIUM_ARGS

from seqrank.labelling.app import (
    OfflineOptions,
    PageServer,
    ServerOptions,
    open_hub,
    run_offline,
)


def main() -> None:
    directory = Path(tempfile.mkdtemp()) / "labels"
    options = ServerOptions(port=0, countdown_s=3.0, annotator="p01", size=192)
    hub = open_hub(directory, "dmc:walker_walk", options)
    server = PageServer(hub, options)
    server.start()
    offline = OfflineOptions("dmc:walker_walk", "root", 10, 1, 50, 2, 0, None)
    threading.Thread(target=run_offline, args=(directory, offline, hub, print), daemon=True).start()
    api = server.url.rstrip("/")
    for choice in ("right", "left"):  # two answers, so the page shows question 3 of 10
        while (state := httpx.get(f"{api}/api/state").json())["status"] != "question":
            time.sleep(0.1)
        body = {"question_id": state["question"]["id"], "choice": choice, "latency_ms": 900}
        httpx.post(f"{api}/api/answer", json=body)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1000, "height": 760})
        page.goto(server.url)
        page.wait_for_function(
            "() => ['left-video', 'right-video']"
            ".every(id => document.getElementById(id).readyState >= 3)"
        )
        page.wait_for_timeout(1200)  # clips play and the countdown runs down a little
        out = Path("docs/labelling-page.png")
        page.screenshot(path=str(out))
        browser.close()
    hub.stop.set()
    server.stop()
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""The real page in Debian's headless Chromium, driven by Playwright: keyboard, clicks,
a time-out and a reload mid-session; the database must hold exactly the given answers."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import pytest

from seqrank.labelling.app import OfflineOptions, PageServer, ServerOptions, open_hub, run_offline

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
    "--autoplay-policy=no-user-gesture-required",
]

sync_api = pytest.importorskip("playwright.sync_api")
if not Path(CHROMIUM).exists():  # `make test` installs Debian's chromium; say so if it is absent
    pytest.fail(f"{CHROMIUM} not found: install Debian's chromium (make test does)", pytrace=False)


def serve_offline(directory: Path, task: str, scheme: str, questions: int, countdown: float):
    hub = open_hub(directory, task, ServerOptions(port=0, countdown_s=countdown, annotator="e2e"))
    server = PageServer(hub, ServerOptions(port=0))
    server.start()
    options = OfflineOptions(task, scheme, questions, 1, 50, 1, 0, None)
    thread = threading.Thread(
        target=run_offline, args=(directory, options, hub, lambda text: None), daemon=True
    )
    thread.start()
    return hub, server, thread


def open_page(playwright, url: str):
    browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
    page = browser.new_page(viewport={"width": 1100, "height": 820})
    page.goto(url)
    return browser, page


def wait_question(page, number: int, total: int) -> None:
    page.wait_for_function(
        f"document.getElementById('progress').textContent.includes('question {number} of {total}')"
        " && !document.getElementById('left').disabled",
        timeout=60_000,
    )


def test_a_whole_session_by_keyboard_click_timeout_and_reload(tmp_path):
    hub, server, thread = serve_offline(
        tmp_path / "labels", "dmc:cartpole_swingup", "sequential", 6, 3.0
    )
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            wait_question(page, 1, 6)
            # the clips really play in the browser (H.264 decodes)
            page.wait_for_function(
                "['left-video', 'right-video']"
                ".every(id => document.getElementById(id).readyState >= 2)",
                timeout=30_000,
            )
            roles = page.locator(".role").all_inner_texts()
            assert sorted(roles) == ["defender · stays", "new challenger"]
            defender_side = "left" if "defender" in page.inner_text("#left-role") else "right"

            page.wait_for_timeout(1500)  # a person's time to decide: the next clips render
            page.evaluate("window.answeredAt = performance.now()")
            page.keyboard.press("ArrowLeft")
            page.wait_for_function(  # the next question's clips decoded and showing
                "document.getElementById('progress').textContent.includes('question 2 of 6')"
                " && ['left-video', 'right-video']"
                ".every(id => document.getElementById(id).readyState >= 2)",
                timeout=30_000,
            )
            shown_after = page.evaluate("performance.now() - window.answeredAt")
            print(f"\nnext question's clips shown {shown_after:.0f} ms after the answer")
            wait_question(page, 2, 6)
            page.click("#right")
            wait_question(page, 3, 6)
            page.keyboard.press("e")
            wait_question(page, 4, 6)
            # no answer: the 3 s countdown runs out and the question counts as timed out
            page.wait_for_function(
                "document.getElementById('progress').textContent.includes('question 5 of 6')",
                timeout=30_000,
            )
            page.reload()  # mid-session: the page picks up at the first unanswered question
            wait_question(page, 5, 6)
            assert "defender" in page.inner_text(f"#{defender_side}-role")  # same side still
            page.click("#skip")
            wait_question(page, 6, 6)
            page.keyboard.press("ArrowRight")
            page.wait_for_selector("#done:not([hidden])", timeout=30_000)
            browser.close()
        thread.join(30)
        stored = hub.db.answered_questions()
        assert [a.choice for _, a in stored] == [
            "left",
            "right",
            "equal",
            "timeout",
            "skip",
            "right",
        ]
        assert [q.index for q, _ in stored] == [0, 1, 2, 3, 4, 5]
        assert all(a.annotator == "e2e" for _, a in stored)
        timed_out = stored[3][1]
        assert 2900 <= timed_out.latency_ms <= 6000  # the countdown, measured by the page
        assert all(a.latency_ms < 3000 for _, a in stored[:3])
    finally:
        hub.stop.set()
        server.stop()
        hub.renderer.close()
        hub.db.close()


def test_the_survey_form_sends_satisfaction_and_criteria(tmp_path):
    hub = open_hub(tmp_path / "labels", "dmc:cartpole_swingup", ServerOptions(annotator="p07"))
    hub.scheme, hub.survey_run = "root", "root"
    hub.set_phase("survey", "survey about the root method")
    server = PageServer(hub, ServerOptions(port=0))
    server.start()
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            page.wait_for_selector("#survey:not([hidden])", timeout=30_000)
            page.check("input[name=satisfaction][value='4']")
            page.fill("#criteria", "distance moved, then posture")
            page.click("#survey-submit")
            page.wait_for_function("document.getElementById('error').hidden", timeout=10_000)
            browser.close()
        for _ in range(100):
            if hub.db.survey("root") is not None:
                break
            threading.Event().wait(0.05)
        row = hub.db.survey("root")
        assert (row["scheme"], row["satisfaction"], row["annotator"]) == ("root", 4, "p07")
        assert row["criteria"] == "distance moved, then posture"
    finally:
        hub.stop.set()
        server.stop()
        hub.renderer.close()
        hub.db.close()

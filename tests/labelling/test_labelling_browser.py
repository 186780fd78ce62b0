"""The real page in Debian's headless Chromium, driven by Playwright: keyboard, clicks,
a time-out and a reload mid-session; the database must hold exactly the given answers.
Answers that fail (500, no reply, answered in another tab) are retried or shown, never
dropped in silence; pages from other origins can neither read nor write."""

from __future__ import annotations

import shutil
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import httpx
import pytest

from seqrank.cli import main
from seqrank.labelling.app import OfflineOptions, PageServer, ServerOptions, open_hub, run_offline
from seqrank.labelling.db import LabelDB
from seqrank.labelling.human import Stopped
from support.pages import start_command

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


TASK = "dmc:cartpole_swingup"


def serve_offline(
    directory: Path,
    task: str,
    scheme: str,
    questions: int,
    countdown: float,
    token=None,
    playback="side-by-side",
):
    options = ServerOptions(
        port=0, token=token, countdown_s=countdown, annotator="e2e", playback=playback
    )
    hub = open_hub(directory, task, options)
    server = PageServer(hub, ServerOptions(port=0))
    server.start()
    options = OfflineOptions(task, scheme, questions, 1, 50, 1, 0, None)

    def drive() -> None:
        with suppress(Stopped):  # the test stopped the server while a question was waiting
            run_offline(directory, options, hub, lambda text: None)

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    return hub, server, thread


def open_page(playwright, url: str, clock: bool = False, extra_args: tuple[str, ...] = ()):
    """A browser and its page at `url`; `clock`: the page's timers can be fast-forwarded."""
    args = [*CHROMIUM_ARGS, *extra_args]
    browser = playwright.chromium.launch(executable_path=CHROMIUM, args=args)
    page = browser.new_page(viewport={"width": 1100, "height": 820})
    if clock:
        page.clock.install()
    page.goto(url)
    return browser, page


def stop(hub, server) -> None:
    hub.stop.set()
    server.stop()
    hub.renderer.close()
    hub.db.close()


def httpx_question(url: str) -> dict:
    for _ in range(1200):
        state = httpx.get(f"{url}/api/state").json()
        if state["status"] == "question":
            return state["question"]
        time.sleep(0.05)
    raise AssertionError("no question was shown")


@contextmanager
def serve_html(html: str) -> Iterator[str]:
    """A second, unrelated web server on another port of this machine, serving one page."""

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def wait_results(page) -> dict:
    page.wait_for_function("() => window.results && window.results.done", timeout=30_000)
    page.wait_for_timeout(1000)  # the form's post goes out after the fetches
    return page.evaluate("() => window.results")


def wait_question(page, number: int, total: int) -> None:
    page.wait_for_function(
        "() => document.getElementById('progress').textContent"
        f".includes('question {number} of {total}')"
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
                "() => ['left-video', 'right-video']"
                ".every(id => document.getElementById(id).readyState >= 2)",
                timeout=30_000,
            )
            roles = page.locator(".role").all_inner_texts()
            assert sorted(roles) == ["defender · stays", "new challenger"]
            defender_side = "left" if "defender" in page.inner_text("#left-role") else "right"

            page.keyboard.press("ArrowLeft")
            wait_question(page, 2, 6)
            page.click("#right")
            wait_question(page, 3, 6)
            page.keyboard.press("e")
            wait_question(page, 4, 6)
            # no answer: the 3 s countdown runs out and the question counts as timed out
            page.wait_for_function(
                "() => document.getElementById('progress').textContent.includes('question 5 of 6')",
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
        stop(hub, server)


def test_the_survey_form_sends_satisfaction_and_criteria(tmp_path):
    hub = open_hub(tmp_path / "labels", "dmc:cartpole_swingup", ServerOptions(annotator="p07"))
    hub.state.open_survey("root", "root", "survey about the root method")
    server = PageServer(hub, ServerOptions(port=0))
    server.start()
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            page.wait_for_selector("#survey:not([hidden])", timeout=30_000)
            page.check("input[name=satisfaction][value='4']")
            page.fill("#criteria", "distance moved, then posture")
            page.click("#survey-submit")
            page.wait_for_function("() => document.getElementById('error').hidden", timeout=10_000)
            browser.close()
        for _ in range(100):
            if hub.db.survey("root") is not None:
                break
            threading.Event().wait(0.05)
        row = hub.db.survey("root")
        assert (row["scheme"], row["satisfaction"], row["annotator"]) == ("root", 4, "p07")
        assert row["criteria"] == "distance moved, then posture"
    finally:
        stop(hub, server)


def error_text(page) -> str:
    return page.inner_text("#error") if page.is_visible("#error") else ""


def wait_error(page, text: str, timeout: float = 20_000) -> None:
    page.wait_for_function(
        f"() => document.getElementById('error').textContent.includes({text!r})", timeout=timeout
    )


def test_failed_and_unanswered_deliveries_are_retried_and_said_so(tmp_path):
    hub, server, thread = serve_offline(tmp_path / "labels", TASK, "sequential", 2, 0.0)
    held = []  # routes of requests left unanswered: the page must give up on them and retry

    def flaky(route):
        held.append(route)
        if len(held) == 1:
            route.fulfill(status=500, json={"detail": "database is busy"})
        elif len(held) > 2:
            route.continue_()
        # the second request gets no reply at all

    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url, clock=True)
            page.route("**/api/answer", flaky)
            wait_question(page, 1, 2)
            page.click("#left")
            wait_error(page, "Server busy (error 500): your answer is kept, retrying in 1 s")
            while len(held) < 2:
                page.wait_for_timeout(50)
            page.clock.fast_forward("00:16")  # past the page's 15 s limit for a reply
            wait_error(page, "No reply from the server in 15 s: your answer is kept, retrying in")
            wait_question(page, 2, 2)
            assert len(held) == 3 and error_text(page) == ""
            page.unroute("**/api/answer")
            page.route("**/api/answer", lambda route: route.abort("failed"))
            page.click("#right")
            wait_error(page, "The server cannot be reached: your answer is kept")
            page.reload()  # the kept answer survives the reload: the new page sends it first
            wait_error(page, "The server cannot be reached: your answer is kept")
            assert "right" in page.evaluate("() => sessionStorage.getItem(PENDING)")
            page.unroute("**/api/answer")
            page.wait_for_selector("#done:not([hidden])", timeout=30_000)
            browser.close()
        thread.join(30)
        assert [a.choice for _, a in hub.db.answered_questions()] == ["left", "right"]
    finally:
        stop(hub, server)


def test_an_answer_refused_as_answered_elsewhere_is_shown_then_the_page_moves_on(tmp_path):
    token = "a-token-for-this-test-only"
    hub, server, thread = serve_offline(tmp_path / "labels", TASK, "pairwise", 2, 0.0, token)
    api = server.url.partition("?")[0] + "api"
    other_tab = httpx.Client(headers={"x-seqrank-token": token})
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            wait_question(page, 1, 2)
            # the token has left the address bar; the cookie (out of the page's reach) and
            # nothing else carries it, clips included
            assert "token" not in page.url and page.evaluate("() => document.cookie") == ""
            page.wait_for_function(
                "() => ['left-video', 'right-video']"
                ".every(id => document.getElementById(id).readyState >= 2)",
                timeout=30_000,
            )
            asked = other_tab.get(f"{api}/state").json()["question"]
            body = {"question_id": asked["id"], "choice": "right", "latency_ms": 5}
            elsewhere: list[int] = []

            def answer_elsewhere_first(route):
                # the other tab answers while this page's answer is on its way: had it
                # answered before the click, the page's poll (every 1.5 s) could show the
                # next question first and the click would answer that one
                elsewhere.append(other_tab.post(f"{api}/answer", json=body).status_code)
                route.continue_()

            page.route("**/api/answer", answer_elsewhere_first)
            page.click("#left")
            wait_error(page, "This question was answered in another tab or window")
            page.unroute("**/api/answer")
            assert elsewhere == [200]
            shown = time.monotonic()
            assert "already answered 'right'" in error_text(page)
            wait_question(page, 2, 2)
            assert time.monotonic() - shown >= 3.0  # long enough to read
            assert error_text(page) == ""
            page.click("#left")
            page.wait_for_selector("#done:not([hidden])", timeout=30_000)
            browser.close()
        thread.join(30)
        stored = hub.db.answered_questions()
        assert [(q.id, a.choice) for q, a in stored[:1]] == [(asked["id"], "right")]
        assert [a.choice for _, a in stored] == ["right", "left"]
    finally:
        other_tab.close()
        stop(hub, server)


ATTACK = """<!doctype html><title>elsewhere</title>
<iframe name="sink"></iframe>
<form id="csrf" method="post" enctype="text/plain" action="TARGET/api/answer" target="sink">
<input name='{"question_id": QUESTION, "choice": "left", "latency_ms": 1, "x": "' value='"}'>
</form>
<script>
window.results = {};
async function attempt(name, request) {
  try {
    const reply = await request();
    window.results[name] = reply.type === "opaque" ? "opaque" : await reply.text();
  } catch (error) { window.results[name] = "blocked"; }
}
const body = JSON.stringify({question_id: QUESTION, choice: "left", latency_ms: 1});
(async () => {
  await attempt("state", () => fetch("TARGET/api/state"));
  await attempt("labels", () => fetch("TARGET/api/labels.jsonl"));
  await attempt("json", () => fetch("TARGET/api/answer",
    {method: "POST", headers: {"Content-Type": "application/json"}, body}));
  await attempt("no-cors", () => fetch("TARGET/api/answer",
    {method: "POST", mode: "no-cors", headers: {"Content-Type": "text/plain"}, body}));
  document.getElementById("csrf").submit();
  window.results.done = true;
})();
</script>"""


# rebind.test resolves to this machine. Chromium's own Private Network Access would stop the
# rebound page before the server sees it: it is off, standing for browsers without it, so
# that the server's Host check is what is tested.
REBINDING = (
    "--host-resolver-rules=MAP rebind.test 127.0.0.1",
    "--disable-features=LocalNetworkAccessChecks,"
    "PrivateNetworkAccessSendPreflights,PrivateNetworkAccessRespectPreflightResults",
)


def test_pages_from_another_origin_can_neither_read_nor_write(tmp_path, caplog):
    """A page on another port of this machine, and one whose name is re-pointed at the
    server (DNS rebinding), against the token-less default: nothing read, nothing stored."""
    hub, server, _ = serve_offline(tmp_path / "labels", TASK, "pairwise", 2, 0.0)
    target = server.url.rstrip("/")
    try:
        question = httpx_question(target)
        attack = ATTACK.replace("QUESTION", str(question["id"]))
        with (
            serve_html(attack.replace("TARGET", target)) as elsewhere,
            sync_api.sync_playwright() as playwright,
        ):
            browser, page = open_page(playwright, elsewhere, extra_args=REBINDING)
            results = wait_results(page)
            rebound = f"http://rebind.test:{server.port}"
            own_origin = attack.replace("TARGET", "")

            def before_rebinding(route):  # served by the attacker's name before re-pointing
                route.fulfill(body=own_origin, content_type="text/html")

            page.route(f"{rebound}/attack", before_rebinding)
            page.goto(f"{rebound}/attack")
            rebinding = wait_results(page)
            browser.close()
        for outcome in (results, rebinding):
            read = " ".join(str(value) for value in outcome.values())
            assert '"status"' not in read and '"header"' not in read, outcome  # state, labels
            assert outcome["state"] in ("blocked", "opaque") or "not an address" in outcome["state"]
        assert "not an address this server serves" in rebinding["state"]  # refused by Host
        refused = [r.getMessage() for r in caplog.records if r.name.endswith("access")]
        assert any("POST /api/answer (403): requests from" in m for m in refused), refused
        assert hub.db.answered_questions() == []
    finally:
        stop(hub, server)


WATCH_NEXT_CLIPS = """(progress) => {
    const started = performance.now();
    window.clipsShownAfter = null;
    const check = () => {
        const shown = document.getElementById('progress').textContent.includes(progress)
            && ['left-video', 'right-video']
                .every(id => document.getElementById(id).readyState >= 2);
        if (shown) window.clipsShownAfter = performance.now() - started;
        else setTimeout(check, 1);
    };
    check();
}"""


def test_the_next_clips_show_moments_after_an_answer(tmp_path):
    """Once the session's clips are rendered (ahead, while the person decides), the next
    question's clips show from the page's memory: printed, not asserted (machines differ)."""
    hub, server, _ = serve_offline(tmp_path / "labels", TASK, "sequential", 4, 0.0)
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            wait_question(page, 1, 4)
            deadline = time.monotonic() + 120
            while not (hub.upcoming and all(hub.renderer.path(s).exists() for s in hub.upcoming)):
                assert time.monotonic() < deadline, "the session's clips were never rendered"
                time.sleep(0.1)
            page.wait_for_timeout(2500)  # the page's next look at the state loads them
            delays = []
            for number in (2, 3, 4):
                # timed inside the page, from the key press to the first moment the next
                # question's two clips are decoded (checked every millisecond)
                page.evaluate(WATCH_NEXT_CLIPS, f"question {number} of 4")
                page.keyboard.press("ArrowLeft")
                page.wait_for_function("() => window.clipsShownAfter !== null", timeout=30_000)
                delays.append(page.evaluate("() => window.clipsShownAfter"))
            shown = ", ".join(f"{d:.0f}" for d in delays)
            print(f"\nnext question's clips shown {shown} ms after each answer")
            assert all(
                src.startswith("blob:")
                for src in page.evaluate(
                    "() => ['left-video', 'right-video'].map(id => document.getElementById(id).src)"
                )
            )  # from memory, not fetched after the answer
            browser.close()
    finally:
        stop(hub, server)


def test_clips_can_play_one_after_the_other(tmp_path):
    """The study's instructions: the two clips play in turn, the resting one dimmed."""
    hub, server, _ = serve_offline(
        tmp_path / "labels", TASK, "pairwise", 2, 0.0, playback="one-after-another"
    )
    playing = (
        "() => ['left-video', 'right-video'].map(id => document.getElementById(id))"
        ".map(v => !v.paused && !v.classList.contains('resting'))"
    )
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, server.url)
            wait_question(page, 1, 2)
            # each state is waited for as a whole: a clip is short, so a second look taken
            # after the wait may already see the next turn (a loaded machine)
            left_only = f"() => ({playing})().join() === 'true,false'"
            right_only = f"() => ({playing})().join() === 'false,true'"
            page.wait_for_function(left_only, timeout=30_000)  # left first, right waits
            page.wait_for_function(right_only, timeout=30_000)  # then right, left rests
            page.wait_for_function(left_only, timeout=30_000)  # and again
            assert page.evaluate(playing) != [True, True]  # never both at once
            page.keyboard.press("ArrowLeft")
            wait_question(page, 2, 2)
            browser.close()
        assert [a.choice for _, a in hub.db.answered_questions()] == ["left"]
    finally:
        stop(hub, server)


def test_the_fine_tuning_study_in_the_browser(tmp_path):
    """`label study --finetune` from a trained run, answered in Chromium: clips in turn,
    two parts of 10 questions, then the survey; the command ends by itself."""
    sizes = ["--hidden", "32", "--batch", "32", "--reward-hidden", "32", "--device", "cpu"]
    source = tmp_path / "trained"
    trained = ["train", "--task", TASK, "--reward", "true", "--steps", "1000", "--quiet"]
    assert (
        main(
            [*trained, "--eval-every", "1000", "--eval-episodes", "1", "--out", str(source), *sizes]
        )
        == 0
    )
    study = tmp_path / "study"
    args = ["label", "study", "--participant", "p1", "--study-dir", str(study), "--finetune"]
    args += ["--start-from", str(source), "--parts", "low,varied", "--methods", "root"]
    args += ["--eval-episodes", "1", "--reward-epochs", "3", "--heldout-pairs", "20"]
    args += ["--countdown", "0", "--port", "0", "--size", "64", "--playback", "one-after-another"]
    process, url = start_command([*args, *sizes])
    try:
        with sync_api.sync_playwright() as playwright:
            browser, page = open_page(playwright, url)
            for session in (1, 2):
                for number in range(1, 11):
                    page.wait_for_function(
                        "() => document.getElementById('progress').textContent"
                        f".includes('session {session}') && document.getElementById('progress')"
                        f".textContent.includes('question {number} of 10')"
                        " && !document.getElementById('left').disabled",
                        timeout=120_000,
                    )
                    if (session, number) == (1, 1):  # the clips play in turn
                        page.wait_for_function(
                            "() => document.getElementById('right-video')"
                            ".classList.contains('resting')",
                            timeout=30_000,
                        )
                    page.keyboard.press("ArrowLeft")
            page.wait_for_selector("#survey:not([hidden])", timeout=120_000)
            page.check("input[name=satisfaction][value='5']")
            page.click("#survey-submit")
            assert process.wait(300) == 0
            browser.close()
    finally:
        if process.poll() is None:
            process.kill()
    db = LabelDB.in_dir(study / "p1")
    assert len(db.answered_questions("root")) == 20 and db.survey("root")["satisfaction"] == 5
    db.close()


def test_two_annotators_answer_side_by_side_in_two_browsers_and_the_operator_sees_both(
    tmp_path,
):
    from seqrank.labelling.crowd_team import open_team, team_addresses

    directory = tmp_path / "labels"
    hub = open_hub(directory, TASK, ServerOptions(port=0, countdown_s=0.0))
    open_team(hub, ["alice", "bob"], 0.0, 60.0)
    server = PageServer(hub, ServerOptions(port=0))
    server.start()
    options = OfflineOptions(TASK, "sequential", 6, 1, 50, 1, 0, None, "full", ("alice", "bob"))

    def drive() -> None:
        with suppress(Stopped):
            run_offline(directory, options, hub, lambda text: None)

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    addresses = dict(team_addresses(hub, server.base))
    clickable = (
        "() => !document.getElementById('left').disabled"
        " && !document.getElementById('asking').hidden"
    )
    try:
        with sync_api.sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            pages = {}
            for name in ("alice", "bob"):  # a context each: their own cookie
                context = browser.new_context(viewport={"width": 1100, "height": 820})
                pages[name] = context.new_page()
                pages[name].goto(addresses[name])
            for page in pages.values():  # both have a question open at the same time
                page.wait_for_function(clickable, timeout=60_000)
            assert "annotator: alice" in pages["alice"].inner_text("#who")
            assert "annotator: bob" in pages["bob"].inner_text("#who")
            clicks = dict.fromkeys(pages, 0)
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and not all(
                p.is_visible("#done") for p in pages.values()
            ):
                for name, page in pages.items():
                    if page.evaluate(clickable):
                        page.click("#left")
                        clicks[name] += 1
                        page.wait_for_timeout(100)
            assert all(p.is_visible("#done") for p in pages.values())
            operator = browser.new_context().new_page()
            operator.goto(addresses["operator"])
            operator.wait_for_selector("#annotators tbody tr[data-annotator='bob']", timeout=30_000)
            shown = operator.locator("#annotators tbody tr").all_inner_texts()
            progress = operator.inner_text("#progress")
            browser.close()
        thread.join(30)
        stored = hub.db.answered_questions()
        assert len(stored) == 6 == sum(clicks.values())
        by = {a.annotator for _, a in stored}
        assert by == {"alice", "bob"} and all(c > 0 for c in clicks.values())
        assert [row.split()[0] for row in shown] == ["alice", "bob"]
        assert "session 1: 6 of 6 answered" in progress
    finally:
        stop(hub, server)

// The labelling page: shows what /api/state says and sends answers without dropping one.
// An answer is kept (in sessionStorage, so a reload keeps it too) and resent until the server
// acknowledges it; the server makes resends harmless. Server errors and silence are retried
// with backoff, saying so on the page; a refusal the person can act on ends the resending and
// stays readable for a few seconds (409: the question was answered elsewhere) before moving on.
"use strict";

// The access token came in the address (?token=...): the server has traded it for a cookie,
// so it leaves the address bar and the history; every request below relies on the cookie.
if (location.search) history.replaceState(null, "", location.pathname);

const REQUEST_TIMEOUT_MS = 15000;
const RETRY_DELAYS_S = [1, 2, 4, 8, 15];
const READ_MS = 4000;      // how long a message stays up before the page moves on
const PENDING = "seqrank-pending-answer";
const $ = (id) => document.getElementById(id);
const sections = ["asking", "waiting", "survey", "done"];

let current = null;      // the question on screen
let busy = false;        // an answer is on its way
let shownAt = 0;         // when the countdown started (ms, performance clock)
let countdownS = 0;
let timerFrame = 0;
let pollTimer = 0;
let answeredAt = -1e9;   // when the last answer was acknowledged (ms, performance clock)
let answeredId = null;   // the question last answered here, never shown again
let playback = "side-by-side"; // or "one-after-another": each clip plays in turn
const CLIPS_KEPT = 40;
// clip address -> {objectUrl, video}: its bytes in memory and a video element that has
// decoded its first frame already (used once, by swapping it into place); null: loading
const clips = new Map();
const shownClips = () => new Set(["left-video", "right-video"].map((id) => $(id).dataset.clip));

// Load the clips the server offers while the person decides: the next question's clips
// then show at once. The oldest are let go beyond CLIPS_KEPT.
function prefetch(urls) {
  for (const url of urls || []) {
    if (clips.has(url)) continue;
    clips.set(url, null);
    fetch(url, { credentials: "same-origin" })
      .then((response) => (response.ok ? response.blob() : null))
      .then((blob) => {
        if (!blob) return clips.delete(url);
        const objectUrl = URL.createObjectURL(blob);
        clips.set(url, { objectUrl, video: decodedVideo(objectUrl) });
      })
      .catch(() => clips.delete(url));
  }
  const shown = shownClips();
  for (const [url, entry] of clips) {
    if (clips.size <= CLIPS_KEPT) break;
    if (entry === null || shown.has(url)) continue;
    URL.revokeObjectURL(entry.objectUrl);
    clips.delete(url);
  }
}

function decodedVideo(src) {
  const video = document.createElement("video");
  Object.assign(video, { muted: true, loop: true, playsInline: true, autoplay: true, preload: "auto" });
  video.src = src;
  video.load();
  return video;
}

// Put clip `url` on one side: a clip already there stays (the defender keeps playing), a
// decoded one is swapped in, anything else loads from memory or from the server.
function placeClip(name, url) {
  let video = $(`${name}-video`);
  video.loop = playback !== "one-after-another";
  video.classList.remove("resting");
  if (video.dataset.clip === url && video.readyState >= 2) return;
  const entry = clips.get(url);
  if (entry && entry.video) {
    entry.video.id = video.id;
    video.replaceWith(entry.video);
    video = entry.video;
    entry.video = null; // in the page now; a later showing loads from memory
  } else {
    video.src = entry ? entry.objectUrl : url; // the cookie carries the access
    video.load();
  }
  video.loop = playback !== "one-after-another";
  video.classList.remove("resting");
  video.dataset.clip = url;
}

function show(name) {
  for (const s of sections) $(s).hidden = s !== name;
}

function showError(text) {
  const box = $("error");
  box.textContent = text;
  box.hidden = !text;
}

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
const detailOf = (reply) => {
  const detail = reply.data && reply.data.detail;
  return typeof detail === "string" ? detail : `error ${reply.status}`;
};

// One request with a time limit; throws on a network error or when no reply comes in time.
async function api(path, body) {
  const controller = new AbortController();
  const timer = setTimeout(() => controller.abort(), REQUEST_TIMEOUT_MS);
  const options = { signal: controller.signal, credentials: "same-origin" };
  if (body !== undefined) {
    Object.assign(options, {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
  }
  try {
    const response = await fetch(path, options);
    let data = null;
    try { data = await response.json(); } catch (_) { data = null; }
    return { ok: response.ok, status: response.status, data };
  } finally {
    clearTimeout(timer);
  }
}

// Send until the server answers something other than "try again" (5xx, 408, 429, a network
// error or no reply); the page says what happened and when the next try is.
async function sendUntilHeard(path, body, what) {
  for (let attempt = 0; ; attempt++) {
    let reply = null;
    let why = "";
    try {
      reply = await api(path, body);
    } catch (error) {
      why = error.name === "AbortError"
        ? `No reply from the server in ${REQUEST_TIMEOUT_MS / 1000} s`
        : "The server cannot be reached";
    }
    if (reply && reply.status < 500 && reply.status !== 408 && reply.status !== 429) return reply;
    if (reply) why = `Server busy (${reply.status >= 500 ? "error " : ""}${reply.status})`;
    const delay = RETRY_DELAYS_S[Math.min(attempt, RETRY_DELAYS_S.length - 1)];
    for (let left = delay; left > 0; left--) {
      showError(`${why}: ${what} is kept, retrying in ${left} s…`);
      await sleep(1000);
    }
    showError(`${why}: ${what} is kept, retrying now…`);
  }
}

function schedule(ms) {
  clearTimeout(pollTimer);
  pollTimer = setTimeout(poll, ms);
}

async function poll() {
  if (busy) return; // an answer is being delivered; the page polls once it is
  let reply;
  try {
    reply = await api("/api/state");
  } catch (_) {
    showError("The labelling server cannot be reached; retrying in 2 s…");
    return schedule(2000);
  }
  if (busy) return;
  if (!reply.ok) {
    const busyServer = reply.status >= 500 ? "Server busy, retrying in 3 s: " : "";
    showError(busyServer + detailOf(reply));
    return schedule(3000);
  }
  showError("");
  render(reply.data);
}

function render(state) {
  countdownS = state.countdown_s || 0;
  playback = state.playback || "side-by-side";
  $("who").textContent = state.annotator ? `annotator: ${state.annotator}` : "";
  $("clip-source").textContent = state.clip_source === "frames"
    ? "clips: frames recorded while the episode was played"
    : "clips: re-rendered from the saved simulator state";
  if (state.status === "question") {
    prefetch(state.prefetch);
    const q = state.question;
    if (q.id === answeredId) return schedule(40); // a reply sent before the answer landed
    const sessions = state.sessions ? ` of ${state.sessions}` : "";
    $("progress").textContent = `${state.scheme} · session ${q.session}${sessions} · question ${q.index} of ${q.questions}`;
    if (!current || current.id !== q.id) showQuestion(q);
    schedule(1500); // while the person decides: more clips may have been rendered
    show("asking");
    return;
  }
  current = null;
  stopCountdown();
  if (state.status === "survey") {
    $("progress").textContent = `survey: ${state.scheme}`;
    if ($("survey").hidden) $("survey-form").reset();
    $("survey-form").dataset.run = state.survey_run;
    show("survey");
    return;
  }
  if (state.status === "done") {
    $("progress").textContent = "finished";
    $("done-text").textContent = state.message || "";
    show("done");
    return schedule(5000);
  }
  $("progress").textContent = state.scheme ? `${state.scheme}` : "";
  $("waiting-text").textContent = state.message || "Please wait…";
  show("waiting");
  // right after an answer the next question is usually moments away: look again soon
  schedule(performance.now() - answeredAt < 3000 ? 40 : 1000);
}

function showQuestion(q) {
  clearTimeout(pollTimer);
  current = q;
  busy = false;
  shownAt = performance.now(); // restarted when both clips play
  stopCountdown();
  for (const name of ["left", "right"]) {
    const side = q[name];
    const box = $(`${name}-box`);
    box.classList.remove("chosen");
    box.classList.toggle("defender", side.role === "defender");
    const role = $(`${name}-role`);
    role.className = `role ${side.role || ""}`;
    role.textContent = side.role === "defender" ? "defender · stays" : side.role === "challenger" ? "new challenger" : "";
    placeClip(name, side.clip);
  }
  setButtons(true);
  $("countdown-text").textContent = countdownS > 0 ? "loading clips…" : "no time limit";
  $("countdown-bar").style.transform = "scaleX(1)";
  waitForClips(q.id);
}

function waitForClips(id) {
  const videos = [$("left-video"), $("right-video")];
  let started = false;
  const start = () => {
    if (started || !current || current.id !== id) return;
    started = true;
    if (playback === "one-after-another") playInTurn(videos, id);
    else for (const v of videos) v.play().catch(() => {});
    startCountdown();
  };
  for (const v of videos) v.dataset.ready = "";
  for (const v of videos) {
    const mark = () => { v.dataset.ready = "1"; if (videos.every((x) => x.dataset.ready)) start(); };
    if (v.readyState >= 2) { mark(); continue; } // decoded already: no event will come
    v.addEventListener("loadeddata", mark, { once: true });
    v.addEventListener("error", mark, { once: true });
  }
  setTimeout(start, 8000); // never let a slow clip block the page
}

// Left plays once, then right, then left again..., the resting one dimmed and paused.
function playInTurn(videos, id) {
  let turn = 0;
  const next = () => {
    if (!current || current.id !== id) return;
    videos.forEach((v, k) => {
      v.classList.toggle("resting", k !== turn);
      if (k !== turn) v.pause();
    });
    const playing = videos[turn];
    playing.loop = false;
    playing.currentTime = 0;
    playing.addEventListener("ended", () => { turn = 1 - turn; next(); }, { once: true });
    playing.play().catch(() => {});
  };
  next();
}

function startCountdown() {
  shownAt = performance.now();
  if (countdownS <= 0) { $("countdown-text").textContent = "no time limit"; return; }
  const tick = () => {
    const left = countdownS - (performance.now() - shownAt) / 1000;
    $("countdown-bar").style.transform = `scaleX(${Math.max(left, 0) / countdownS})`;
    $("countdown-text").textContent = left > 0 ? `${left.toFixed(1)} s left` : "time is up";
    if (left <= 0) { timerFrame = 0; answer("timeout"); return; }
    timerFrame = requestAnimationFrame(tick);
  };
  timerFrame = requestAnimationFrame(tick);
}

function stopCountdown() {
  if (timerFrame) cancelAnimationFrame(timerFrame);
  timerFrame = 0;
}

function setButtons(enabled) {
  for (const id of ["left", "right", "equal", "skip"]) $(id).disabled = !enabled;
}

async function answer(choice) {
  if (!current || busy) return;
  busy = true;
  stopCountdown();
  setButtons(false);
  if (choice === "left" || choice === "right") $(`${choice}-box`).classList.add("chosen");
  const latency = shownAt ? performance.now() - shownAt : 0;
  const body = { question_id: current.id, choice, latency_ms: Math.max(0, latency) };
  sessionStorage.setItem(PENDING, JSON.stringify(body));
  const reply = await deliver(body);
  if (reply) answeredId = body.question_id; // stored: a late reply showing it is stale
  current = null;
  busy = false;
  answeredAt = performance.now();
  // the reply carries the state after the answer: the next question shows without a poll
  if (reply && reply.ok && reply.data && reply.data.next) render(reply.data.next);
  else poll();
}

// Deliver a kept answer; it is forgotten only once the server has said what became of it.
async function deliver(body) {
  const reply = await sendUntilHeard("/api/answer", body, "your answer");
  if (reply.status === 401 || reply.status === 403) {
    // kept: once the page is opened again with the printed address, it is sent first
    showError(`Your answer is kept but the server refused it: ${detailOf(reply)}`);
    await sleep(READ_MS);
    return;
  }
  sessionStorage.removeItem(PENDING);
  if (reply.ok) {
    showError("");
    return reply;
  }
  const what = reply.status === 409
    ? "This question was answered in another tab or window, so this answer was not stored"
    : "Your answer was refused";
  showError(`${what} (${detailOf(reply)}). Moving on…`);
  await sleep(READ_MS);
  showError("");
}

// An answer kept from before a reload (or a refusal) is delivered before anything is shown.
async function resumeKept() {
  const kept = sessionStorage.getItem(PENDING);
  if (kept) {
    busy = true;
    let body = null;
    try { body = JSON.parse(kept); } catch (_) { sessionStorage.removeItem(PENDING); }
    if (body) await deliver(body);
    busy = false;
  }
  poll();
}

$("left").addEventListener("click", () => answer("left"));
$("right").addEventListener("click", () => answer("right"));
$("equal").addEventListener("click", () => answer("equal"));
$("skip").addEventListener("click", () => answer("skip"));

document.addEventListener("keydown", (event) => {
  if (event.target instanceof HTMLTextAreaElement || event.target instanceof HTMLInputElement) return;
  if ($("asking").hidden) return;
  const keys = { ArrowLeft: "left", ArrowRight: "right", ArrowUp: "equal", e: "equal", E: "equal", ArrowDown: "skip", s: "skip", S: "skip" };
  const choice = keys[event.key];
  if (choice) { event.preventDefault(); answer(choice); }
});

$("survey-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const form = event.target;
  const picked = form.querySelector("input[name=satisfaction]:checked");
  if (!picked) return;
  $("survey-submit").disabled = true;
  busy = true;
  const body = { run: form.dataset.run, satisfaction: Number(picked.value), criteria: $("criteria").value };
  const reply = await sendUntilHeard("/api/survey", body, "your survey");
  $("survey-submit").disabled = false;
  busy = false;
  if (!reply.ok) return showError(`The survey was refused: ${detailOf(reply)}`);
  showError("");
  poll();
});

resumeKept();

// The labelling page: shows what /api/state says, sends answers, never loses one.
// An answer is resent until the server acknowledges it (the server makes resends harmless).
"use strict";

const token = new URLSearchParams(location.search).get("token");
const headers = token ? { "X-Seqrank-Token": token } : {};
const $ = (id) => document.getElementById(id);
const sections = ["asking", "waiting", "survey", "done"];

let current = null;      // the question on screen
let busy = false;        // an answer is on its way
let shownAt = 0;         // when the countdown started (ms, performance clock)
let countdownS = 0;
let timerFrame = 0;
let pollTimer = 0;
let answeredAt = -1e9;   // when the last answer was acknowledged (ms, performance clock)

function show(name) {
  for (const s of sections) $(s).hidden = s !== name;
}

function showError(text) {
  const box = $("error");
  box.textContent = text;
  box.hidden = !text;
}

async function api(path, body) {
  const options = body === undefined
    ? { headers }
    : { method: "POST", headers: { ...headers, "Content-Type": "application/json" }, body: JSON.stringify(body) };
  const response = await fetch(path, options);
  let data = null;
  try { data = await response.json(); } catch (_) { data = null; }
  return { ok: response.ok, status: response.status, data };
}

function schedule(ms) {
  clearTimeout(pollTimer);
  pollTimer = setTimeout(poll, ms);
}

async function poll() {
  let reply;
  try {
    reply = await api("/api/state");
  } catch (_) {
    showError("The labelling server cannot be reached; retrying…");
    return schedule(2000);
  }
  if (!reply.ok) {
    showError(reply.data && reply.data.detail ? reply.data.detail : `server error ${reply.status}`);
    return schedule(3000);
  }
  showError("");
  render(reply.data);
}

function render(state) {
  countdownS = state.countdown_s || 0;
  $("who").textContent = state.annotator ? `annotator: ${state.annotator}` : "";
  if (state.status === "question") {
    const q = state.question;
    const sessions = state.sessions ? ` of ${state.sessions}` : "";
    $("progress").textContent = `${state.scheme} · session ${q.session}${sessions} · question ${q.index} of ${q.questions}`;
    if (!current || current.id !== q.id) showQuestion(q);
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

function clipUrl(side) {
  return token ? `${side.clip}?token=${encodeURIComponent(token)}` : side.clip;
}

function showQuestion(q) {
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
    const video = $(`${name}-video`);
    video.dataset.ready = "";
    video.src = clipUrl(side);
    video.load();
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
    for (const v of videos) v.play().catch(() => {});
    startCountdown();
  };
  for (const v of videos) {
    const mark = () => { v.dataset.ready = "1"; if (videos.every((x) => x.dataset.ready)) start(); };
    v.addEventListener("loadeddata", mark, { once: true });
    v.addEventListener("error", mark, { once: true });
  }
  setTimeout(start, 8000); // never let a slow clip block the page
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
  for (let attempt = 0; ; attempt++) {
    let reply;
    try {
      reply = await api("/api/answer", body);
    } catch (_) {
      showError("Your answer has not reached the server yet; retrying…");
      await new Promise((r) => setTimeout(r, Math.min(500 * 2 ** attempt, 5000)));
      continue;
    }
    if (!reply.ok) showError(reply.data && reply.data.detail ? reply.data.detail : `error ${reply.status}`);
    else showError("");
    break;
  }
  current = null;
  busy = false;
  answeredAt = performance.now();
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
  try {
    const reply = await api("/api/survey", {
      run: form.dataset.run, satisfaction: Number(picked.value), criteria: $("criteria").value,
    });
    showError(reply.ok ? "" : (reply.data && reply.data.detail) || `error ${reply.status}`);
  } catch (_) {
    showError("The survey could not be sent; please try again.");
  }
  $("survey-submit").disabled = false;
  poll();
});

poll();

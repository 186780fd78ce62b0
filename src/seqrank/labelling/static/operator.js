// The operator page: what /api/operator says of the team, refreshed every 2 seconds.
"use strict";
if (location.search) history.replaceState(null, "", location.pathname);
const $ = (id) => document.getElementById(id);
const REFRESH_MS = 2000;

const num = (value, digits) => (value === null || value === undefined ? "-" : value.toFixed(digits));

function cell(row, text, className) {
  const td = document.createElement("td");
  td.textContent = text;
  if (className) td.className = className;
  row.appendChild(td);
}

function showAnnotators(people) {
  const body = $("annotators").querySelector("tbody");
  body.replaceChildren();
  for (const p of people) {
    const row = document.createElement("tr");
    row.dataset.annotator = p.name;
    if (p.flagged) row.className = "flagged";
    cell(row, p.name + (p.flagged ? ` (flagged: estimated below ${p.flag_below})` : ""), p.flagged ? "flag" : "");
    cell(row, String(p.answers));
    cell(row, num(p.per_minute, 1));
    cell(row, String(p.timeouts));
    cell(row, p.median_latency_ms === null ? "-" : `${(p.median_latency_ms / 1000).toFixed(1)} s`);
    cell(row, String(p.handed_over));
    cell(row, num(p.kappa, 2));
    const checks = p.flagged || p.rests_on >= p.flag_after ? `${p.rests_on} checked` : `${p.rests_on} checked (a flag needs ${p.flag_after})`;
    cell(row, p.reliability === null ? "-" : `${num(p.reliability, 2)} [${num(p.low, 2)}, ${num(p.high, 2)}], ${checks}`);
    cell(row, p.gold_answered ? `${p.gold_right} of ${p.gold_answered} right` : "-");
    cell(row, p.address, "address");
    body.appendChild(row);
  }
}

function showChains(chains) {
  const body = $("chains").querySelector("tbody");
  body.replaceChildren();
  for (const c of chains) {
    const row = document.createElement("tr");
    cell(row, String(c.session));
    cell(row, String(c.chain));
    cell(row, c.owner || "(anyone free)");
    cell(row, `${c.answered} of ${c.questions}`);
    cell(row, c.continues === null ? "" : `chain ${c.continues}, handed over`);
    body.appendChild(row);
  }
}

// Who is asked again: two others while a member's shared answers are fewer than N, then a share.
function overlapText(view) {
  const share = `overlap ${view.overlap}`;
  return view.overlap_until > 0 ? `two others until ${view.overlap_until} shared, then ${share}` : share;
}

// The session's questions answered over all its chains; a handed-over chain's questions are
// its parent's unanswered ones, so only chains that continue none count toward the total.
function sessionProgress(chains) {
  if (!chains.length) return "";
  const session = chains[0].session;
  const answered = chains.reduce((sum, c) => sum + c.answered, 0);
  const questions = chains.filter((c) => c.continues === null).reduce((sum, c) => sum + c.questions, 0);
  return `session ${session}: ${answered} of ${questions} answered · `;
}

function showCurve(points) {
  const svg = $("curve");
  svg.replaceChildren();
  if (points.length < 2) {
    $("curve-note").textContent = points.length ? `eval return ${points[0].eval_return.toFixed(1)} at step ${points[0].step}` : "no evaluation yet";
    return;
  }
  const xs = points.map((p) => p.step), ys = points.map((p) => p.eval_return);
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const line = document.createElementNS("http://www.w3.org/2000/svg", "polyline");
  line.setAttribute("points", points.map((p) => `${10 + 580 * (p.step - x0) / (x1 - x0 || 1)},${190 - 180 * (p.eval_return - y0) / (y1 - y0 || 1)}`).join(" "));
  svg.appendChild(line);
  $("curve-note").textContent = `eval return ${y0.toFixed(1)} to ${y1.toFixed(1)}; last ${ys[ys.length - 1].toFixed(1)} at step ${xs[xs.length - 1]}`;
}

async function refresh() {
  try {
    const response = await fetch("/api/operator", { credentials: "same-origin" });
    if (!response.ok) throw new Error(`error ${response.status}`);
    const view = await response.json();
    $("progress").textContent = `${view.scheme || "-"} · ${view.phase} · ${sessionProgress(view.chains)}${overlapText(view)} · hand-over after ${view.reassign_after_s} s`;
    $("message").textContent = view.message;
    showAnnotators(view.annotators);
    showChains(view.chains);
    showCurve(view.curve);
    $("updated").textContent = `updated ${new Date().toLocaleTimeString()}`;
  } catch (error) {
    $("updated").textContent = `not updated (${error.message}); retrying`;
  }
  setTimeout(refresh, REFRESH_MS);
}
refresh();

"use strict";
// The shop overview: every machine as its bridge publishes it, pushed by the server as it
// changes (server-sent events), and the shop's history. It only reads.

const $ = (id) => document.getElementById(id);

// The page key (from /api/session): the Hold carries it, which only a page of the
// overview's own origin can read, so no other site's page can press it.
let pageKey = "";

// A machine's state in words and colour, as the console's banner says it.
const STATES = {
  idle: ["IDLE", "idle"],
  running: ["RUNNING", "run"],
  held: ["HELD", "held"],
  alarm: ["ALARM", "alarm"],
};

function span(seconds) {
  const s = Math.round(seconds);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60);
  return h ? `${h} h ${m} min` : m ? `${m} min ${s % 60} s` : `${s} s`;
}

function cell(row, text, className) {
  const c = row.insertCell();
  c.textContent = text;
  if (className) c.className = className;
  return c;
}

function render(machines) {
  const body = $("machines-table").querySelector("tbody");
  body.replaceChildren();
  $("machines-none").hidden = machines.length > 0;
  for (const m of machines) {
    const row = body.insertRow();
    row.dataset.machine = m.topic;
    row.className = m.online ? "" : "offline";
    cell(row, m.name || m.topic);
    const [word, colour] = m.online ? (STATES[m.state] || ["–", "idle"]) : ["OFFLINE", "offline"];
    const state = cell(row, word, "state " + colour);
    if (!m.online && m.offline) state.title = m.offline;
    cell(row, m.run ? (m.run.job || m.run.program) : "–");
    const p = m.progress;
    const progress = cell(row, "");
    if (p) {
      const bar = document.createElement("progress");
      bar.max = 100;
      bar.value = p.percent;
      progress.append(bar, ` ${p.percent.toFixed(1)} %` + (p.line ? `, line ${p.line}` : ""));
    } else {
      progress.textContent = "–";
    }
    cell(row, p && p.left_s !== undefined ? span(p.left_s) : "–");
    cell(row, m.feed_override ? m.feed_override + " %" : "–");
    const alarm = m.alarm ? `ALARM:${m.alarm.code} ${m.alarm.text}` : "";
    const last = m.last ? (m.last.completed ? "last run completed"
      : `last run stopped: ${m.last.reason || "?"}` + (m.last.resume_at ? `; resumes at line ${m.last.resume_at}` : "")) : "";
    cell(row, alarm || last || "–", alarm ? "alarm" : "");
    const bridge = cell(row, (m.bridge || "?") + " ");
    if (m.console) {
      const link = Object.assign(document.createElement("a"), { href: m.console, textContent: "console", rel: "noopener" });
      bridge.append(link);
    }
    const action = row.insertCell();
    if (m.online && m.state === "running") {
      const button = Object.assign(document.createElement("button"), { textContent: "Hold", className: "hold" });
      button.onclick = () => hold(m.topic);
      action.append(button);
    }
  }
}

// A Hold to a running machine's bridge; the machine's row says whether it held.
async function hold(machine) {
  $("hold-error").textContent = "";
  const response = await fetch("/api/shop/" + encodeURIComponent(machine) + "/hold", {
    method: "POST",
    headers: { "X-Whirl-Page": pageKey },
  });
  if (!response.ok) {
    const text = await response.text();
    let said = text;
    try { said = JSON.parse(text).error; } catch { /* plain words */ }
    $("hold-error").textContent = `Hold of ${machine} not sent: ${said}`;
  }
}

async function session() {
  const s = await (await fetch("/api/session")).json();
  pageKey = s.page_key;
  $("login-link").hidden = !s.token_required || s.authorised;
}

function connect() {
  const events = new EventSource("/api/shop/events");
  events.addEventListener("machines", (e) => {
    $("link-state").textContent = "live";
    $("link-state").className = "muted";
    render(JSON.parse(e.data));
  });
  events.onerror = () => {
    $("link-state").textContent = "the overview server cannot be reached: retrying";
    $("link-state").className = "alarm";
  };
}

async function history(event) {
  if (event) event.preventDefault();
  $("history-error").textContent = "";
  const q = new URLSearchParams();
  for (const key of ["machine", "since"]) {
    const value = $("history-" + key).value.trim();
    if (value) q.set(key, value);
  }
  const response = await fetch("/api/history?" + q);
  const answer = await response.json();
  if (!response.ok) {
    $("history-error").textContent = answer.error;
    return;
  }
  const body = $("history-table").querySelector("tbody");
  body.replaceChildren();
  for (const r of answer) {
    const row = body.insertRow();
    [r.id, r.machine || "–", r.kind, r.outcome, r.started_at.replace("T", " ").replace("Z", ""),
      r.job || r.program || "–", r.reason || ""].forEach((c, i) => cell(row, c, i === 3 ? "outcome-" + r.outcome : ""));
  }
}

$("history-form").addEventListener("submit", history);
session();
connect();
history();

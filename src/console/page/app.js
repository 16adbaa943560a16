// The whirl console's page: plain script, no build step, nothing from the internet.
// Runs live in the server; this page subscribes to them (server-sent events) and presses
// buttons through the API.
"use strict";

const $ = (id) => document.getElementById(id);
let views = [];
let grooveShown = { machine: null, executed: -1, at: 0 };

function show() {
  const page = (location.hash || "#run").slice(1);
  for (const p of document.querySelectorAll(".page")) {
    p.classList.toggle("current", p.id === "page-" + page);
  }
  for (const a of document.querySelectorAll("nav a")) {
    a.classList.toggle("current", a.id === "nav-" + page);
  }
  if (page === "history") history();
}
window.addEventListener("hashchange", show);

// The console's page key (from /api/session): every action carries it, which only a page
// of the console's own origin can read, so no other site's page can press a button.
let pageKey = "";

async function api(path, body) {
  const init = body === undefined ? {} : {
    method: "POST",
    headers: { "Content-Type": "application/json", "X-Whirl-Page": pageKey },
    body: JSON.stringify(body),
  };
  const response = await fetch(path, init);
  const text = await response.text();
  let data = null;
  try {
    data = text ? JSON.parse(text) : null;
  } catch {
    // A request the server could not read is answered in plain words (axum's).
    data = { error: text };
  }
  if (!response.ok) throw new Error(data && data.error ? data.error : response.statusText);
  return data;
}

function fill(select, names) {
  select.replaceChildren(...names.map((n) => new Option(n, n)));
}

function duration(s) {
  if (s === null || s === undefined) return "–";
  const m = Math.floor(s / 60);
  return m + ":" + String(Math.floor(s % 60)).padStart(2, "0");
}

// A span of time in words with its units: "1 h 10 min 53 s", "10 min 53 s", "53 s".
function span(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.max(0, Math.round(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), rest = s % 60;
  if (h > 0) return h + " h " + m + " min " + rest + " s";
  if (m > 0) return m + " min " + rest + " s";
  return rest + " s";
}

function mm(x) { return x.toFixed(4); }

// A SHA-256 as the page shows it: its first 12 hex digits, enough to tell files apart.
function short(sha) { return sha.slice(0, 12) + "…"; }

// A record's UTC time as "2026-05-01 14:03:27 UTC".
function utc(text) { return text ? text.replace("T", " ").replace(/\.\d+Z$/, "").replace("Z", "") + " UTC" : "–"; }

// What the run's program was planned from: the program, the job and machine profile by
// their hashes, the planned Δ, installation angle and feed.
function provenanceText(p) {
  if (!p) return "–";
  return p.program + " (sha256 " + short(p.program_sha256) + ") from job " + p.job +
    " (sha256 " + short(p.job_sha256) + ") for machine " + p.machine +
    (p.machine_sha256 ? " (profile sha256 " + short(p.machine_sha256) + ")" : " (its profile not read from a file)") +
    "; planned Δ " + p.delta_mm + " mm, installation angle " +
    p.installation_angle_deg.toFixed(3) + "°, axial feed " + p.axial_feed_mm + " mm/rev";
}

// How the console is reached and guarded, in one line (no secret in it): loopback or not,
// the host names it answers to, whether a token guards its actions.
function safetyText(s) {
  const reach = s.loopback ? "Loopback only (" + s.listen + ")" :
    "Reachable from the network at " + s.listen;
  const hosts = "answers to " + [...new Set(s.hosts)].join(", ");
  const guard = s.token_required ?
    "a token guards every action" + (s.authorised ? " (this page is logged in)" : " (log in to act)") :
    "no token: any program of this computer's users can act";
  return reach + "; " + hosts + "; " + guard + "; actions only from this page.";
}

// Who holds the chosen machine's lock (this console's run or a whirl stream of another
// terminal) and since when; fetched as runs change and every few seconds, for a lock
// taken outside this console tells no event.
let locks = [];
let locksAt = 0;

// At most one fetch a second as runs change, the last change always fetched after it.
let locksSoon = null;
function fetchLocksSoon() {
  if (locksSoon) return;
  const wait = Math.max(0, 1000 - (Date.now() - locksAt));
  locksSoon = setTimeout(() => { locksSoon = null; fetchLocks(); }, wait);
}

async function fetchLocks() {
  locksAt = Date.now();
  try {
    locks = await api("/api/locks");
  } catch {
    locks = [];
  }
  showLock();
}

function showLock() {
  const l = locks.find((x) => x.machine === $("run-machine").value);
  const line = $("run-lock");
  if (!l) { line.textContent = ""; return; }
  line.className = "lock" + (l.held ? " held" : "");
  line.textContent = l.held ?
    "Machine locked (" + l.what + ") by " + l.held.holder + (l.held.since ? " since " + utc(l.held.since) : "") :
    "Machine free (" + l.what + "): no run holds it.";
}

async function jobsPage(machines, jobs) {
  fill($("jobs-machine"), machines);
  const body = $("jobs-table").querySelector("tbody");
  body.replaceChildren();
  jobs.forEach((job, i) => {
    const row = body.insertRow();
    row.dataset.job = job;
    row.insertCell().textContent = job;
    for (const key of ["segments", "delta", "bound", "time", "verify"]) {
      row.insertCell().className = "job-" + key;
    }
    const actions = row.insertCell();
    const plan = document.createElement("button");
    plan.textContent = "Plan";
    plan.id = "plan-" + i;
    plan.onclick = () => planJob(row, "plan");
    const verify = document.createElement("button");
    verify.textContent = "Verify";
    verify.id = "verify-" + i;
    verify.onclick = () => planJob(row, "verify");
    const profile = document.createElement("button");
    profile.textContent = "Profile";
    profile.id = "profile-" + i;
    profile.onclick = () => showProfile(row.dataset.job);
    actions.append(plan, " ", verify, " ", profile);
  });
}

// The groove of the job picked, as whirl understood it: its facts and its axial section.
async function showProfile(job) {
  $("jobs-error").textContent = "";
  try {
    const r = await api("/api/profile?job=" + encodeURIComponent(job));
    $("profile-title").textContent = "Profile of " + r.job;
    const body = $("profile-facts").querySelector("tbody");
    body.replaceChildren();
    for (const f of r.facts) {
      const row = body.insertRow();
      row.insertCell().textContent = f.name;
      row.insertCell().textContent = f.value;
    }
    $("profile-plot").innerHTML = r.svg;
    $("job-profile").hidden = false;
  } catch (e) {
    $("jobs-error").textContent = job + ": " + e.message;
    $("job-profile").hidden = true;
  }
}

async function planJob(row, what) {
  $("jobs-error").textContent = "";
  const cell = (k) => row.querySelector(".job-" + k);
  cell(what === "plan" ? "segments" : "verify").textContent = "…";
  try {
    const r = await api("/api/" + what, { job: row.dataset.job, machine: $("jobs-machine").value });
    cell("segments").textContent = r.segments;
    cell("delta").textContent = r.delta_mm;
    cell("bound").textContent = mm(r.max_error_mm);
    cell("time").textContent = duration(r.cycle_time_s);
    if (r.verify) {
      const v = r.verify;
      cell("verify").textContent = (v.within_delta ? "within Δ" : "BEYOND Δ") +
        ": overcut " + mm(v.max_overcut_mm) + ", undercut " + mm(v.max_undercut_mm);
    }
    row.classList.add("planned");
  } catch (e) {
    $("jobs-error").textContent = row.dataset.job + ": " + e.message;
    cell(what === "plan" ? "segments" : "verify").textContent = "";
  }
}

function current() {
  const machine = $("run-machine").value;
  return views.find((v) => v.machine === machine);
}

// Whether the machine stands held, by the controller's own word: grbl's Hold:0, the
// register map's Held; the CANopen master's message that the drives stand on the path,
// not yet followed by a resume (drives report no state of the job).
function held(v) {
  const s = v.state || "";
  if (s.startsWith("Hold") || s === "Held") return true;
  const stood = v.messages.map((m) => m.includes("the drives stand on the path")).lastIndexOf(true);
  const resumed = v.messages.map((m) => m.startsWith("resume requested")).lastIndexOf(true);
  return stood > resumed;
}

// The machine's state for the banner: a word, its colour and what the operator does next.
function machineState(v) {
  if (!v) return ["NO RUN", "idle", "Choose a job, then dry-run it or stream it."];
  if (v.phase !== "running") {
    if (v.completed) return ["COMPLETED", "done", v.measured ? measuredText(v) : "The program ran to its end."];
    if (v.alarms.length) {
      return ["ALARM", "alarm", v.alarms[v.alarms.length - 1] + " — the run has ended" +
        (v.resume ? " at line " + v.resume.line + ": clear the alarm at the machine, then resume there below." :
          ": clear the alarm at the machine before another run.")];
    }
    if ((v.outcome || "").startsWith("stopped")) {
      return ["STOPPED", "held", v.resume ? "The run ended at line " + v.resume.line +
        ": resume there below, or start another run." : "The run ended where it stood."];
    }
    return ["FAILED", "alarm", (v.outcome || "") + " — see the messages below."];
  }
  if (v.alarms.length) {
    return ["ALARM", "alarm", v.alarms[v.alarms.length - 1] +
      " — the machine has stopped: Stop the run, clear the alarm at the machine, then resume at the line offered."];
  }
  if ((v.state || "").startsWith("Hold:1")) return ["HOLDING", "held", "Slowing to a stand along the path…"];
  if (held(v)) return ["HELD", "held", "Standing on the path: Resume to go on, or Stop to end the run here."];
  return ["RUNNING", "run", (v.line ? "Line " + v.line + " of " + v.total + ". " : "") + "Space bar or Hold: feed hold."];
}

function measuredText(v) {
  const m = v.measured;
  return (m.within_delta ? "within Δ" : "beyond Δ") + ": overcut " + mm(m.max_overcut_mm) +
    " mm, undercut " + mm(m.max_undercut_mm) + " mm (Δ " + m.delta_mm + " mm)";
}

// C within its turn, and the turn: 370.5° is 10.50° of turn 1 (turns counted from 0°).
function turnOf(c) {
  const turn = Math.floor(c / 360);
  return (c - 360 * turn).toFixed(2) + "° (turn " + turn + ")";
}

// The workpiece's speed from the last two views of a run: C's turns over machine time
// (wall time × the run's time scale).
let lastSeen = null;
function workpieceRpm(v) {
  if (!v.position) return null;
  const now = { id: v.id, c: v.position[2], t: v.elapsed_s * v.time_scale };
  const before = lastSeen;
  if (!before || before.id !== v.id || now.t <= before.t) {
    lastSeen = now;
    return null;
  }
  if (now.t - before.t < 0.5) return before.rpm;
  now.rpm = ((now.c - before.c) / 360) / (now.t - before.t) * 60;
  lastSeen = now;
  return now.rpm;
}

// The time left stops while the machine stands held (the rate it is reckoned from would
// make it grow).
let frozenLeft = null;

function render() {
  const v = current();
  const running = !!v && v.phase === "running";
  const standing = running && held(v);
  const [word, css, todo] = machineState(v);
  $("run-banner").className = "banner " + css;
  $("run-banner-word").textContent = word;
  $("run-banner-todo").textContent = todo;
  $("btn-hold").disabled = !running || standing;
  $("btn-resume").disabled = !standing;
  $("btn-stop").disabled = !running;
  if (!running) $("stop-confirm").hidden = true;
  $("run-start").disabled = running;
  $("run-stream").disabled = running;
  showLock();
  if (!v) return;
  const name = v.record ? "record " + v.record :
    "run " + v.id + (v.spooled ? " (its record in the spool)" : " (unrecorded)");
  $("run-title").textContent = name + ": " + v.job + " on " + v.machine + " over " +
    v.transport + " at " + v.time_scale + "×" + (v.resumed_at ? ", resumed at line " + v.resumed_at : "") +
    (running ? (standing ? " (held)" : " (running)") : " (ended)");
  $("run-state").textContent = running ? (v.state || "–") : "– (the run has ended)";
  $("run-line").textContent = v.line ? v.line + " of " + v.total : "–";
  $("run-around").replaceChildren(...v.around.map(([n, text]) => {
    const item = document.createElement("li");
    item.value = n;
    item.textContent = text;
    if (n === v.line) item.className = "executing";
    return item;
  }));
  $("run-ring").textContent = v.ring_rpm ? v.ring_rpm + " rpm (the program's S)" : "–";
  $("run-provenance").textContent = provenanceText(v.provenance);
  $("run-started").textContent = utc(v.started_at) + (v.started_by ? " by " + v.started_by : "");
  $("run-progress").value = v.total ? v.done / v.total : 0;
  $("run-done").textContent = v.done + " of " + v.total + " " + v.unit;
  $("run-elapsed").textContent = span(v.elapsed_s);
  if (standing && (!frozenLeft || frozenLeft.id !== v.id)) frozenLeft = { id: v.id, left: v.left_s };
  if (!standing) frozenLeft = null;
  const left = running ? (frozenLeft ? frozenLeft.left : v.left_s) : null;
  $("run-left").textContent = left === null || left === undefined ? "–" :
    span(left) + (standing ? " (held: waiting)" : "");
  // The wall clock's end at the pace so far (the same for any transport and time scale).
  const pace = running && !standing && v.done > 0 && v.done < v.total ?
    v.elapsed_s * (v.total - v.done) / v.done : null;
  $("run-finish").textContent = pace === null ? "–" :
    new Date(Date.now() + 1000 * pace).toLocaleTimeString() + " (at the pace so far)";
  const rpm = running && !standing ? workpieceRpm(v) : null;
  $("run-rpm").textContent = rpm === null || rpm === undefined ? "–" : Math.abs(rpm).toFixed(2) + " rpm (C)";
  const p = v.position;
  for (const [id, text] of [["x", p && p[0].toFixed(3)], ["z", p && p[1].toFixed(3)], ["c", p && turnOf(p[2])]]) {
    $("dro-" + id).textContent = text || "–";
    $("dro-w" + id).textContent = text || "–";
  }
  $("run-position").textContent = p ?
    "X " + p[0].toFixed(3) + " mm, Z " + p[1].toFixed(3) + " mm, C " + p[2].toFixed(2) + "°" : "–";
  $("run-link").textContent = v.link_use === null ? "–" : (100 * v.link_use).toFixed(1) + " %";
  $("run-outcome").textContent = v.outcome || "–";
  $("run-measured").textContent = v.measured && v.completed ? measuredText(v) :
    (running ? "–" : "not measured: the run stopped part way (resume it to finish the groove)");
  $("run-alarms").replaceChildren(...v.alarms.map((a) => Object.assign(document.createElement("li"), { textContent: a })));
  $("run-messages").replaceChildren(...v.messages.map((m) => Object.assign(document.createElement("li"), { textContent: m })));
  renderFeed(v, running);
  const offer = !running && v.resume && !v.completed;
  $("resume-offer").hidden = !offer;
  if (offer) {
    $("resume-text").textContent = "Stopped. Resume at line " + v.resume.line +
      (v.resume.possibly_run_to ? " (lines up to " + v.resume.possibly_run_to + " may have run: re-entering along the groove cuts them again harmlessly)" : "") + ".";
    $("btn-resume-at").textContent = "Resume at line " + v.resume.line;
  }
  groove(v);
}

// The feed override: offered from the controller's slowest up to the run's cap (the
// insert cusp within its share of Δ, or the controller's fastest), the cap's reason beside
// it, and the override the controller reports running at.
let feedShown = null;

function renderFeed(v, running) {
  const f = v.feed;
  $("feed").hidden = !f;
  if (!f) return;
  for (const id of ["feed-percent", "feed-set", "feed-down", "feed-reset", "feed-up"]) {
    $(id).disabled = !running;
  }
  const input = $("feed-percent");
  const slider = $("feed-slider");
  slider.disabled = !running;
  for (const box of [input, slider]) {
    box.min = f.cap.min_percent;
    box.max = f.cap.max_percent;
  }
  // The value asked into the box when it changes, not while the operator types; another
  // run's refusal or note cleared.
  const run = v.machine + "#" + v.id;
  if (feedShown === null || !feedShown.startsWith(run + ":")) {
    $("feed-error").textContent = "";
    $("feed-note").textContent = "";
  }
  const shown = run + ":" + f.asked;
  if (feedShown !== shown) {
    input.value = f.asked;
    slider.value = f.asked;
    feedShown = shown;
  }
  $("feed-cap").textContent = "Offered from " + f.cap.min_percent + " % up to the cap of " +
    f.cap.max_percent + " %: " + f.cap.reason;
  $("feed-running").textContent = f.running !== null ?
    "in effect: " + f.running + " % (as the controller reports)" :
    (f.asked === 100 ? "none asked" : "asked " + f.asked + " %, not yet reported running");
}

async function feed(ask) {
  $("feed-error").textContent = "";
  $("feed-note").textContent = "";
  try {
    const r = await api("/api/runs/" + encodeURIComponent($("run-machine").value) + "/feed-override", ask);
    if (r.held) $("feed-note").textContent = r.held;
  } catch (e) {
    $("feed-error").textContent = e.message;
  }
}

async function groove(v) {
  const now = Date.now();
  const fresh = grooveShown.machine !== v.machine || grooveShown.executed !== v.executed;
  if (!fresh || (v.phase === "running" && now - grooveShown.at < 2000)) return;
  grooveShown = { machine: v.machine, executed: v.executed, at: now };
  const response = await fetch("/api/runs/" + encodeURIComponent(v.machine) + "/groove.svg");
  if (response.status === 200) {
    $("groove-plot").innerHTML = await response.text();
    $("groove-caption").textContent = "Run #" + v.id + ", " + v.job + ": the axial section cut so far (" +
      v.executed + " executed moves) against the target, the error magnified, with the Δ band.";
  }
}

// History: the run records searched in the server (its database), fetched when the page
// is shown, searched, or a run ends; one run's whole record on a click.
let ended = new Set();

function historyQuery() {
  const q = new URLSearchParams();
  for (const key of ["job", "machine", "since", "until", "outcome"]) {
    const value = $("history-" + key).value.trim();
    if (value) q.set(key, value);
  }
  return q.toString();
}

async function history() {
  $("history-error").textContent = "";
  try {
    const runs = await api("/api/history?" + historyQuery());
    const body = $("history-table").querySelector("tbody");
    body.replaceChildren();
    for (const r of runs) {
      const row = body.insertRow();
      row.dataset.run = r.id;
      const how = { "plan": "nothing (a plan)", "dry-run": "simulator (dry run)", "stream": "MACHINE (stream)" }[r.mode];
      const cells = [r.id, r.kind, how, r.outcome, r.started_at.replace("T", " ").replace("Z", ""),
        took(r), r.machine || "–", r.host, r.job || r.program || "–", r.transport || "–",
        r.resume_at === null ? "–" : r.resume_at, r.reason || ""];
      cells.forEach((c, i) => {
        const cell = row.insertCell();
        cell.textContent = c;
        if (i === 2) cell.className = "mode-" + r.mode;
        if (i === 3) cell.className = "outcome-" + r.outcome;
      });
      row.onclick = () => historyRun(r.id);
    }
  } catch (e) {
    $("history-error").textContent = e.message;
  }
}

// How long a run took (a running one: so far, as the server read it).
function took(r) {
  if (r.duration_s === null || r.duration_s === undefined) return "–";
  return span(r.duration_s) + (r.ended_at ? "" : " so far");
}

async function historyRun(id) {
  $("history-error").textContent = "";
  try {
    const r = await api("/api/history/" + id);
    for (const row of $("history-table").querySelectorAll("tbody tr")) {
      row.classList.toggle("chosen", row.dataset.run === String(id));
    }
    $("history-run-title").textContent = "Run " + r.id + ": " + r.kind + ", " + r.outcome;
    const figures = [
      ["Started", r.started_at], ["Ended", r.ended_at], ["Why", r.reason],
      ["Machine", r.machine && r.machine + (r.machine_file ? " (" + r.machine_file.path + ", sha256 " + r.machine_file.sha256.slice(0, 12) + "…)" : "")],
      ["Job", r.job_file && r.job_file.path + " (sha256 " + r.job_file.sha256.slice(0, 12) + "…)"],
      ["Program", r.program_id && r.program_id.name + ": " + r.program_id.lines + " lines (sha256 " + r.program_id.sha256.slice(0, 12) + "…)"],
      ["Sent to", { "plan": "nothing (a plan)", "dry-run": "the simulator (a dry run)", "stream": "the machine (a stream)" }[r.mode]],
      ["Took", took(r)],
      ["Transport", r.transport && r.transport + (r.port ? " to " + r.port : " (dry run on the simulator)")],
      ["Measured", r.measured && (r.measured.within_delta ? "within Δ" : "not within Δ") + ": overcut " + mm(r.measured.max_overcut_mm) +
        " mm, undercut " + mm(r.measured.max_undercut_mm) + " mm (Δ " + r.measured.delta_mm + " mm)"],
      ["Resumed at", r.resume_from && "line " + r.resume_from + (r.resumes ? ", continuing run " + r.resumes : "")],
      ["Resume at", r.resume_at && "line " + r.resume_at + (r.possibly_run_to ? " (to line " + r.possibly_run_to + " may have run)" : "")],
      ["Host", r.host + ", process " + r.pid],
      ["Log", r.log && r.log.path],
    ].filter(([, v]) => v !== null && v !== undefined && v !== "");
    $("history-run-figures").replaceChildren(...figures.flatMap(([k, v]) => [
      Object.assign(document.createElement("dt"), { textContent: k }),
      Object.assign(document.createElement("dd"), { textContent: v, id: "history-run-" + k.toLowerCase().replace(" ", "-") }),
    ]));
    $("history-run-notes").replaceChildren(...r.notes.map((n) => Object.assign(document.createElement("li"), {
      textContent: (n.at || "") + " " + n.kind + (n.code !== null ? " " + n.code : "") +
        (n.line !== null ? " at line " + n.line : "") + ": " + n.text,
    })));
    $("history-run").hidden = false;
  } catch (e) {
    $("history-error").textContent = e.message;
  }
}

// A run that has just ended changes the history: fetched again if it is shown.
function historyOnEnd() {
  const now = new Set(views.filter((v) => v.phase === "ended").map((v) => v.machine + "#" + v.id));
  const fresh = [...now].some((k) => !ended.has(k));
  ended = now;
  if (fresh && location.hash === "#history") history();
}

async function press(button) {
  $("run-error").textContent = "";
  try {
    await api("/api/runs/" + encodeURIComponent($("run-machine").value) + "/" + button, {});
  } catch (e) {
    $("run-error").textContent = e.message;
  }
}

async function main() {
  show();
  const session = await api("/api/session");
  pageKey = session.page_key;
  $("login-link").hidden = !(session.token_required && !session.authorised);
  $("safety").textContent = safetyText(session);
  $("safety").classList.toggle("open", !session.loopback || !session.token_required);
  const [machines, jobs] = await Promise.all([api("/api/machines"), api("/api/jobs")]);
  await jobsPage(machines, jobs);
  fill($("run-machine"), machines);
  fill($("run-job"), jobs);
  // No job is chosen for the operator: the first in the list is no better a guess.
  $("run-job").prepend(new Option("— choose a job —", "", true, true));
  $("run-machine").onchange = render;
  fetchLocks();
  setInterval(fetchLocks, 5000);
  $("run-form").onsubmit = async (event) => {
    event.preventDefault();
    $("run-error").textContent = "";
    if (!$("run-job").value) {
      $("run-error").textContent = "Choose a job first.";
      return;
    }
    try {
      await api("/api/runs", {
        machine: $("run-machine").value,
        job: $("run-job").value,
        transport: $("run-transport").value,
        time_scale: Number($("run-scale").value),
      });
    } catch (e) {
      $("run-error").textContent = e.message;
    }
  };
  $("run-stream").onclick = async () => {
    $("run-error").textContent = "";
    if (!$("run-job").value) {
      $("run-error").textContent = "Choose a job first.";
      return;
    }
    try {
      await api("/api/runs", { machine: $("run-machine").value, job: $("run-job").value, stream: true });
    } catch (e) {
      $("run-error").textContent = e.message;
    }
  };
  $("history-form").onsubmit = (event) => { event.preventDefault(); history(); };
  $("btn-hold").onclick = () => press("hold");
  $("btn-resume").onclick = () => press("resume");
  // Stop ends the run: asked twice, on the page (not a dialog a stray key dismisses).
  $("btn-stop").onclick = () => { $("stop-confirm").hidden = false; $("btn-stop-confirm").focus(); };
  $("btn-stop-cancel").onclick = () => { $("stop-confirm").hidden = true; };
  $("btn-stop-confirm").onclick = () => { $("stop-confirm").hidden = true; press("stop"); };
  // The space bar holds a running machine, wherever the page's focus is but in a field of
  // the run form; it never starts or resumes motion.
  document.addEventListener("keydown", (event) => {
    if (event.code !== "Space" || event.repeat) return;
    const tag = event.target.tagName;
    if (tag === "INPUT" || tag === "SELECT" || tag === "TEXTAREA") return;
    const v = current();
    if (v && v.phase === "running" && !held(v)) {
      event.preventDefault();
      press("hold");
    }
  });
  $("feed-slider").oninput = () => { $("feed-percent").value = $("feed-slider").value; };
  $("feed-slider").onchange = () => feed({ percent: Number($("feed-slider").value) });
  $("btn-resume-at").onclick = () => press("resume-at");
  $("feed-set").onclick = () => feed({ percent: Number($("feed-percent").value) });
  $("feed-down").onclick = () => feed({ step: -10 });
  $("feed-reset").onclick = () => feed({ percent: 100 });
  $("feed-up").onclick = () => feed({ step: 10 });
  setInterval(fetchLocks, 3000);
  const events = new EventSource("/api/events");
  events.addEventListener("runs", (event) => {
    views = JSON.parse(event.data);
    $("link-state").textContent = "live";
    $("link-state").className = "muted";
    document.body.classList.remove("console-gone");
    render();
    historyOnEnd();
    fetchLocksSoon();
  });
  // The console gone is said at once, in red: its buttons no longer reach the machine.
  const gone = (words) => {
    $("link-state").textContent = words;
    $("link-state").className = "alarm";
    document.body.classList.add("console-gone");
  };
  events.addEventListener("gone", (event) => {
    events.close();
    gone("CONSOLE GONE: " + event.data + ". Nothing pressed here reaches the machine.");
  });
  events.onerror = () => gone("The console does not answer (reconnecting…): nothing pressed here reaches the machine.");
}

main().catch((e) => { $("run-error").textContent = e.message; });

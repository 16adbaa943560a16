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

function mm(x) { return x.toFixed(4); }

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
    actions.append(plan, " ", verify);
  });
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

function render() {
  const v = current();
  const running = !!v && v.phase === "running";
  $("btn-hold").disabled = !running;
  $("btn-resume").disabled = !running;
  $("btn-stop").disabled = !running;
  $("run-start").disabled = running;
  $("run-stream").disabled = running;
  if (!v) return;
  $("run-title").textContent = "#" + v.id + " " + v.job + " on " + v.machine + " over " +
    v.transport + " at " + v.time_scale + "×" + (v.resumed_at ? ", resumed at line " + v.resumed_at : "") +
    (running ? " (running)" : " (ended)");
  $("run-state").textContent = v.state || "–";
  $("run-line").textContent = v.line ? v.line + " of " + v.total : "–";
  $("run-progress").value = v.total ? v.done / v.total : 0;
  $("run-done").textContent = v.done + " of " + v.total + " " + v.unit;
  $("run-left").textContent = duration(v.left_s);
  $("run-position").textContent = v.position ?
    "X " + v.position[0].toFixed(3) + " mm, Z " + v.position[1].toFixed(3) + " mm, C " + v.position[2].toFixed(2) + "°" : "–";
  $("run-link").textContent = v.link_use === null ? "–" : (100 * v.link_use).toFixed(1) + " %";
  $("run-outcome").textContent = v.outcome || "–";
  $("run-measured").textContent = v.measured ?
    (v.measured.within_delta ? "within Δ" : "beyond Δ") + ": overcut " + mm(v.measured.max_overcut_mm) +
    " mm, undercut " + mm(v.measured.max_undercut_mm) + " mm (Δ " + v.measured.delta_mm + " mm)" : "–";
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
  input.min = f.cap.min_percent;
  input.max = f.cap.max_percent;
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
      const cells = [r.id, r.kind, r.outcome, r.started_at.replace("T", " ").replace("Z", ""),
        r.machine || "–", r.job || r.program || "–", r.transport || "–",
        r.resume_at === null ? "–" : r.resume_at, r.reason || ""];
      cells.forEach((c, i) => {
        const cell = row.insertCell();
        cell.textContent = c;
        if (i === 2) cell.className = "outcome-" + r.outcome;
      });
      row.onclick = () => historyRun(r.id);
    }
  } catch (e) {
    $("history-error").textContent = e.message;
  }
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
  const [machines, jobs] = await Promise.all([api("/api/machines"), api("/api/jobs")]);
  await jobsPage(machines, jobs);
  fill($("run-machine"), machines);
  fill($("run-job"), jobs);
  $("run-machine").onchange = render;
  $("run-form").onsubmit = async (event) => {
    event.preventDefault();
    $("run-error").textContent = "";
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
    try {
      await api("/api/runs", { machine: $("run-machine").value, job: $("run-job").value, stream: true });
    } catch (e) {
      $("run-error").textContent = e.message;
    }
  };
  $("history-form").onsubmit = (event) => { event.preventDefault(); history(); };
  $("btn-hold").onclick = () => press("hold");
  $("btn-resume").onclick = () => press("resume");
  $("btn-stop").onclick = () => press("stop");
  $("btn-resume-at").onclick = () => press("resume-at");
  $("feed-set").onclick = () => feed({ percent: Number($("feed-percent").value) });
  $("feed-down").onclick = () => feed({ step: -10 });
  $("feed-reset").onclick = () => feed({ percent: 100 });
  $("feed-up").onclick = () => feed({ step: 10 });
  const events = new EventSource("/api/events");
  events.addEventListener("runs", (event) => {
    views = JSON.parse(event.data);
    $("link-state").textContent = "live";
    $("link-state").className = "muted";
    document.body.classList.remove("console-gone");
    render();
    historyOnEnd();
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

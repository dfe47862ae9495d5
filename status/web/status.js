// rayfarm status page: polls the broker's JSON API (/api/jobs, /api/workers)
// once a second and redraws. No libraries, nothing fetched from elsewhere.
// When a poll fails the page says "broker unreachable", greys what it last
// saw and keeps retrying; the next successful poll brings it back.
"use strict";

const POLL_MS = 1000;
const RATE_WINDOW_MS = 20000;  // rows/s and ETA come from the last 20 s of polls

const state = {
  selected: null,        // job id the user clicked; null = follow the running job
  shown: null,           // job id whose image is on screen
  shownRows: -1,         // rows_done of the image on screen
  loading: false,        // a preview is being fetched
  samples: new Map(),    // job id -> [{t, rows}]
  lastContact: null,
  recordOf: null,        // job id whose record is shown
  connectShown: false,   // the worker hint names the broker's real port (/api/service)
};

const $ = (id) => document.getElementById(id);

// A broker bound beyond loopback wants a bearer token (docs/api.md): open the
// page as http://HEAD:8080/#token=TOKEN. The fragment never reaches the server
// or its logs; the page keeps the token for this tab and clears the address bar.
const token = (() => {
  const m = location.hash.match(/token=([^&]+)/);
  if (m) {
    sessionStorage.setItem("rayfarm-token", decodeURIComponent(m[1]));
    history.replaceState(null, "", location.pathname);
  }
  return sessionStorage.getItem("rayfarm-token");
})();

function request(path) {
  return fetch(path, { cache: "no-store", headers: token ? { Authorization: `Bearer ${token}` } : {} });
}

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v;
    else if (k.startsWith("data-")) e.setAttribute(k, v);
    else e[k] = v;
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return e;
}

async function getJson(path) {
  const res = await request(path);
  if (!res.ok) throw new Error(`${path}: HTTP ${res.status}`);
  return res.json();
}

// ---- numbers ----------------------------------------------------------------

function fmtDuration(s) {
  if (!isFinite(s)) return "?";
  if (s < 1) return "<1 s";
  if (s < 90) return `${Math.round(s)} s`;
  if (s < 5400) return `${Math.round(s / 60)} min`;
  return `${(s / 3600).toFixed(1)} h`;
}

function fmtRate(r) { return r >= 100 ? r.toFixed(0) : r >= 10 ? r.toFixed(1) : r.toFixed(2); }

function jobName(job) {
  if (job.scene) return job.scene.split("/").pop();
  if (Array.isArray(job.scenes) && job.scenes.length) {
    const first = job.scenes[0];
    const name = (typeof first === "string" ? first : first.name || "").split("/").pop();
    return job.scenes.length > 1 ? `${name} +${job.scenes.length - 1}` : name;
  }
  return "";
}

// Rows per second over the recent window, and over the whole window: the
// ETA range runs between the two (widened by 10%), so it is honest about a
// rate that still moves.
function rateOf(job, now) {
  let s = state.samples.get(job.id);
  if (!s) state.samples.set(job.id, (s = []));
  if (!s.length || s[s.length - 1].rows !== job.rows_done || now - s[s.length - 1].t > 5000) s.push({ t: now, rows: job.rows_done });
  while (s.length > 2 && now - s[1].t > RATE_WINDOW_MS) s.shift();
  if (job.state !== "running" || s.length < 2) return null;
  const last = s[s.length - 1];
  const whole = (last.rows - s[0].rows) / ((now - s[0].t) / 1000);
  let recent = whole;
  for (let i = s.length - 2; i >= 0; --i) {
    if (now - s[i].t >= 4000) { recent = (last.rows - s[i].rows) / ((now - s[i].t) / 1000); break; }
  }
  return { recent, whole };
}

function etaText(job, rate) {
  if (job.state === "done") return "—";
  if (job.state !== "running") return "";
  if (!rate || !(Math.max(rate.recent, rate.whole) > 0)) return "estimating…";
  const left = job.rows_total - job.rows_done;
  const fast = Math.max(rate.recent, rate.whole), slow = Math.min(rate.recent, rate.whole);
  const lo = 0.9 * left / fast, hi = slow > 0 ? 1.1 * left / slow : Infinity;
  const a = fmtDuration(lo), b = fmtDuration(hi);
  return a === b ? `~${a}` : `${a} – ${b}`;
}

// ---- jobs -------------------------------------------------------------------

function drawJobs(jobs) {
  const now = Date.now();
  const body = $("jobs").tBodies[0];
  body.replaceChildren();
  for (const job of jobs.slice().reverse()) {  // newest first
    const total = job.rows_total || 0;
    const pct = total ? (100 * job.rows_done) / total : 0;
    const rate = rateOf(job, now);
    const bar = el("div", { class: "bar" + (job.state === "done" ? " done" : "") }, el("span"));
    bar.firstChild.style.width = `${pct.toFixed(1)}%`;
    const row = el("tr", { "data-job-id": String(job.id), "data-state": job.state },
      el("td", {}, String(job.id)),
      el("td", {}, jobName(job)),
      el("td", {}, el("span", { class: `badge ${job.state}` }, job.state)),
      el("td", {}, el("div", { class: "progress" }, bar,
        el("span", { class: "pct" }, `${job.state === "done" ? 100 : Math.floor(pct)}%`))),
      el("td", { class: "num" }, rate ? fmtRate(rate.recent) : ""),
      el("td", { class: "eta" }, etaText(job, rate)));
    if (job.id === state.shown) row.classList.add("selected");
    row.addEventListener("click", () => { state.selected = job.id; refresh(); });
    body.append(row);
  }
  $("jobs-empty").hidden = jobs.length > 0;
  const running = jobs.filter((j) => j.state === "running").length;
  const queued = jobs.filter((j) => j.state === "queued").length;
  $("farm-summary").textContent = `${running} running · ${queued} queued · ${jobs.length} jobs`;
}

// The job whose image to show: the one clicked, else the running one, else the newest.
function jobToShow(jobs) {
  if (state.selected !== null) {
    const picked = jobs.find((j) => j.id === state.selected);
    if (picked) return picked;
  }
  return jobs.find((j) => j.state === "running") || jobs[jobs.length - 1] || null;
}

// Fetches the preview (with the token, if any) and swaps it in only once it
// has loaded, so the image never flickers.
async function drawPreview(job) {
  const img = $("preview");
  if (!job) {
    img.hidden = true;
    $("preview-empty").hidden = false;
    $("preview-title").textContent = "";
    $("preview-caption").textContent = "";
    return;
  }
  const total = job.rows_total || 0;
  $("preview-title").textContent = `job ${job.id} · ${jobName(job)}`;
  const pct = total ? Math.floor((100 * job.rows_done) / total) : 0;
  const img0 = $("preview");
  const size = img0.naturalWidth && img0.dataset.job === String(job.id) ? `, ${img0.naturalWidth}×${img0.naturalHeight}` : "";
  $("preview-caption").textContent = job.state === "done"
    ? `final image${size}`
    : job.state === "running"
      ? `${pct}% of the rows in; rows not yet rendered show their nearest rendered row`
      : job.state;
  if (job.id === state.shown && job.rows_done === state.shownRows) return;
  if (state.loading || !(job.rows_done > 0)) return;
  state.loading = true;
  const rows = job.rows_done;
  let url;
  try {
    const res = await request(`api/jobs/${job.id}/preview.png?rows=${rows}`);
    if (!res.ok) throw new Error(`HTTP ${res.status}`);
    url = URL.createObjectURL(await res.blob());
  } catch (e) {
    state.loading = false;
    return;
  }
  const next = new Image();
  next.onload = () => {
    state.loading = false;
    if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
    img.src = url;
    img.hidden = false;
    img.dataset.job = String(job.id);
    img.dataset.rows = String(rows);
    $("preview-empty").hidden = true;
    state.shown = job.id;
    state.shownRows = rows;
  };
  next.onerror = () => { state.loading = false; URL.revokeObjectURL(url); };
  next.src = url;
}

async function drawRecord(job) {
  const box = $("record");
  if (!job || job.state !== "done") {
    box.hidden = true;
    state.recordOf = null;
    return;
  }
  if (state.recordOf === job.id) return;
  state.recordOf = job.id;
  let rec;
  try {
    rec = await getJson(`api/jobs/${job.id}/records/1`);
  } catch (e) {
    state.recordOf = null;  // not written yet: try again next poll
    return;
  }
  const dl = $("record-summary");
  dl.replaceChildren();
  const add = (k, v) => { if (v !== undefined && v !== null) dl.append(el("dt", {}, k), el("dd", {}, v)); };
  const s = rec.settings || {};
  add("size", s.width ? `${s.width}×${s.height}, ${s.spp} spp, depth ${s.max_depth}` : undefined);
  add("total", rec.total_s !== undefined ? `${rec.total_s.toFixed(2)} s` : undefined);
  add("render", rec.render_s !== undefined ? `${rec.render_s.toFixed(2)} s` : undefined);
  add("tasks", rec.task_count);
  add("workers", Array.isArray(rec.workers) ? rec.workers.length : undefined);
  add("rays", rec.stats && rec.stats.rays !== undefined ? Number(rec.stats.rays).toLocaleString() : undefined);
  $("record-json").textContent = JSON.stringify(rec, null, 2);
  box.hidden = false;
}

// ---- workers ------------------------------------------------------------------

function drawWorkers(workers) {
  const body = $("workers").tBodies[0];
  body.replaceChildren();
  for (const w of workers) {
    body.append(el("tr", { "data-worker": w.name, "data-state": w.state },
      el("td", {}, w.name),
      el("td", { class: "num" }, w.weight.toFixed(1)),
      el("td", { class: "num" }, w.rows_per_s > 0 ? fmtRate(w.rows_per_s) : "—"),
      el("td", { class: "num" }, String(w.rows_done)),
      el("td", { class: "num" }, String(w.tasks_in_flight)),
      el("td", { class: "num" }, `${w.last_heard_s < 1 ? "<1" : Math.round(w.last_heard_s)} s ago`),
      el("td", {}, el("span", { class: `badge ${w.state}` }, w.state))));
  }
  $("workers-empty").hidden = workers.length > 0;
  drawLoadChart(workers);
}

// Two horizontal bars per worker, busy seconds and rows, each scaled to its
// own maximum: balanced work shows as bars of equal length (the paper's Figure 2).
function drawLoadChart(workers) {
  const box = $("load-chart");
  const ns = "http://www.w3.org/2000/svg";
  // Drawn at the box's own width, so 12px text stays 12px.
  const rowH = 34, labelW = 150, valueW = 90, width = Math.max(400, box.clientWidth || 900);
  const height = Math.max(1, workers.length) * rowH + 28;
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
  svg.setAttribute("role", "img");
  const add = (tag, attrs, text) => {
    const e = document.createElementNS(ns, tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    svg.append(e);
    return e;
  };
  const maxBusy = Math.max(1e-9, ...workers.map((w) => w.busy_s));
  const maxRows = Math.max(1, ...workers.map((w) => w.rows_done));
  const span = width - labelW - valueW;
  add("rect", { x: labelW, y: 2, width: 12, height: 10, class: "busy" });
  add("text", { x: labelW + 16, y: 11, class: "axis" }, "busy seconds");
  add("rect", { x: labelW + 130, y: 2, width: 12, height: 10, class: "rows" });
  add("text", { x: labelW + 146, y: 11, class: "axis" }, "rows rendered");
  workers.forEach((w, i) => {
    const y = 24 + i * rowH;
    add("text", { x: 0, y: y + 17 }, w.name);
    add("rect", { x: labelW, y: y + 2, height: 12, width: (span * w.busy_s) / maxBusy, class: "busy" });
    add("rect", { x: labelW, y: y + 16, height: 12, width: (span * w.rows_done) / maxRows, class: "rows" });
    add("text", { x: width - valueW + 8, y: y + 12, class: "axis" }, `${w.busy_s.toFixed(1)} s`);
    add("text", { x: width - valueW + 8, y: y + 27, class: "axis" }, `${w.rows_done} rows`);
  });
  if (!workers.length) add("text", { x: 0, y: 40, class: "axis" }, "no workers");
  box.replaceChildren(svg);
}

// ---- connection ---------------------------------------------------------------

function setConnected(ok, error) {
  const c = $("connection");
  if (ok) {
    state.lastContact = new Date();
    c.dataset.state = "ok";
    c.textContent = "live";
    $("unreachable").hidden = true;
    document.body.classList.remove("stale");
    return;
  }
  c.dataset.state = "unreachable";
  c.textContent = "broker unreachable";
  const since = state.lastContact ? ` Last contact ${state.lastContact.toLocaleTimeString()}.` : "";
  $("unreachable-detail").textContent = `${error}.${since}`;
  $("unreachable").hidden = false;
  document.body.classList.add("stale");
}

// The "no workers" hint names the worker socket the broker bound (its --bind
// port need not be the default), and on a keyed farm the key options without
// which a worker is never admitted. Asked again after an outage: a restarted
// broker may have bound another port, or been given keys.
async function showWorkerConnect() {
  try {
    const service = await getJson("api/service");
    if (service.worker_command) {
      $("worker-command").textContent = service.worker_command;
      $("worker-allow").textContent = service.allow || "";
      $("worker-keys").hidden = !service.allow;
      state.connectShown = true;
    }
  } catch (e) {
    // The hint keeps its placeholder; the next poll asks again.
  }
}

async function refresh() {
  let jobs, workers;
  try {
    [jobs, workers] = await Promise.all([getJson("api/jobs"), getJson("api/workers")]);
  } catch (e) {
    setConnected(false, e instanceof TypeError ? "No answer from the broker" : e.message);
    state.connectShown = false;
    return;
  }
  setConnected(true);
  if (!state.connectShown) showWorkerConnect();
  if (!Array.isArray(jobs)) jobs = jobs.jobs || [];
  const shown = jobToShow(jobs);
  if (shown && shown.id !== state.shown) state.shownRows = -1;
  drawJobs(jobs);
  drawWorkers(workers);
  drawPreview(shown);
  drawRecord(shown);
}

async function loop() {
  await refresh();
  setTimeout(loop, POLL_MS);
}

loop();

// Trayecto web UI: a form that starts renders through the JSON API, then polls the job and swaps in
// the preview PNG after each pass. Fields are checked here with the server's own limits (from
// /api/options), and whatever the server still refuses is shown beside the same fields.
"use strict";

const FIELDS = ["scene", "output", "width", "height", "spp", "secondary", "max_depth",
  "exposure", "integrator", "tonemap", "default_light"];
const $ = (id) => document.getElementById(id);
let options = null;
let current = null;       // id of the job the page is following
let shownVersion = 0;     // preview version on screen
let pollTimer = null;
let previewUrl = null;    // object URL of the preview on screen
let fetchingPreview = false;

function fmtTime(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  if (s < 60) return s.toFixed(1) + " s";
  const m = Math.floor(s / 60);
  const r = Math.round(s - 60 * m);
  return m + " min " + String(r).padStart(2, "0") + " s";
}

function setError(field, message) {
  const el = $("err-" + field);
  const input = $(field);
  if (el) el.textContent = message || "";
  if (input) input.setAttribute("aria-invalid", message ? "true" : "false");
}

function clearErrors() {
  FIELDS.forEach((f) => setError(f, ""));
  $("form-error").textContent = "";
}

function intRule(field, lo, hi, errors) {
  const raw = $(field).value.trim();
  const v = Number(raw);
  if (raw === "" || !Number.isInteger(v) || v < lo || v > hi) {
    errors[field] = `must be a whole number from ${lo} to ${hi}`;
    return null;
  }
  return v;
}

// Mirrors request.rs: same ranges and the same messages.
function readForm() {
  const L = options.limits;
  const errors = {};
  const body = {};
  body.scene = $("scene").value;
  if (!body.scene) errors.scene = "choose a scene";
  let out = $("output").value.trim().replace(/\.(png|exr)$/i, "");
  if (out === "") errors.output = "give an output name";
  else if (out.length > L.max_output_name) errors.output = `must be at most ${L.max_output_name} characters`;
  else if (!/^[A-Za-z0-9_\-][A-Za-z0-9_.\-]*$/.test(out)) {
    errors.output = "must be a plain file name: letters, digits, '-', '_' and '.', not starting with '.'";
  }
  body.output = out;
  body.width = intRule("width", 1, L.max_size, errors);
  body.height = intRule("height", 1, L.max_size, errors);
  body.spp = intRule("spp", 1, L.max_spp, errors);
  body.secondary = intRule("secondary", 1, L.max_secondary, errors);
  body.max_depth = intRule("max_depth", 0, L.max_depth, errors);
  const ex = Number($("exposure").value.trim());
  if ($("exposure").value.trim() === "" || !isFinite(ex) || ex <= 0 || ex > 1e6) {
    errors.exposure = "must be a positive number (at most 1000000)";
  }
  body.exposure = ex;
  body.integrator = $("integrator").value;
  body.tonemap = $("tonemap").value;
  // "" = as the scene file says (auto unless a TOML scene sets default_light).
  body.default_light = $("default_light").value || null;
  if (!errors.spp && body.width && body.height && body.spp && body.secondary) {
    const samples = body.width * body.height * body.spp * body.secondary;
    if (samples > L.max_samples) {
      errors.spp = `width × height × samples × secondary rays = ${samples} is over this server's budget of ${L.max_samples}`;
    }
  }
  return { body, errors };
}

function fillSelect(sel, values, groups) {
  sel.innerHTML = "";
  if (groups) {
    for (const [label, items] of groups) {
      if (!items.length) continue;
      const g = document.createElement("optgroup");
      g.label = label;
      for (const v of items) g.appendChild(new Option(v, v));
      sel.appendChild(g);
    }
  } else {
    for (const v of values) sel.appendChild(new Option(v, v));
  }
}

async function api(method, url, body) {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const res = await fetch(url, init);
  let data = null;
  try { data = await res.json(); } catch (_) { data = null; }
  return { status: res.status, ok: res.ok, data };
}

async function init() {
  const o = await api("GET", "/api/options");
  options = o.data;
  const d = options.defaults;
  fillSelect($("integrator"), options.integrators);
  fillSelect($("tonemap"), options.tonemaps);
  fillSelect($("default_light"), [""].concat(options.default_lights || []));
  $("default_light").options[0].textContent = "as the scene says (auto)";
  await loadScenes(d.scene);
  for (const f of ["output", "width", "height", "spp", "secondary", "max_depth", "exposure",
    "integrator", "tonemap", "default_light"]) {
    $(f).value = d[f];
  }
  $("width").max = $("height").max = options.limits.max_size;
  $("spp").max = options.limits.max_spp;
  $("secondary").max = options.limits.max_secondary;
  $("max_depth").max = options.limits.max_depth;
  // Re-check a field as soon as it is edited, so a fixed field loses its message at once.
  for (const f of FIELDS) {
    $(f).addEventListener("input", () => {
      const { errors } = readForm();
      setError(f, errors[f]);
    });
  }
  $("render-form").addEventListener("submit", (e) => { e.preventDefault(); start(); });
  $("cancel").addEventListener("click", cancel);
  const list = await refreshRecent();
  const running = list.find((j) => j.active);
  if (running) follow(running.id);
}

async function loadScenes(selected) {
  const s = await api("GET", "/api/scenes");
  fillSelect($("scene"), null, [["Built-in", s.data.builtin], ["Scenes folder", s.data.files]]);
  if (selected) $("scene").value = selected;
}

async function start() {
  clearErrors();
  const { body, errors } = readForm();
  const bad = Object.keys(errors);
  if (bad.length) {
    bad.forEach((f) => setError(f, errors[f]));
    $(bad[0]).focus();
    return;
  }
  $("start").disabled = true;
  const r = await api("POST", "/api/renders", body);
  $("start").disabled = false;
  if (!r.ok) {
    const fields = (r.data && r.data.fields) || {};
    for (const [f, m] of Object.entries(fields)) {
      if ($("err-" + f)) setError(f, m); else $("form-error").textContent = m;
    }
    if (!Object.keys(fields).length) {
      $("form-error").textContent = (r.data && r.data.error) || `the server answered ${r.status}`;
    }
    return;
  }
  follow(r.data.id);
}

async function cancel() {
  if (current === null) return;
  $("cancel").disabled = true;
  await api("POST", `/api/renders/${current}/cancel`);
}

function follow(id) {
  current = id;
  shownVersion = 0;
  $("preview").dataset.version = "0";
  $("preview").dataset.job = String(id);
  $("result").hidden = true;
  $("cancel").disabled = false;
  $("progress").value = 0;
  if (pollTimer) clearTimeout(pollTimer);
  poll();
}

async function showPreview(job) {
  if (fetchingPreview || !job.preview || job.preview_version <= shownVersion) return;
  fetchingPreview = true;
  try {
    const res = await fetch(job.preview);
    if (res.ok && job.id === current) {
      const blob = await res.blob();
      const url = URL.createObjectURL(blob);
      const img = $("preview");
      img.src = url;
      img.classList.add("shown");
      $("placeholder").hidden = true;
      if (previewUrl) URL.revokeObjectURL(previewUrl);
      previewUrl = url;
      shownVersion = job.preview_version;
      img.dataset.version = String(shownVersion);
    }
  } finally {
    fetchingPreview = false;
  }
}

function showStatus(job) {
  $("state").textContent = job.state;
  $("progress").value = job.progress;
  $("samples").textContent = `${job.samples_done} / ${job.spp} spp`;
  $("elapsed").textContent = "elapsed " + fmtTime(job.elapsed_s);
  $("remaining").textContent = "remaining " + fmtTime(job.remaining_s);
}

function showResult(job) {
  const tbody = $("timings").querySelector("tbody");
  tbody.innerHTML = "";
  for (const t of job.timings) {
    const tr = document.createElement("tr");
    const a = document.createElement("td");
    a.textContent = t.phase;
    const b = document.createElement("td");
    b.textContent = t.seconds.toFixed(3) + " s";
    tr.append(a, b);
    tbody.appendChild(tr);
  }
  $("log").textContent = job.log.join("\n") + (job.error ? "\n" + job.error : "");
  for (const [id, url, ext] of [["dl-png", job.png, "png"], ["dl-exr", job.exr, "exr"]]) {
    const a = $(id);
    a.hidden = !url;
    if (url) { a.href = url; a.download = `${job.output}.${ext}`; }
  }
  $("result").hidden = false;
  if (job.state === "done" && job.png) {
    const img = $("preview");
    img.src = job.png + "?final";
    img.classList.add("shown");
    $("placeholder").hidden = true;
  }
}

async function poll() {
  if (current === null) return;
  const id = current;
  let r;
  try { r = await api("GET", `/api/renders/${id}`); } catch (_) { r = null; }
  if (id !== current) return;
  if (!r || !r.ok) {
    pollTimer = setTimeout(poll, 1000);
    return;
  }
  const job = r.data;
  showStatus(job);
  if (job.active) {
    await showPreview(job);
    pollTimer = setTimeout(poll, 250);
  } else {
    $("cancel").disabled = true;
    showResult(job);
    refreshRecent();
  }
}

async function refreshRecent() {
  const r = await api("GET", "/api/renders");
  const list = (r.data && r.data.renders) || [];
  const ul = $("recent");
  ul.innerHTML = "";
  for (const j of list) {
    const li = document.createElement("li");
    const name = document.createElement("a");
    name.href = "#";
    name.textContent = j.output;
    name.addEventListener("click", (e) => { e.preventDefault(); follow(j.id); });
    li.appendChild(name);
    if (j.png) {
      const a = document.createElement("a");
      a.href = j.png; a.download = j.output + ".png"; a.textContent = "PNG";
      li.appendChild(a);
    }
    if (j.exr) {
      const a = document.createElement("a");
      a.href = j.exr; a.download = j.output + ".exr"; a.textContent = "EXR";
      li.appendChild(a);
    }
    const meta = document.createElement("span");
    meta.className = "meta";
    meta.textContent = `${j.scene} · ${j.width}×${j.height} · ${j.spp} spp · ${j.state}` +
      (j.active ? "" : " · " + fmtTime(j.elapsed_s));
    li.appendChild(meta);
    ul.appendChild(li);
  }
  return list;
}

init().catch((e) => { $("form-error").textContent = "could not reach the server: " + e; });

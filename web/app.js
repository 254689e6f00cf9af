// Trayecto web UI: a form that starts renders through the JSON API, then polls the job and swaps in
// the preview PNG after each pass. Fields are checked here with the server's own limits (from
// /api/options), and whatever the server still refuses is shown beside the same fields.
"use strict";

const FIELDS = ["scene", "output", "width", "height", "spp", "secondary", "max_depth",
  "exposure", "integrator", "tonemap", "default_light", "denoise", "transparent", "spectral", "guiding", "environment",
  "env_rotation", "view_spp", "aovs", "variant", "time", "frames", "fps", "shutter"];
const $ = (id) => document.getElementById(id);
let options = null;
let current = null;       // id of the job the page is following
let shownVersion = 0;     // preview version on screen
let pollTimer = null;
let previewUrl = null;    // object URL of the preview on screen
let fetchingPreview = false;
let lastState = null;      // state of the followed job at the last poll
let builtinNames = [];     // the built-in scenes (they cannot be included in a saved TOML scene)
let finalJob = null;       // {id, layer, linear} of the finished render on show

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
  body.denoise = $("denoise").checked;
  body.transparent = $("transparent").checked;
  // "" = the scene file's default (pbrt files spectral, as pbrt-v4; other formats RGB).
  body.spectral = { "": null, spectral: true, rgb: false }[$("spectral").value];
  // "" = the scene file's setting (TOML [render] guiding), else off.
  body.guiding = { "": null, on: true, off: false }[$("guiding").value];
  body.environment = $("environment").value || null;
  // "" = the file's default materials (KHR_materials_variants); the list is the scene's own.
  body.variant = $("variant").value || null;
  const rot = Number($("env_rotation").value.trim() || "0");
  if (!isFinite(rot) || Math.abs(rot) > 36000) errors.env_rotation = "must be a number of degrees (at most 36000 either way)";
  else if (rot !== 0 && !body.environment) errors.env_rotation = "turns the environment map: choose one (environment)";
  body.env_rotation = rot;
  if ($("aovs").checked) body.aovs = ["albedo", "normal"];
  // The moment of an animated scene: a time, one frame (N) or a sequence (A..B).
  const time = $("time").value.trim();
  if (time !== "") {
    const t = Number(time);
    if (!isFinite(t) || Math.abs(t) > 1e6) errors.time = "must be a number of seconds (at most 1000000 either way)";
    else body.time = t;
  }
  const frames = $("frames").value.trim();
  if (frames !== "") {
    const m = /^(\d+)(?:\s*\.\.\s*(\d+))?$/.exec(frames);
    if (!m) errors.frames = "must be a frame N or a sequence A..B (whole numbers from 0)";
    else if (m[2] === undefined) body.frame = Number(m[1]);
    else if (Number(m[1]) > Number(m[2])) errors.frames = "must be A..B with A <= B";
    else body.frames = [Number(m[1]), Number(m[2])];
    if (m && body.time !== undefined) errors.frames = "time and frames both give the moment: use one";
  }
  const fps = $("fps").value.trim();
  if (fps !== "") {
    const f = Number(fps);
    if (!isFinite(f) || f <= 0 || f > 1e6) errors.fps = "must be a positive number (at most 1000000)";
    else body.fps = f;
  }
  const shutter = $("shutter").value.trim();
  if (shutter !== "") {
    const parts = shutter.split(",").map((x) => Number(x.trim()));
    if (parts.length !== 2 || !parts.every(isFinite) || parts[0] > parts[1]) {
      errors.shutter = "must be open,close in seconds with open <= close";
    } else body.shutter = parts;
  }
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
  $("default_light").options[0].textContent = "as the scene says";
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
  setupViewport();
  $("scene").addEventListener("change", async () => { await prefillScene(); newScene(); });
  $("show-all").addEventListener("change", () => loadScenes($("scene").value));
  $("upload").addEventListener("change", upload);
  $("upload-box").hidden = !options.uploads;
  $("cancel").addEventListener("click", cancel);
  await prefillScene();
  newScene();
  const list = await refreshRecent();
  const running = list.find((j) => j.active);
  if (running) follow(running.id);
}

async function loadScenes(selected) {
  const all = $("show-all").checked;
  const s = await api("GET", "/api/scenes" + (all ? "?all=true" : ""));
  fillSelect($("scene"), null, [["Built-in", s.data.builtin], ["Scenes folder", s.data.files]]);
  builtinNames = s.data.builtin;
  const env = $("environment").value;
  fillSelect($("environment"), [""].concat(s.data.environments || []));
  $("environment").options[0].textContent = "none";
  $("environment").value = env;
  $("hidden-count").textContent = !all && s.data.hidden ? `(${s.data.hidden} hidden)` : "";
  if (selected) $("scene").value = selected;
}

// The size, samples and depth a render of the chosen scene gets from its file.
async function prefillScene() {
  const name = $("scene").value;
  const sel = $("scene");
  delete sel.dataset.prefilled;
  $("scene-note").textContent = "";
  if (!name) return;
  const r = await api("GET", "/api/scene-defaults?scene=" + encodeURIComponent(name));
  if (name !== sel.value) return;
  // A variant belongs to its scene: another scene starts from its file's default materials.
  const variants = (r.ok && r.data.variants) || [];
  fillSelect($("variant"), [""].concat(variants));
  $("variant").options[0].textContent = "the file's default materials";
  $("variant").value = "";
  $("variant-box").hidden = variants.length === 0;
  setError("variant", "");
  if (r.ok) {
    setError("scene", "");
    for (const f of ["width", "height", "spp", "max_depth"]) $(f).value = r.data[f];
    $("scene-note").textContent = r.data.note || "";
  } else {
    setError("scene", (r.data && r.data.error) || `the server answered ${r.status}`);
  }
  // Marks the answer as applied (the e2e test waits for it before filling in its own values).
  sel.dataset.prefilled = name;
}

async function upload() {
  const file = $("upload").files[0];
  if (!file) return;
  const status = $("upload-status");
  const max = options.limits.max_upload;
  if (max && file.size > max) {
    status.textContent = `${file.name} is larger than this server's upload limit of ${max} bytes`;
    return;
  }
  status.textContent = `uploading ${file.name}…`;
  let res;
  try {
    res = await fetch("/api/uploads?name=" + encodeURIComponent(file.name), {
      method: "POST", headers: { "Content-Type": "application/octet-stream" }, body: file });
  } catch (e) {
    status.textContent = `${file.name}: upload failed (${e})`;
    return;
  }
  let data = null;
  try { data = await res.json(); } catch (_) { data = null; }
  if (!res.ok) {
    status.textContent = `${file.name}: ${(data && data.error) || "the server answered " + res.status}`;
    return;
  }
  const first = data.scenes.find((f) => !/\.(ply|obj)$/i.test(f)) || data.scenes[0];
  $("upload").value = "";
  // The list is reloaded and the new scene selected before the status says "uploaded", so
  // whoever reads the status (a user, the e2e test) finds the scene already chosen.
  await loadScenes(first);
  status.textContent = `uploaded ${file.name}: ${data.scenes.length} scene file(s)` +
    (data.skipped.length ? `, skipped ${data.skipped.join(", ")}` : "");
  await prefillScene();
  newScene();
}

async function start(extra) {
  clearErrors();
  const { body, errors } = readForm();
  delete errors.view_spp;
  Object.assign(body, extra || {});
  const bad = Object.keys(errors);
  if (bad.length) {
    bad.forEach((f) => setError(f, errors[f]));
    $(bad[0]).focus();
    return;
  }
  // The one render button renders what the viewport shows: its moved view, else the scene's
  // camera.
  const camera = viewCamera();
  if (camera && !body.camera) body.camera = camera;
  $("render").disabled = true;
  const r = await api("POST", "/api/renders", body);
  $("render").disabled = false;
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
  $("final").hidden = true;
  finalJob = null;
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
      $("final").hidden = true;
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

/** The render button's state: "Render" when nothing runs; while the followed render runs it
 * says how far it is, and a click queues another render. */
function showButton(job) {
  const b = $("render");
  const active = !!(job && job.active);
  b.dataset.state = active ? (job.state === "queued" ? "queued" : "rendering") : "idle";
  b.textContent = active ? "Queue another render" : "Render";
  let s = "ready";
  if (active && job.state === "queued") s = `queued, position ${job.queue_position}`;
  else if (active) s = `${job.state} ${Math.round(100 * job.progress)} %` +
    (job.remaining_s != null ? `, ${fmtTime(job.remaining_s)} left` : "");
  else if (job) s = `${job.state}: ${job.output}`;
  $("render-state").textContent = s;
}

function showStatus(job) {
  showButton(job);
  $("state").textContent = job.state;
  $("queue").textContent = job.queue_position ? `position ${job.queue_position} in the queue` : "";
  $("progress").value = job.progress;
  $("samples").textContent = `${job.samples_done} / ${job.spp} spp` +
    (job.frames && job.frames.current != null
      ? `, frame ${job.frames.current} (${job.frames.first}..${job.frames.last})` : "");
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
  // A failed job's error is already the log's last line ("error: …"); said once.
  const said = job.error && job.log.some((l) => l.includes(job.error));
  $("log").textContent = job.log.join("\n") + (job.error && !said ? "\nerror: " + job.error : "");
  for (const [id, url, ext] of [["dl-png", job.png, "png"], ["dl-exr", job.exr, "exr"],
    ["dl-denoised-png", job.denoised_png, "denoised.png"],
    ["dl-denoised-exr", job.denoised_exr, "denoised.exr"]]) {
    const a = $(id);
    a.hidden = !url;
    if (url) { a.href = url; a.download = `${job.output}.${ext}`; }
  }
  // A sequence: every frame written, each its own PNG and EXR (the image shown is the last).
  const links = $("frame-links");
  links.innerHTML = "";
  const done = (job.frames && job.frames.done) || [];
  for (const f of done) {
    for (const [url, ext] of [[f.png, "png"], [f.exr, "exr"]]) {
      const a = document.createElement("a");
      a.href = url;
      const n = String(f.frame).padStart(4, "0");
      a.download = `${job.output}_${n}.${ext}`;
      a.textContent = `frame ${f.frame} ${ext.toUpperCase()}`;
      links.appendChild(a);
    }
  }
  links.hidden = done.length === 0;
  $("result").hidden = false;
  $("show-denoised").hidden = true;
  // The finished image is tone-mapped here from its linear data, so exposure and tone mapping
  // apply at once; the layer buttons switch between beauty, AOVs and the denoised image.
  const layers = $("layers");
  const have = { beauty: !!job.linear, albedo: job.aovs && job.aovs.includes("albedo"),
    normal: job.aovs && job.aovs.includes("normal"), denoised: !!job.denoised_exr };
  layers.hidden = !(job.state === "done" && job.linear);
  for (const b of layers.querySelectorAll("button")) {
    b.hidden = !have[b.dataset.layer];
    b.setAttribute("aria-pressed", String(b.dataset.layer === "beauty"));
    b.onclick = () => showLayer(job, b.dataset.layer);
  }
  if (job.state === "done" && job.linear) showLayer(job, "beauty");
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
    if (job.state === "queued" || job.state !== lastState) refreshRecent();
    lastState = job.state;
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
    meta.textContent = `${j.scene}${j.variant ? " (" + j.variant + ")" : ""} · ${j.width}×${j.height} · ${j.spp} spp · ` +
      (j.queue_position ? `queued, position ${j.queue_position}` : j.state) +
      (j.active ? "" : " · " + fmtTime(j.elapsed_s));
    li.dataset.state = j.state;
    li.appendChild(meta);
    if (j.active) {
      const b = document.createElement("button");
      b.type = "button";
      b.className = "small";
      b.textContent = "Cancel";
      b.setAttribute("aria-label", `cancel ${j.output}`);
      b.addEventListener("click", async () => {
        b.disabled = true;
        await api("POST", `/api/renders/${j.id}/cancel`);
        refreshRecent();
      });
      li.appendChild(b);
    }
    ul.appendChild(li);
  }
  return list;
}


// ---- Tone mapping: the library's operators (src/film/tonemap.rs), applied to linear data the
// server sends (little-endian f32 RGB), so exposure and tone mapping change without a re-render.
function srgb(c) { return c <= 0.0031308 ? c * 12.92 : 1.055 * Math.pow(c, 1 / 2.4) - 0.055; }
const clamp01 = (x) => (x < 0 ? 0 : x > 1 ? 1 : x);
// Wrensch's minimal AgX, column-major matrices as in tonemap.rs.
const AGX_IN = [0.84247906, 0.042328242, 0.042375655, 0.0784336, 0.8784686, 0.0784336,
  0.079223745, 0.07916613, 0.879143];
const AGX_OUT = [1.196879, -0.05289685, -0.052971635, -0.09802088, 1.1519031, -0.09804345,
  -0.09902974, -0.09896118, 1.1510737];
function mat3(m, x, y, z) {
  return [m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z, m[2] * x + m[5] * y + m[8] * z];
}
function agxEncode(x) {
  const lo = -12.47393, hi = 4.026069;
  const l = Math.min(Math.max(Math.log2(Math.max(x, 1e-10)), lo), hi);
  return (l - lo) / (hi - lo);
}
function agxCurve(v) {
  const v2 = v * v, v4 = v2 * v2;
  return 15.5 * v4 * v2 - 40.14 * v4 * v + 31.96 * v4 - 6.868 * v2 * v + 0.4298 * v2 + 0.1191 * v - 0.00232;
}
/** One pixel: linear RGB (exposure applied) to display RGB in [0, 1], as Tonemap::apply. */
function tonemap(op, r, g, b) {
  r = Math.max(r, 0); g = Math.max(g, 0); b = Math.max(b, 0);
  if (!isFinite(r) || !isFinite(g) || !isFinite(b)) { r = 0; g = 0; b = 0; }
  switch (op) {
    case "gamma2.2": return [r, g, b].map((c) => Math.pow(Math.min(c, 1), 1 / 2.2));
    case "aces": return [r, g, b].map((c) =>
      srgb(clamp01((c * (c * 2.51 + 0.03)) / (c * (c * 2.43 + 0.59) + 0.14))));
    case "agx": {
      const v = mat3(AGX_IN, r, g, b).map((x) => agxCurve(agxEncode(x)));
      return mat3(AGX_OUT, v[0], v[1], v[2]).map(clamp01);
    }
    case "pbr-neutral": {
      // Khronos PBR Neutral, as pbr_neutral in tonemap.rs.
      const x = Math.min(r, g, b);
      const offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
      let c = [r - offset, g - offset, b - offset];
      const start = 0.76, d = 0.24, peak = Math.max(c[0], c[1], c[2]);
      if (peak >= start) {
        const np = 1 - (d * d) / (peak + d - start);
        const t = 1 - 1 / (0.15 * (peak - np) + 1);
        c = c.map((v) => v * (np / peak) * (1 - t) + np * t);
      }
      return c.map((v) => srgb(clamp01(v)));
    }
    default: return [r, g, b].map((c) => srgb(Math.min(c, 1)));
  }
}
/** Draws linear data into `canvas`: `mode` "beauty" uses the form's exposure and tone mapping,
 * "albedo" is shown as a colour (sRGB), "normal" as (n + 1) / 2, as the AOV side files are. */
function drawLinear(canvas, lin, mode) {
  const { w, h, data } = lin;
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const g = canvas.getContext("2d");
  const img = g.createImageData(w, h);
  const out = img.data;
  const ex = Number($("exposure").value);
  const exposure = isFinite(ex) && ex > 0 ? ex : 1;
  const op = $("tonemap").value;
  for (let i = 0, j = 0; i < data.length; i += 3, j += 4) {
    let c;
    if (mode === "normal") c = [0, 1, 2].map((k) => clamp01(data[i + k] * 0.5 + 0.5));
    else if (mode === "albedo") c = tonemap("clamp", data[i], data[i + 1], data[i + 2]);
    else c = tonemap(op, data[i] * exposure, data[i + 1] * exposure, data[i + 2] * exposure);
    out[j] = Math.min(Math.max(Math.floor(c[0] * 255 + 0.5), 0), 255);
    out[j + 1] = Math.min(Math.max(Math.floor(c[1] * 255 + 0.5), 0), 255);
    out[j + 2] = Math.min(Math.max(Math.floor(c[2] * 255 + 0.5), 0), 255);
    out[j + 3] = 255;
  }
  g.putImageData(img, 0, 0);
}
async function fetchLinear(url) {
  const res = await fetch(url, { cache: "no-store" });
  if (!res.ok) return null;
  const w = Number(res.headers.get("x-width")), h = Number(res.headers.get("x-height"));
  const buf = await res.arrayBuffer();
  if (buf.byteLength !== w * h * 12) return null;
  return { w, h, data: new Float32Array(buf), version: Number(res.headers.get("x-version") || 0),
    samples: Number(res.headers.get("x-samples") || 0) };
}
async function showLayer(job, layer) {
  for (const b of $("layers").querySelectorAll("button")) {
    b.setAttribute("aria-pressed", String(b.dataset.layer === layer));
  }
  const lin = await fetchLinear(job.linear + "?layer=" + layer);
  if (!lin || job.id !== current) return;
  finalJob = { id: job.id, layer, lin };
  const c = $("final");
  drawLinear(c, lin, layer === "denoised" ? "beauty" : layer);
  c.dataset.layer = layer;
  c.dataset.job = String(job.id);
  c.hidden = false;
  $("preview").classList.remove("shown");
  $("placeholder").hidden = true;
}
function redisplay() {
  if (vp.lin) drawLinear($("viewport"), vp.lin, "beauty");
  if (finalJob && !$("final").hidden) {
    drawLinear($("final"), finalJob.lin, finalJob.layer === "denoised" ? "beauty" : finalJob.layer);
  }
}

// ---- The viewport: an orbit camera around the scene's bounds over a progressive preview that
// the server restarts (cancelling the stale one) whenever the camera moves.
const vp = {
  // One session per tab, kept over reloads, so a reload's first view cancels the old preview.
  session: (() => {
    let id = null;
    try { id = sessionStorage.getItem("trayecto-viewport"); } catch (_) { id = null; }
    if (!id || !/^[A-Za-z0-9_-]{1,64}$/.test(id)) {
      id = "p" + Math.random().toString(36).slice(2, 12) + Date.now().toString(36);
      try { sessionStorage.setItem("trayecto-viewport", id); } catch (_) { /* private mode */ }
    }
    return id;
  })(),
  scene: null,        // scene the orbit below belongs to
  home: null,         // the scene's own view {camera, bounds}
  orbit: null,        // {target, dist, yaw, pitch, up, A, B, fov, radius}
  // Whether the user has orbited, dollied or panned away from the scene's own camera. Until
  // then no camera is sent, so the viewport and "Render final" use the scene's camera as the
  // command line does: its projection (orthographic, spherical), lens and screen window. The
  // orbit is a perspective eye/target/fov, so a moved view of such a scene is perspective.
  moved: false,
  homeGen: null,      // the first view request of `scene`: only its status may set `home`
  sending: false, dirty: false, polling: false, repoll: false, generation: 0, shown: 0, lin: null, timer: null, sentAt: 0,
};
const V = {
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  mul: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  len: (a) => Math.hypot(a[0], a[1], a[2]),
  norm: (a) => { const l = Math.hypot(a[0], a[1], a[2]); return l > 0 ? [a[0] / l, a[1] / l, a[2] / l] : a; },
};
/** Orbit parameters from a camera: yaw and pitch of the eye around the target in a frame whose
 * pole is the camera's up vector. */
function orbitFrom(view) {
  const c = view.camera;
  const up = V.norm(c.up);
  const off = V.sub(c.eye, c.target);
  const dist = V.len(off);
  const dir = V.mul(off, 1 / dist);
  let B = V.sub(dir, V.mul(up, V.dot(dir, up)));
  if (V.len(B) < 1e-6) B = Math.abs(up[0]) < 0.9 ? V.cross(up, [1, 0, 0]) : V.cross(up, [0, 1, 0]);
  B = V.norm(B);
  const A = V.cross(up, B);
  const b = view.bounds;
  const radius = b ? 0.5 * V.len(V.sub(b.max, b.min)) : dist;
  return { target: c.target.slice(), dist, yaw: 0, pitch: Math.asin(Math.max(-1, Math.min(1, V.dot(dir, up)))),
    up, A, B, fov: c.fov, radius: radius > 0 ? radius : dist };
}
function orbitCamera(o) {
  const cp = Math.cos(o.pitch);
  const dir = V.add(V.add(V.mul(o.A, cp * Math.sin(o.yaw)), V.mul(o.B, cp * Math.cos(o.yaw))),
    V.mul(o.up, Math.sin(o.pitch)));
  return { eye: V.add(o.target, V.mul(dir, o.dist)), target: o.target.slice(), up: o.up.slice(), fov: o.fov };
}
function viewSize() {
  const w = Number($("width").value) || 256, h = Number($("height").value) || 256;
  const s = Math.min(1, 400 / Math.max(w, h));
  return [Math.max(1, Math.round(w * s)), Math.max(1, Math.round(h * s))];
}
const PITCH_MAX = 89 * Math.PI / 180;
/** The camera to send: none while the view is the scene's own (see `vp.moved`). */
function viewCamera() {
  return vp.orbit && vp.moved ? orbitCamera(vp.orbit) : undefined;
}
/** Marks the view as moved by the user and says so when that loses the scene's projection. */
function setMoved(moved) {
  vp.moved = moved;
  showProjection();
}
function showProjection() {
  const p = $("vp-projection");
  const proj = vp.home && vp.home.projection;
  $("viewport").dataset.projection = vp.moved || !proj ? "perspective" : proj;
  if (!proj || proj === "perspective") { p.hidden = true; p.textContent = ""; return; }
  p.hidden = false;
  p.textContent = vp.moved
    ? `Perspective view: the scene's ${proj} camera is not kept once the view is moved (Render final ` +
      `and Save camera use this perspective view). Reset view renders the scene's own camera again.`
    : `The scene's ${proj} camera (the viewport and Render final use it until you move the view).`;
}
function orbitBy(dyaw, dpitch) {
  const o = vp.orbit; if (!o) return;
  setMoved(true);
  o.yaw -= dyaw;
  o.pitch = Math.max(-PITCH_MAX, Math.min(PITCH_MAX, o.pitch + dpitch));
  sendView();
}
function dollyBy(factor) {
  const o = vp.orbit; if (!o) return;
  setMoved(true);
  o.dist = Math.max(o.radius * 1e-3, Math.min(o.radius * 1e3, o.dist * factor));
  sendView();
}
/** Moves the target by (dx, dy) in view-height units along the camera's right and up. */
function panBy(dx, dy) {
  const o = vp.orbit; if (!o) return;
  setMoved(true);
  const c = orbitCamera(o);
  const fwd = V.norm(V.sub(c.target, c.eye));
  const right = V.norm(V.cross(fwd, o.up));
  const up = V.cross(right, fwd);
  const span = 2 * o.dist * Math.tan(o.fov * Math.PI / 360);
  o.target = V.add(o.target, V.add(V.mul(right, -dx * span), V.mul(up, dy * span)));
  sendView();
}
function setupViewport() {
  const c = $("viewport");
  let drag = null;
  c.addEventListener("contextmenu", (e) => e.preventDefault());
  c.addEventListener("pointerdown", (e) => {
    c.focus();
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 || e.button === 1 };
    c.setPointerCapture(e.pointerId);
    c.classList.add("dragging");
  });
  c.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    const h = c.getBoundingClientRect().height || 1;
    if (drag.pan) panBy(dx / h, dy / h);
    else orbitBy(dx / h * Math.PI, dy / h * Math.PI);
  });
  const end = () => { drag = null; c.classList.remove("dragging"); };
  c.addEventListener("pointerup", end);
  c.addEventListener("pointercancel", end);
  c.addEventListener("wheel", (e) => {
    e.preventDefault();
    const d = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaY;
    dollyBy(Math.exp(Math.max(-500, Math.min(500, d)) * 0.002));
  }, { passive: false });
  c.addEventListener("keydown", (e) => {
    const step = 5 * Math.PI / 180;
    const k = e.key;
    if (e.shiftKey && k.startsWith("Arrow")) {
      const d = { ArrowLeft: [-0.05, 0], ArrowRight: [0.05, 0], ArrowUp: [0, -0.05], ArrowDown: [0, 0.05] }[k];
      panBy(d[0], d[1]);
    } else if (k === "ArrowLeft") orbitBy(-step, 0);
    else if (k === "ArrowRight") orbitBy(step, 0);
    else if (k === "ArrowUp") orbitBy(0, step);
    else if (k === "ArrowDown") orbitBy(0, -step);
    else if (k === "+" || k === "=") dollyBy(1 / 1.15);
    else if (k === "-" || k === "_") dollyBy(1.15);
    else return;
    e.preventDefault();
  });
  for (const f of ["width", "height", "max_depth", "environment", "env_rotation", "default_light",
    "view_spp", "integrator", "variant"]) {
    $(f).addEventListener("change", () => sendView());
  }
  for (const f of ["exposure", "tonemap"]) $(f).addEventListener("input", redisplay);
  $("tonemap").addEventListener("change", redisplay);
  $("reset-view").addEventListener("click", () => {
    if (vp.home) { vp.orbit = orbitFrom(vp.home); setMoved(false); sendView(); }
  });
  $("save-camera").addEventListener("click", () => {
    if (vp.orbit) download("camera.toml", cameraToml(orbitCamera(vp.orbit)));
  });
  $("save-scene").addEventListener("click", saveScene);
}
const num = (x) => (Number.isInteger(x) ? x.toFixed(1) : String(x));
function cameraToml(c) {
  const v = (a) => "[" + a.map(num).join(", ") + "]";
  return `[[camera]]\neye = ${v(c.eye)}\ntarget = ${v(c.target)}\nup = ${v(c.up)}\nfov = ${num(c.fov)}\n`;
}
function download(name, text) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([text], { type: "application/toml" }));
  a.download = name;
  document.body.appendChild(a);
  a.click();
  setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
}
/** A TOML scene that includes the chosen model (its path in the scenes folder) with this
 * camera; saved beside the folder's top level, it renders the framed view (also from the CLI). */
function saveScene() {
  if (!vp.orbit) return;
  const scene = $("scene").value;
  if (builtinNames.includes(scene)) {
    $("vp-state").textContent = "a built-in scene cannot be included in a TOML scene; save the camera instead";
    return;
  }
  const q = (s) => JSON.stringify(s);
  let t = `# Saved from the Trayecto viewport. Put this file in the server's scenes folder.\nname = ${q(scene)}\n`;
  const dl = $("default_light").value;
  if (dl) t += `default_light = ${q(dl)}\n`;
  t += "\n" + cameraToml(orbitCamera(vp.orbit));
  t += `\n[[object]]\nname = "model"\ntype = "mesh"\nfile = ${q(scene)}\n`;
  const variant = $("variant").value;
  if (variant) t += `variant = ${q(variant)}\n`;
  const env = $("environment").value;
  if (env) t += `\n[[light]]\ntype = "environment"\nfile = ${q(env)}\nrotation = ${num(Number($("env_rotation").value) || 0)}\n`;
  download(scene.replace(/^.*\//, "").replace(/\.[^.]*$/, "") + "-view.toml", t);
}
function newScene() {
  vp.scene = $("scene").value;
  vp.home = null;
  vp.orbit = null;
  vp.homeGen = null;
  setMoved(false);
  sendView();
}
/** Sends the current view; while a send is in flight the newest view waits, so at most one
 * request is outstanding and the last camera always reaches the server. */
async function sendView() {
  if (!vp.scene) return;
  if (vp.sending) { vp.dirty = true; return; }
  const { body, errors } = readForm();
  const [w, h] = viewSize();
  const spp = Number($("view_spp").value);
  if (!Number.isInteger(spp) || spp < 1 || spp > options.limits.max_spp) {
    setError("view_spp", `must be a whole number from 1 to ${options.limits.max_spp}`);
    return;
  }
  setError("view_spp", "");
  for (const f of ["environment", "env_rotation", "max_depth"]) if (errors[f]) return;
  const view = { scene: vp.scene, width: w, height: h, spp, max_depth: body.max_depth,
    integrator: body.integrator, default_light: body.default_light, environment: body.environment,
    env_rotation: body.env_rotation, variant: body.variant };
  const camera = viewCamera();
  if (camera) view.camera = camera;
  vp.sending = true;
  vp.sentAt = performance.now();
  const sentScene = vp.scene;
  try {
    const r = await api("POST", "/api/viewport?session=" + vp.session, view);
    if (r.ok) {
      if (r.data.generation !== vp.generation) {
        // The image on show belongs to an earlier view until this one's first image arrives:
        // its state and sample count must not be read as the new view's.
        $("viewport").dataset.state = "rendering";
        $("viewport").dataset.samples = "0";
      }
      vp.generation = r.data.generation;
      if (sentScene === vp.scene && vp.homeGen === null) vp.homeGen = vp.generation;
      $("viewport").dataset.generation = String(vp.generation);
    } else {
      $("vp-state").textContent = (r.data && (r.data.error + (r.data.fields ? ": " +
        Object.entries(r.data.fields).map(([k, v]) => `${k} ${v}`).join("; ") : ""))) || `the server answered ${r.status}`;
    }
  } finally {
    vp.sending = false;
  }
  if (vp.dirty) { vp.dirty = false; sendView(); return; }
  pollView();
}
/** Follows the session until its newest view is done; one chain of polls at a time (a send
 * while a poll is out asks that chain to poll again at once). */
async function pollView() {
  if (vp.polling) { vp.repoll = true; return; }
  if (vp.timer) { clearTimeout(vp.timer); vp.timer = null; }
  vp.polling = true;
  let delay = null;
  try {
    let r;
    try { r = await api("GET", "/api/viewport/" + vp.session); } catch (_) { r = null; }
    const c = $("viewport");
    if (r && r.ok) {
      const s = r.data;
      // Only a status of this scene's requests carries its view (an earlier scene's may still
      // be on show just after the choice).
      if (s.view && !vp.home && vp.scene === $("scene").value && vp.homeGen !== null
        && s.generation >= vp.homeGen) {
        vp.home = s.view;
        if (!vp.orbit) { vp.orbit = orbitFrom(s.view); c.dataset.orbit = "ready"; }
        showProjection();
      }
      const current = s.generation === vp.generation;
      if (current && s.version > vp.shown) {
        const lin = await fetchLinear("/api/viewport/" + vp.session + "/linear");
        if (lin && lin.version > vp.shown) {
          vp.lin = lin;
          vp.shown = lin.version;
          drawLinear(c, lin, "beauty");
          c.dataset.version = String(lin.version);
          c.dataset.samples = String(lin.samples);
          c.dataset.size = `${lin.w}x${lin.h}`;
          $("vp-samples").textContent = `${lin.w}×${lin.h} · ${lin.samples} / ${s.spp} spp`;
        }
      }
      if (current) {
        // The state is set after the image, so "done" means the last image is on show.
        const done = s.state === "done" && vp.shown >= s.version;
        $("vp-state").textContent = s.error ? "error: " + s.error : s.state;
        c.dataset.state = s.state === "done" && !done ? "refining" : s.state;
        if (s.first_ms != null) {
          $("vp-time").textContent = `first image ${Math.round(s.first_ms)} ms` +
            (s.full_ms != null ? ` · first full-size pass ${Math.round(s.full_ms)} ms` : "");
        }
        if (!done && s.state !== "failed") delay = 60;
      } else {
        delay = 60;
      }
    } else {
      delay = 500;
    }
  } finally {
    vp.polling = false;
  }
  if (vp.repoll) { vp.repoll = false; delay = 0; }
  if (delay !== null) vp.timer = setTimeout(pollView, delay);
}

init().catch((e) => { $("form-error").textContent = "could not reach the server: " + e; });

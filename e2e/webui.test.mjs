// End-to-end test of the web UI (`trayecto serve`) in headless Chromium, driven by Playwright.
// scripts/e2e.sh starts the server and passes its address in TRAYECTO_URL.
import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { chromium } from "playwright-core";

const BASE = process.env.TRAYECTO_URL;
assert.ok(BASE, "TRAYECTO_URL must name the running server");
let context;
let page;
let profile;

before(async () => {
  profile = fs.mkdtempSync(path.join(os.tmpdir(), "trayecto-chromium-"));
  context = await chromium.launchPersistentContext(profile, {
    executablePath: "/usr/bin/chromium",
    headless: true,
    acceptDownloads: true,
    viewport: { width: 1280, height: 800 },
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync"],
  });
  page = context.pages()[0] ?? (await context.newPage());
  page.setDefaultTimeout(30_000);
});

after(async () => {
  if (context) await context.close();
  if (profile) fs.rmSync(profile, { recursive: true, force: true });
});

async function openPage() {
  await page.goto(BASE + "/");
  // The form is ready once the options and scenes have arrived.
  await page.waitForSelector("#scene option[value=cornell]", { state: "attached" });
  // ... and the chosen scene's size has been filled in.
  await page.waitForFunction(() => document.getElementById("scene").dataset.prefilled);
}

async function fill(values) {
  for (const [k, v] of Object.entries(values)) {
    if (k === "scene") {
      await page.selectOption("#scene", v);
      // Choosing a scene fills in its size: wait for it before setting ours.
      await page.waitForFunction((name) => document.getElementById("scene").dataset.prefilled === name, v);
    }
    else await page.fill("#" + k, String(v));
  }
}

/** What the page shows: job state, preview version and a checksum of the preview's pixels. */
async function snapshot() {
  return page.evaluate(() => {
    const img = document.getElementById("preview");
    let sum = null;
    if (img.complete && img.naturalWidth > 0) {
      const c = document.createElement("canvas");
      c.width = img.naturalWidth;
      c.height = img.naturalHeight;
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      const d = g.getImageData(0, 0, c.width, c.height).data;
      sum = 0;
      for (let i = 0; i < d.length; i++) sum = (sum * 31 + d[i]) >>> 0;
    }
    return {
      state: document.getElementById("state").textContent,
      version: Number(img.dataset.version),
      sum,
    };
  });
}

function pngSize(buf) {
  assert.deepEqual([...buf.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a],
    "PNG signature");
  assert.equal(buf.subarray(12, 16).toString("ascii"), "IHDR");
  return [buf.readUInt32BE(16), buf.readUInt32BE(20)];
}

test("an invalid field shows its message, and fixing it clears it", async () => {
  await openPage();
  await fill({ width: 0, output: "../escape" });
  await page.click("#render");
  assert.match(await page.textContent("#err-width"), /whole number from 1 to 4096/);
  assert.match(await page.textContent("#err-output"), /plain file name/);
  assert.equal(await page.getAttribute("#width", "aria-invalid"), "true");
  await fill({ width: 64, output: "ok" });
  assert.equal(await page.textContent("#err-width"), "");
  assert.equal(await page.textContent("#err-output"), "");
  // Nothing was started.
  const r = await (await fetch(BASE + "/api/renders")).json();
  assert.equal(r.renders.length, 0);
});

test("a render shows a preview that refines before it finishes, then downloads as PNG", async () => {
  await openPage();
  // Large enough to take a few seconds even on a fast, idle machine, so several passes are seen.
  await fill({ scene: "cornell", output: "e2e-progressive", width: 160, height: 120, spp: 1024,
    secondary: 1, max_depth: 8, exposure: 1 });
  await page.click("#render");
  const seen = [];
  const t0 = Date.now();
  for (;;) {
    const s = await snapshot();
    if (s.state === "rendering" && s.sum !== null
        && !seen.some((o) => o.version === s.version)) seen.push(s);
    if (s.state === "done" || s.state === "failed") break;
    assert.ok(Date.now() - t0 < 120_000, "render did not finish");
    await new Promise((r) => setTimeout(r, 40));
  }
  assert.equal(await page.textContent("#state"), "done");
  assert.ok(seen.length >= 2, `saw ${seen.length} previews while rendering`);
  assert.ok(new Set(seen.map((s) => s.sum)).size >= 2, "the preview did not change");
  assert.match(await page.textContent("#elapsed"), /^elapsed \d/);
  assert.equal(await page.getAttribute("#progress", "value"), "1");
  // Phase timings and log are shown.
  const phases = await page.$$eval("#timings td:first-child", (tds) => tds.map((t) => t.textContent));
  assert.deepEqual(phases, ["load", "build (accel)", "render", "write", "total"]);
  assert.match(await page.textContent("#log"), /wrote (.* and )?e2e-progressive\.png/);
  // The final image downloads as a valid PNG of the requested size.
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#dl-png")]);
  assert.equal(download.suggestedFilename(), "e2e-progressive.png");
  const buf = fs.readFileSync(await download.path());
  assert.deepEqual(pngSize(buf), [160, 120]);
  // It is listed among the recent renders.
  await page.waitForSelector("#recent li:has-text('e2e-progressive')");
});

test("Cancel stops a long render", async () => {
  await openPage();
  await fill({ scene: "cornell", output: "e2e-cancel", width: 256, height: 256, spp: 16384,
    max_depth: 8 });
  await page.click("#render");
  await page.waitForFunction(() => Number(document.getElementById("preview").dataset.version) >= 1);
  assert.equal(await page.textContent("#state"), "rendering");
  const t0 = Date.now();
  await page.click("#cancel");
  await page.waitForFunction(() => document.getElementById("state").textContent === "cancelled",
    null, { timeout: 10_000 });
  const took = Date.now() - t0;
  console.log(`cancel took ${took} ms`);
  assert.ok(await page.isDisabled("#cancel"));
  const r = await (await fetch(BASE + "/api/renders")).json();
  assert.equal(r.active, 0);
  const job = r.renders.find((j) => j.output === "e2e-cancel");
  assert.equal(job.state, "cancelled");
  assert.equal(job.png, null);
});

test("three renders with --max-jobs 1 wait in the queue and complete in order", async () => {
  await openPage();
  const names = ["e2e-q1", "e2e-q2", "e2e-q3"];
  // The first is long enough that the other two are submitted while it renders.
  await fill({ scene: "cornell", output: names[0], width: 128, height: 128, spp: 1024, max_depth: 6 });
  await page.click("#render");
  for (const n of names.slice(1)) {
    await fill({ output: n, width: 32, height: 32, spp: 16 });
    await page.click("#render");
  }
  // The page follows the last one, which waits behind the other two.
  await page.waitForFunction(() => /position 2 in the queue/.test(document.getElementById("queue").textContent));
  await page.waitForSelector("#recent li:has-text('queued, position 1')");
  // A reload shows the same queue: the state is on the server.
  await page.reload();
  await page.waitForSelector("#recent li[data-state=queued]");
  const done = [];
  const t0 = Date.now();
  while (done.length < 3) {
    const r = await (await fetch(BASE + "/api/renders")).json();
    const running = r.renders.filter((j) => j.active && j.state !== "queued");
    assert.ok(running.length <= 1, JSON.stringify(running));
    // The list is newest first. Jobs that finished between two polls cannot be ordered by
    // watching, so those are taken oldest first; the order across polls is what is observed.
    for (const j of [...r.renders].reverse()) {
      if (names.includes(j.output) && j.state === "done" && !done.includes(j.output)) done.push(j.output);
    }
    // Only a guard against a hang: a loaded machine can be 10x slower than CI's idle 2 cores.
    assert.ok(Date.now() - t0 < 300_000, "the queued renders did not finish: " + done);
    await new Promise((res) => setTimeout(res, 30));
  }
  assert.deepEqual(done, names);
  await page.waitForFunction(() => document.getElementById("state").textContent === "done");
});

test("a model uploaded from the page is offered and selected", async () => {
  await openPage();
  const glb = path.resolve("../shared/scenes/gltf/Box/glTF-Binary/Box.glb");
  await page.setInputFiles("#upload", glb);
  await page.waitForFunction(() => /^uploaded Box\.glb/.test(document.getElementById("upload-status").textContent));
  assert.equal(await page.inputValue("#scene"), "uploads/Box.glb");
  // A second upload of the same name is refused with the reason.
  await page.setInputFiles("#upload", glb);
  await page.waitForFunction(() => /already uploaded/.test(document.getElementById("upload-status").textContent));
});

test("a server on 127.0.0.2 refuses the page without its token, and opens with it", async () => {
  const bare = process.env.TRAYECTO_TOKEN_SERVER;
  const withToken = process.env.TRAYECTO_TOKEN_URL;
  assert.ok(bare && withToken && withToken.includes("?token="), "the token server's addresses");
  const p = await context.newPage();
  try {
    const refused = await p.goto(bare + "/");
    assert.equal(refused.status(), 401);
    assert.match(await p.textContent("body"), /access token/);
    const api = await fetch(bare + "/api/options");
    assert.equal(api.status, 401);
    await p.goto(withToken);
    // Redirected to the bare page, which now works through its cookie (API calls included).
    assert.equal(p.url(), bare + "/");
    await p.waitForSelector("#scene option[value=cornell]", { state: "attached" });
  } finally {
    await p.close();
  }
});

/** The viewport canvas: its dataset (generation, version, samples, state) and a checksum. */
async function viewport() {
  return page.evaluate(() => {
    const c = document.getElementById("viewport");
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    let sum = 0;
    for (let i = 0; i < d.length; i++) sum = (sum * 31 + d[i]) >>> 0;
    return { generation: Number(c.dataset.generation || 0), version: Number(c.dataset.version || 0),
      samples: Number(c.dataset.samples || -1), state: c.dataset.state || "", size: c.dataset.size || "",
      sum };
  });
}

/** Waits until the viewport shows an image of a generation after `g` (a new view). */
async function waitNewView(g) {
  await page.waitForFunction((g0) => {
    const c = document.getElementById("viewport");
    return Number(c.dataset.generation) > g0 && c.dataset.version && c.dataset.state !== "loading"
      && c.dataset.state !== "rendering";
  }, g);
}

/** Watches the viewport until its image reaches `spp` samples; returns the sample counts seen. */
async function watchRefine(spp) {
  let seen = [];
  let generation = -1;
  const t0 = Date.now();
  for (;;) {
    const v = await viewport();
    const latest = await page.evaluate(() => !vp.sending && !vp.dirty && vp.generation);
    // Only the newest view counts (a drag may send several).
    if (v.generation !== generation) { seen = []; generation = v.generation; }
    if (!seen.length || seen[seen.length - 1] !== v.samples) seen.push(v.samples);
    if (latest === v.generation && v.samples >= spp && v.state === "done") return seen;
    assert.ok(Date.now() - t0 < 120_000, "the viewport did not refine: " + JSON.stringify(seen));
    await new Promise((r) => setTimeout(r, 15));
  }
}

/** Waits until the newest view has been sent and its image refined to `spp` samples. */
async function settle(spp) {
  await page.waitForFunction((n) => {
    const c = document.getElementById("viewport");
    return !vp.sending && !vp.dirty && Number(c.dataset.generation) === vp.generation
      && c.dataset.state === "done" && Number(c.dataset.samples) >= n;
  }, spp, { timeout: 120_000 });
}

async function openViewport(values, spp) {
  await openPage();
  if (values) await fill(values);
  // A view with every value filled in (fill types, which does not send views).
  await page.dispatchEvent("#width", "change");
  // The scene's own view arrives with the first image; then the orbit is ready.
  await page.waitForFunction(() => document.getElementById("viewport").dataset.orbit === "ready");
  await settle(spp);
}

test("the viewport orbits and dollies with the mouse, restarts and refines while still", async () => {
  await openViewport({ scene: "cornell", width: 200, height: 200, max_depth: 4, view_spp: 64 }, 64);
  const box = await page.locator("#viewport").boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  let before = await viewport();
  const t0 = Date.now();
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 60, cy + 10, { steps: 6 });
  await page.mouse.up();
  await waitNewView(before.generation);
  console.log(`orbit: first new image on the page after ${Date.now() - t0} ms`);
  let after = await viewport();
  assert.notEqual(after.sum, before.sum, "the orbit did not change the image");
  // While still, the preview refines: more samples in later images, up to the view's 64.
  const seen = await watchRefine(64);
  assert.ok(seen.length >= 2, "no refinement seen: " + JSON.stringify(seen));
  for (let i = 1; i < seen.length; i++) assert.ok(seen[i] > seen[i - 1], JSON.stringify(seen));
  assert.equal((await viewport()).size, "200x200");
  console.log("viewport timings: " + await page.textContent("#vp-time"));
  // The wheel dollies.
  before = await viewport();
  await page.mouse.move(cx, cy);
  await page.mouse.wheel(0, 400);
  await waitNewView(before.generation);
  await settle(64);
  after = await viewport();
  assert.notEqual(after.sum, before.sum, "the wheel did not change the image");
  // Shift-drag pans.
  before = after;
  await page.keyboard.down("Shift");
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 30, cy, { steps: 3 });
  await page.mouse.up();
  await page.keyboard.up("Shift");
  await waitNewView(before.generation);
  await settle(64);
  assert.notEqual((await viewport()).sum, before.sum, "shift-drag did not change the image");
});

test("the keyboard orbits a focused, labelled viewport", async () => {
  await openViewport({ scene: "cornell", width: 64, height: 64, max_depth: 3, view_spp: 4 }, 4);
  assert.match(await page.getAttribute("#viewport", "aria-label"), /orbit/);
  assert.equal(await page.getAttribute("#viewport", "tabindex"), "0");
  await page.focus("#viewport");
  for (const key of ["ArrowLeft", "Equal", "Shift+ArrowUp"]) {
    const before = await viewport();
    const orbit = await page.evaluate(() => JSON.stringify(vp.orbit));
    await page.keyboard.press(key);
    assert.notEqual(await page.evaluate(() => JSON.stringify(vp.orbit)), orbit, key);
    await settle(4);
    assert.notEqual((await viewport()).sum, before.sum, `${key} did not change the image`);
  }
});

/** Waits for the followed job's final image on the page. */
async function waitFinal() {
  await page.waitForFunction(() => {
    const f = document.getElementById("final");
    return document.getElementById("state").textContent === "done" && !f.hidden
      && f.dataset.job === String(current);
  });
}

/** How many bytes of the final render's canvas differ from the viewport's (or why they cannot
 * be compared). */
async function finalVsViewport() {
  return page.evaluate(() => {
    const a = document.getElementById("viewport"), b = document.getElementById("final");
    const da = a.getContext("2d").getImageData(0, 0, a.width, a.height).data;
    const db = b.getContext("2d").getImageData(0, 0, b.width, b.height).data;
    if (a.width !== b.width || a.height !== b.height) return `sizes ${a.width}x${a.height} vs ${b.width}x${b.height}`;
    let n = 0;
    for (let i = 0; i < da.length; i++) if (da[i] !== db[i]) n++;
    return n;
  });
}

test("Render final renders the framed view, the same image the viewport refined to", async () => {
  await openViewport({ scene: "cornell", output: "e2e-final", width: 48, height: 40, spp: 8,
    max_depth: 4, view_spp: 8, exposure: 1 }, 8);
  await page.selectOption("#tonemap", "clamp");
  await page.focus("#viewport");
  await page.keyboard.press("ArrowRight");
  await page.keyboard.press("ArrowDown");
  await page.keyboard.press("-");
  await settle(8);
  const camera = await page.evaluate(() => orbitCamera(vp.orbit));
  await page.click("#render");
  await waitFinal();
  const r = await (await fetch(BASE + "/api/renders")).json();
  const job = r.renders.find((j) => j.output === "e2e-final");
  for (const k of ["eye", "target", "up"]) {
    job.camera[k].forEach((x, i) => assert.ok(Math.abs(x - camera[k][i]) < 1e-4, `${k}: ${job.camera[k]} vs ${camera[k]}`));
  }
  // Same view, size, samples and settings: the final image is the viewport's, pixel for pixel.
  const same = await finalVsViewport();
  assert.equal(same, 0, "the final image differs from the viewport's");
});

test("an orthographic scene camera is kept until the view moves, and the page says when it is not", async () => {
  await openViewport({ scene: "orthographic.pbrt", output: "e2e-ortho", width: 64, height: 48, spp: 4,
    max_depth: 5, view_spp: 4, exposure: 1 }, 4);
  // The orbit flag may still be the first scene's: wait for this scene's view to arrive.
  await page.waitForFunction(() => vp.home && vp.home.projection === "orthographic");
  await settle(4);
  await page.selectOption("#tonemap", "clamp");
  const note = () => page.evaluate(() => {
    const p = document.getElementById("vp-projection");
    return { hidden: p.hidden, text: p.textContent, projection: document.getElementById("viewport").dataset.projection };
  });
  let n = await note();
  assert.equal(n.projection, "orthographic");
  assert.ok(!n.hidden && /orthographic camera/.test(n.text) && !/Perspective/.test(n.text), n.text);
  // Unmoved, Render final sends no camera: the scene's own (orthographic) camera renders, the
  // same image the viewport refined to.
  await page.click("#render");
  await waitFinal();
  const r = await (await fetch(BASE + "/api/renders")).json();
  const job = r.renders.find((j) => j.output === "e2e-ortho");
  assert.equal(job.camera, null, "the unmoved view sent a camera: " + JSON.stringify(job.camera));
  assert.equal(await finalVsViewport(), 0, "the final image differs from the viewport's");
  // An orbit turns it into a perspective view, and the note says so.
  const g = (await viewport()).generation;
  await page.focus("#viewport");
  await page.keyboard.press("ArrowRight");
  await waitNewView(g);
  n = await note();
  assert.equal(n.projection, "perspective");
  assert.ok(!n.hidden && /^Perspective view/.test(n.text), n.text);
  // Reset view returns to the scene's camera.
  await page.click("#reset-view");
  await settle(4);
  n = await note();
  assert.equal(n.projection, "orthographic");
  assert.ok(!/Perspective/.test(n.text), n.text);
});

/** Mean display RGB (0-255) of a canvas. */
async function meanRgb(id) {
  return page.evaluate((id) => {
    const c = document.getElementById(id);
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    const m = [0, 0, 0];
    for (let i = 0; i < d.length; i += 4) for (let k = 0; k < 3; k++) m[k] += d[i + k];
    return m.map((x) => x / (d.length / 4));
  }, id);
}

/** The channel (0 r, 1 g, 2 b) that leads the others by more than 40 of 255, or -1. */
function dominant(rgb) {
  for (let k = 0; k < 3; k++) {
    if (rgb.every((x, j) => j === k || rgb[k] - x > 40)) return k;
  }
  return -1;
}

test("a glTF scene's material variants are offered and change the viewport and the final render", async () => {
  // The quad fills the view: blue by default, red or green as its variants say.
  await openViewport({ scene: "quad_variants.gltf", output: "e2e-variant", width: 32, height: 32,
    spp: 4, max_depth: 2, view_spp: 4, exposure: 1 }, 4);
  assert.ok(await page.isVisible("#variant"), "the variant picker is not shown");
  assert.deepEqual(await page.$$eval("#variant option", (os) => os.map((o) => o.value)), ["", "Red", "Green"]);
  assert.equal(dominant(await meanRgb("viewport")), 2, "default materials: " + await meanRgb("viewport"));
  for (const [variant, channel] of [["Green", 1], ["Red", 0]]) {
    const before = await viewport();
    await page.selectOption("#variant", variant);
    await waitNewView(before.generation);
    await settle(4);
    const rgb = await meanRgb("viewport");
    assert.equal(dominant(rgb), channel, `viewport with variant ${variant}: ${rgb}`);
  }
  // The final render uses the chosen variant (Red) and equals the viewport's image.
  await page.selectOption("#tonemap", "clamp");
  await page.click("#render");
  await waitFinal();
  const r = await (await fetch(BASE + "/api/renders")).json();
  const job = r.renders.find((j) => j.output === "e2e-variant");
  assert.equal(job.variant, "Red");
  assert.equal(dominant(await meanRgb("final")), 0, "final render: " + await meanRgb("final"));
  const differ = await finalVsViewport();
  assert.equal(differ, 0, "the final image differs from the viewport's");
  // A scene without variants hides the picker and forgets the choice.
  await fill({ scene: "cornell" });
  assert.ok(!(await page.isVisible("#variant")), "the variant picker is shown for the Cornell box");
  assert.equal(await page.inputValue("#variant"), "");
});

test("exposure and tone mapping apply on the page and match the server's PNG within 1/255", async () => {
  await openPage();
  const tonemaps = await page.$$eval("#tonemap option", (os) => os.map((o) => o.value));
  assert.ok(tonemaps.length >= 4, tonemaps.join());
  for (const [i, tm] of tonemaps.entries()) {
    await fill({ scene: "cornell", output: `e2e-tm-${i}`, width: 40, height: 30, spp: 4, max_depth: 4,
      exposure: 2.5 });
    await page.selectOption("#tonemap", tm);
    await page.click("#render");
    await page.waitForFunction((name) => {
      const c = document.getElementById("final");
      return document.getElementById("state").textContent === "done" && !c.hidden
        && c.dataset.layer === "beauty" && c.dataset.job === String(current) && document.getElementById("dl-png").href.includes("/image.png")
        && document.getElementById("dl-png").download === name + ".png";
    }, `e2e-tm-${i}`);
    const worst = await page.evaluate(async () => {
      const png = document.getElementById("dl-png").href;
      const img = new Image();
      img.src = png;
      await img.decode();
      const c = document.createElement("canvas");
      c.width = img.naturalWidth; c.height = img.naturalHeight;
      c.getContext("2d").drawImage(img, 0, 0);
      const a = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
      const f = document.getElementById("final");
      const b = f.getContext("2d").getImageData(0, 0, f.width, f.height).data;
      if (a.length !== b.length) return 999;
      let worst = 0;
      for (let i = 0; i < a.length; i++) worst = Math.max(worst, Math.abs(a[i] - b[i]));
      return worst;
    });
    assert.ok(worst <= 1, `${tm}: the page's tone mapping differs from the server's PNG by ${worst}/255`);
  }
  // Changing the exposure re-displays the image without a new render.
  const count = (await (await fetch(BASE + "/api/renders")).json()).renders.length;
  const sum = () => page.evaluate(() => {
    const f = document.getElementById("final");
    const d = f.getContext("2d").getImageData(0, 0, f.width, f.height).data;
    let s = 0; for (let i = 0; i < d.length; i++) s = (s * 31 + d[i]) >>> 0; return s;
  });
  const s0 = await sum();
  await page.fill("#exposure", "0.25");
  await page.waitForFunction((s) => {
    const f = document.getElementById("final");
    const d = f.getContext("2d").getImageData(0, 0, f.width, f.height).data;
    let x = 0; for (let i = 0; i < d.length; i++) x = (x * 31 + d[i]) >>> 0; return x !== s;
  }, s0);
  assert.notEqual(await sum(), s0);
  assert.equal((await (await fetch(BASE + "/api/renders")).json()).renders.length, count);
});

test("the layer toggle shows the albedo and normal AOVs of a final render", async () => {
  await openPage();
  await fill({ scene: "cornell", output: "e2e-aov", width: 32, height: 32, spp: 2, max_depth: 3 });
  await page.check("#aovs");
  await page.click("#render");
  await page.waitForFunction(() => !document.getElementById("layers").hidden
    && document.getElementById("final").dataset.layer === "beauty" && !document.getElementById("final").hidden
    && document.getElementById("final").dataset.job === String(current));
  assert.ok(await page.isHidden("#layers [data-layer=denoised]"));
  const sums = {};
  for (const layer of ["albedo", "normal", "beauty"]) {
    await page.click(`#layers [data-layer=${layer}]`);
    await page.waitForFunction((l) => document.getElementById("final").dataset.layer === l, layer);
    assert.equal(await page.getAttribute(`#layers [data-layer=${layer}]`, "aria-pressed"), "true");
    sums[layer] = await page.evaluate(() => {
      const f = document.getElementById("final");
      const d = f.getContext("2d").getImageData(0, 0, f.width, f.height).data;
      let s = 0; for (let i = 0; i < d.length; i++) s = (s * 31 + d[i]) >>> 0; return s;
    });
  }
  assert.equal(new Set(Object.values(sums)).size, 3, JSON.stringify(sums));
  await page.uncheck("#aovs");
});

test("Save camera downloads a TOML camera the CLI reads", async () => {
  await openViewport({ scene: "cornell", width: 64, height: 64, view_spp: 1 }, 1);
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#save-camera")]);
  const text = fs.readFileSync(await download.path(), "utf8");
  assert.match(text, /^\[\[camera\]\]\neye = \[.*\]\ntarget = \[.*\]\nup = \[.*\]\nfov = [\d.]+\n$/);
});

test("screenshot for the README", { skip: !process.env.WEBUI_SCREENSHOT }, async () => {
  await openPage();
  const glb = path.resolve("../shared/scenes/gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
  await page.setInputFiles("#upload", glb);
  await page.waitForFunction(() => /^uploaded DamagedHelmet\.glb/.test(document.getElementById("upload-status").textContent));
  await page.waitForFunction(() => document.getElementById("scene").dataset.prefilled === "uploads/DamagedHelmet.glb");
  await page.selectOption("#environment", "studio_small_03_1k.hdr");
  await fill({ width: 400, height: 400, max_depth: 6, view_spp: 32 });
  await page.selectOption("#tonemap", "agx");
  await page.dispatchEvent("#environment", "change");
  await page.waitForFunction(() => document.getElementById("viewport").dataset.orbit === "ready",
    null, { timeout: 300_000 });
  const box = await page.locator("#viewport").boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  const g = (await viewport()).generation;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 70, cy + 25, { steps: 5 });
  await waitNewView(g);
  await page.waitForFunction(() => Number(document.getElementById("viewport").dataset.samples) >= 8,
    null, { timeout: 300_000 });
  await page.screenshot({ path: process.env.WEBUI_SCREENSHOT });
  await page.mouse.up();
});

test("the page fits 1400, 1280 and 390 px windows: nothing cut, one render button", async () => {
  for (const width of [1400, 1280, 390]) {
    await page.setViewportSize({ width, height: 900 });
    await openPage();
    const r = await page.evaluate(() => {
      const doc = document.documentElement;
      const ctx = document.createElement("canvas").getContext("2d");
      const cut = [];
      for (const sel of document.querySelectorAll("#render-form select")) {
        if (sel.closest("[hidden]")) continue;
        const st = getComputedStyle(sel);
        ctx.font = `${st.fontSize} ${st.fontFamily}`;
        // The widest choice plus the padding and the arrow must fit the box.
        const widest = Math.max(0, ...[...sel.options].map((o) => ctx.measureText(o.textContent).width));
        if (widest + 28 > sel.getBoundingClientRect().width) cut.push(`${sel.id} (${Math.round(widest)} px)`);
      }
      const buttons = [...document.querySelectorAll("button")].filter((b) => /render/i.test(b.textContent)
        && !b.closest("#recent") && b.offsetParent !== null);
      return { overflow: doc.scrollWidth - doc.clientWidth, cut, buttons: buttons.map((b) => b.id) };
    });
    assert.ok(r.overflow <= 0, `${width} px: the page is ${r.overflow} px wider than the window`);
    assert.deepEqual(r.cut, [], `${width} px: choices cut`);
    assert.deepEqual(r.buttons, ["render"], `${width} px: render buttons`);
  }
  // The button says what the render is doing, and is back to "Render" when it ends.
  await page.setViewportSize({ width: 1280, height: 800 });
  await openPage();
  assert.equal((await page.textContent("#render")).trim(), "Render");
  await fill({ scene: "cornell", output: "e2e-button", width: 64, height: 64, spp: 256, max_depth: 4 });
  await page.click("#render");
  await page.waitForFunction(() => document.getElementById("render").dataset.state !== "idle");
  await page.waitForFunction(() => document.getElementById("render").dataset.state === "idle", null, { timeout: 60_000 });
  assert.equal((await page.textContent("#render")).trim(), "Render");
  assert.match(await page.textContent("#render-state"), /done: e2e-button/);
  // The form starts from the command line's defaults.
  const o = await (await fetch(BASE + "/api/options")).json();
  assert.equal(o.defaults.max_depth, 64);
});

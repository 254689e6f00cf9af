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
}

async function fill(values) {
  for (const [k, v] of Object.entries(values)) {
    if (k === "scene") await page.selectOption("#scene", v);
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
  await page.click("#start");
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
  await page.click("#start");
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
  assert.match(await page.textContent("#log"), /wrote e2e-progressive\.png/);
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
  await page.click("#start");
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

test("screenshot for the README", { skip: !process.env.WEBUI_SCREENSHOT }, async () => {
  await openPage();
  await fill({ scene: "cornell", output: "cornell", width: 256, height: 256, spp: 48, max_depth: 8 });
  await page.click("#start");
  await page.waitForFunction(() => document.getElementById("state").textContent === "done",
    null, { timeout: 300_000 });
  await page.waitForFunction(() => document.getElementById("preview").complete);
  await page.screenshot({ path: process.env.WEBUI_SCREENSHOT });
});

// End-to-end tests of the browser UI (issues #8, #15) in headless Chromium, driven by
// Playwright, against a running landsketch server started with the admin token
// `$LANDSKETCH_ADMIN_TOKEN`:
//
//   LANDSKETCH_ADMIN_TOKEN=… node tests/browser/e2e.mjs http://127.0.0.1:8080 [--screenshots docs/ui]
//
// `cargo test --test browser` starts a server and runs this. The page opens in citizen mode;
// the planner's checks log in first. axe-core checks accessibility in both modes. Chromium: /usr/bin/chromium or
// $CHROMIUM. Every check asserts real behaviour (frames arrive, pixels change, the server's
// messages are shown); there are no timed assertions, only generous waits against hangs.

import assert from 'node:assert/strict';
import { mkdtempSync, mkdirSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '../..');
const args = process.argv.slice(2);
const base = args[0];
if (!base) {
  console.error('usage: node tests/browser/e2e.mjs <base-url> [--screenshots DIR]');
  process.exit(2);
}
const TOKEN = process.env.LANDSKETCH_ADMIN_TOKEN;
if (!TOKEN) {
  console.error('LANDSKETCH_ADMIN_TOKEN must name the admin token the server was started with');
  process.exit(2);
}
/** Words of the planner's tools and of the renderer's internals that a citizen never reads. */
const JARGON = ['hlp', 'tam', 'sam', 'contour', 'albedo', 'gooch', '+proj', 'epsg', 'fps', 'rtt'];
const shotsAt = args.indexOf('--screenshots');
const shots = shotsAt >= 0 ? resolve(args[shotsAt + 1]) : null;
if (shots) mkdirSync(shots, { recursive: true });

/** Longest wait for anything (a frame renders in about a second on lavapipe). */
const WAIT = 120_000;
/** Render scale of the viewer: small frames (rendering is on the CPU), full size for screenshots. */
const RENDER_SCALE = shots ? 1 : 0.25;
const SERIES = ['2024-06-01', '2024-06-11'].map((day) => ({
  day,
  path: join(root, `data/test/fields/series_${day}.tif`),
}));

const FLAGS = [
  '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync',
];

const profile = mkdtempSync(join(tmpdir(), 'landsketch-chromium-'));
const context = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  args: FLAGS,
  viewport: { width: 1280, height: 720 },
  acceptDownloads: true,
});
await context.grantPermissions(['clipboard-read', 'clipboard-write'], { origin: base });
await context.addInitScript((scale) => localStorage.setItem('landsketch.renderScale', scale), String(RENDER_SCALE));

/** Console errors and page errors of every page, with the step they happened in. */
const problems = [];
/** Failed requests the tests cause on purpose: `[step, part of the URL or message]`. */
const expected = [];
let step = 'start';

function watch(page) {
  page.on('console', (message) => {
    if (message.type() === 'error') problems.push({ step, text: message.text(), url: message.location().url });
  });
  page.on('pageerror', (error) => problems.push({ step, text: `page error: ${error.message}` }));
  page.on('response', (response) => {
    const status = response.status();
    if (status >= 400) problems.push({ step, text: `HTTP ${status}`, url: response.url(), status });
  });
  return page;
}

async function check(name, body) {
  step = name;
  const started = Date.now();
  await body();
  console.log(`ok - ${name} (${((Date.now() - started) / 1000).toFixed(1)} s)`);
}

/** The id of the last frame drawn (0 before the first). */
async function frameId(page) {
  return Number((await page.locator('#frame').getAttribute('data-frame-id')) ?? 0);
}

/** Waits for a still frame newer than frame `after`; returns its camera. */
async function nextStill(page, after) {
  await page.waitForFunction((id) => {
    const canvas = document.getElementById('frame');
    return Number(canvas.dataset.frameId ?? 0) > id && canvas.dataset.still === 'true';
  }, after, { timeout: WAIT });
  return JSON.parse(await page.locator('#frame').getAttribute('data-camera'));
}

/**
 * Waits for a still frame after which no other frame arrives for a while: a session that just
 * opened may follow its first still with the frames of controls the page sends on `hello`.
 */
async function settledStill(page) {
  let camera = await nextStill(page, 0);
  for (;;) {
    const id = await frameId(page);
    await page.waitForTimeout(600);
    if ((await frameId(page)) === id) return camera;
    camera = await nextStill(page, id);
  }
}

/** Runs `action` and waits for the still frame it causes. */
async function stillAfter(page, action) {
  const before = await frameId(page);
  await action();
  return nextStill(page, before);
}

/** The shown frame as 64 × 48 grey levels, and its share of dark and light pixels. */
async function pixels(page) {
  return page.evaluate(() => {
    const source = document.getElementById('frame');
    const small = Object.assign(document.createElement('canvas'), { width: 64, height: 48 });
    const g = small.getContext('2d');
    g.drawImage(source, 0, 0, 64, 48);
    const data = g.getImageData(0, 0, 64, 48).data;
    const grey = [];
    for (let i = 0; i < data.length; i += 4) grey.push((data[i] + data[i + 1] + data[i + 2]) / 3);
    const full = source.getContext('2d').getImageData(0, 0, source.width, source.height).data;
    let dark = 0;
    let light = 0;
    for (let i = 0; i < full.length; i += 4) {
      const v = (full[i] + full[i + 1] + full[i + 2]) / 3;
      if (v < 96) dark += 1;
      if (v > 200) light += 1;
    }
    const n = full.length / 4;
    return { grey, dark: dark / n, light: light / n, width: source.width, height: source.height };
  });
}

/** Mean grey level of a frame (0…255): lower is more ink. */
function brightness(p) {
  return p.grey.reduce((sum, v) => sum + v, 0) / p.grey.length;
}

/** Mean absolute grey-level difference of two frames (0…255). */
function difference(a, b) {
  return a.grey.reduce((sum, v, i) => sum + Math.abs(v - b.grey[i]), 0) / a.grey.length;
}

/** A visible change: the frames differ by more than JPEG noise. */
const CHANGED = 1.0;

/**
 * Waits until the page's address (the view's link, updated a moment after each change) has a
 * parameter `name` that `accept(value, arg)` accepts (it runs in the page: only its arguments
 * are in scope); fails with the last value if it never does.
 */
async function linked(page, name, accept, arg = null) {
  try {
    await page.waitForFunction(
      ([n, source, a]) => new Function('v', 'a', `return (${source})(v, a)`)(new URL(location.href).searchParams.get(n), a),
      [name, accept.toString(), arg],
      { timeout: WAIT },
    );
  } catch {
    assert.fail(`the link's ${name} is ${new URL(page.url()).searchParams.get(name)}`);
  }
}

async function openPane(page, name) {
  await page.locator(`#tab-${name}`).click();
  await page.locator(`#pane-${name}`).waitFor({ state: 'visible' });
}

/** The visible controls that have no label (no `<label>`, `aria-label` or text). */
async function unlabelled(page) {
  return page.locator('input, select, button, output').evaluateAll((controls) => controls
    .filter((c) => c.getClientRects().length && !c.labels?.length && !c.getAttribute('aria-label') && !c.textContent.trim())
    .map((c) => c.outerHTML));
}

/** Mean grey level of a grey canvas (runs in the page). */
function canvasMean(canvas) {
  const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
  let sum = 0;
  for (let i = 0; i < data.length; i += 4) sum += data[i];
  return sum / (data.length / 4);
}

/** Mean grey level of the art-map paint canvas. */
async function paintBrightness(page) {
  return page.locator('#art-canvas').evaluate(canvasMean);
}

/** Waits until the art-map list shows `kind` `index` with `source` (`generated` or `uploaded`). */
async function artSource(page, kind, index, source) {
  await page.waitForFunction(
    ([k, i, s]) => document.querySelector(`#art-${k}s li.artmap[data-index="${i}"]`)?.dataset.source === s,
    [kind, index, source],
    { timeout: WAIT },
  );
}

/** The serious and critical accessibility violations axe-core finds on the page. */
async function axeViolations(page) {
  await page.addScriptTag({ path: join(here, 'node_modules/axe-core/axe.min.js') });
  const violations = await page.evaluate(async () => (await window.axe.run(document, { resultTypes: ['violations'] })).violations
    .filter((v) => v.impact === 'serious' || v.impact === 'critical')
    .map((v) => `${v.id} (${v.impact}): ${v.nodes.slice(0, 3).map((n) => n.target.join(' ')).join(', ')}`));
  return violations;
}

/** The jargon words (`JARGON`) in the page's visible text, each with a few words around it. */
async function jargonIn(page) {
  const text = (await page.evaluate(() => document.body.innerText)).toLowerCase();
  return JARGON.flatMap((word) => {
    const found = [];
    for (let at = text.indexOf(word); at >= 0; at = text.indexOf(word, at + 1)) found.push(`${word}: …${text.slice(Math.max(0, at - 30), at + 30)}…`);
    return found;
  });
}

/** Logs in as planner with `token` through the login dialog; returns the dialog's status text. */
async function login(page, token) {
  await page.locator('#login').click();
  await page.locator('#login-dialog').waitFor({ state: 'visible' });
  await page.locator('#login-token').waitFor({ state: 'visible' });
  await page.locator('#login-token').fill(token);
  await page.locator('#login-submit').click();
  await page.waitForFunction(() => document.body.dataset.mode === 'planner' || document.getElementById('login-status').textContent, null, { timeout: WAIT });
  return page.locator('#login-status').textContent();
}

/** Controls a finger can hardly hit: visible ones smaller than 44 × 44 CSS pixels. */
async function smallControls(page) {
  return page.locator('button, select, input:not([type="hidden"]), [role="tab"], [role="radio"], canvas[role="button"]').evaluateAll((controls) => controls
    .filter((c) => c.getClientRects().length && getComputedStyle(c).visibility !== 'hidden')
    .map((c) => [c, c.getBoundingClientRect()])
    .filter(([c, r]) => (r.height < 44 || r.width < 44) && !(c.type === 'checkbox' && c.closest('label, .check')))
    .map(([c, r]) => `${c.id || c.outerHTML.slice(0, 60)} ${Math.round(r.width)}×${Math.round(r.height)}`));
}

async function shot(page, name) {
  if (shots) await page.screenshot({ path: join(shots, `${name}.jpg`), type: 'jpeg', quality: 80 });
}

async function upload(page, { name, kind, time, file }) {
  await openPane(page, 'upload');
  await page.locator('#upload-file').setInputFiles(file);
  await page.locator('#upload-name').fill(name);
  await page.locator('#upload-kind').selectOption(kind);
  await page.locator('#upload-time').fill(time ?? '');
  await page.locator('#upload-submit').click();
  const status = page.locator('#upload-status');
  await page.waitForFunction(() => ['ok', 'error'].includes(document.getElementById('upload-status').dataset.kind), null, { timeout: WAIT });
  return { kind: await status.getAttribute('data-kind'), text: await status.textContent() };
}

const page = watch(await context.newPage());
/** The camera of the default view, and the camera the page shows now. */
let initial;
let camera;

try {
  await check('the page loads in citizen mode with a welcome and shows frames', async () => {
    await page.goto(base);
    camera = await nextStill(page, 0);
    initial = camera;
    assert.equal(await page.locator('#connection').getAttribute('data-state'), 'open');
    assert.equal(await page.locator('body').getAttribute('data-mode'), 'citizen');
    assert.match(await page.locator('#welcome-title').textContent(), /Boulder/);
    assert.match(await page.locator('#welcome-plan').textContent(), /woodland/);
    assert.equal(await page.locator('#legend-ground li').count(), 3, 'the ground\'s three land-cover classes in the legend');
    assert.match(await page.locator('#legend-ground').textContent(), /Ground: forest/);
    assert.ok(await page.locator('#hint').isVisible(), 'first-use hints on how to move');
    await shot(page, 'citizen');
    await page.locator('#hint-close').click();
    assert.ok(await page.locator('#hint').isHidden(), 'the hints go once read');
    assert.equal(await page.evaluate(() => document.activeElement.id), 'viewer', 'the keys walk after "Got it"');
    const p = await pixels(page);
    const viewer = await page.locator('#viewer').evaluate((v) => v.clientWidth);
    assert.ok(Math.abs(p.width - Math.round(viewer * RENDER_SCALE)) <= 1, `frames of ${RENDER_SCALE} × the viewer (${viewer} px), got ${p.width} × ${p.height}`);
    assert.ok(p.dark > 0.005, `ink in the frame: ${(p.dark * 100).toFixed(2)} % dark`);
    assert.ok(p.light > 0.2, `paper in the frame: ${(p.light * 100).toFixed(2)} % light`);
    const link = await page.locator('#link').inputValue();
    assert.match(link, /[?&]x=.*&yaw=/, `the view is in the link: ${link}`);
    assert.deepEqual(await unlabelled(page), [], 'every visible control has a label');
    assert.deepEqual(await jargonIn(page), [], 'no jargon in citizen mode');
    assert.deepEqual(await axeViolations(page), [], 'axe-core: no serious or critical violations in citizen mode');
  });

  await check('a kiosk without login offers nothing that changes what others see', async () => {
    for (const id of ['#tab-style', '#tab-upload', '#tab-art', '#style-reset', '#upload-submit', '#stats']) {
      assert.ok(await page.locator(id).isHidden(), `${id} hidden in citizen mode`);
    }
    await openPane(page, 'data');
    assert.equal(await page.locator('button.danger:visible').count(), 0, 'no delete buttons');
    await openPane(page, 'about');
  });

  await check('the first-time citizen flow: go to the plan, with and without it, highlight it, share the link', async () => {
    const looking = await pixels(page);
    const there = await stillAfter(page, () => page.locator('#go-plan').click());
    assert.ok(Math.hypot(there.position[0] - camera.position[0], there.position[1] - camera.position[1]) > 50, 'moved to the plan');
    assert.ok(difference(looking, await pixels(page)) > CHANGED, 'a new view');
    assert.equal(await page.evaluate(() => document.activeElement.id), 'viewer', 'the keys walk after a button');
    const withPlan = await pixels(page);
    await stillAfter(page, () => page.locator('#with-plan').click());
    assert.equal(await page.locator('#with-plan').getAttribute('aria-pressed'), 'false');
    assert.match(await page.locator('#legend-planned').textContent(), /hidden/);
    await linked(page, 'layer_styles', (v) => v === JSON.stringify({ planned: { visible: false } }));
    const without = await pixels(page);
    assert.ok(difference(withPlan, without) > CHANGED, 'the plan disappeared');
    await stillAfter(page, () => page.locator('#with-plan').click());
    assert.ok(difference(without, await pixels(page)) > CHANGED, 'the plan is back');
    await stillAfter(page, () => page.locator('#highlight-plan').click());
    await linked(page, 'style', (v) => v !== null && JSON.parse(v).focus === 1);
    assert.equal(await page.locator('#highlight-plan').getAttribute('aria-pressed'), 'true');
    await shot(page, 'citizen-highlight');
    const coloured = await page.evaluate(() => {
      const c = document.getElementById('frame');
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let n = 0;
      for (let i = 0; i < d.length; i += 4) if (Math.max(d[i], d[i + 1], d[i + 2]) - Math.min(d[i], d[i + 1], d[i + 2]) > 40) n += 1;
      return n / (d.length / 4);
    });
    assert.ok(coloured > 0.001, `the plan in colour over the sketch: ${(coloured * 100).toFixed(2)} % coloured pixels`);
    await stillAfter(page, () => page.locator('#with-plan').click());
    await page.locator('#copy-link').click();
    const link = await page.locator('#link').inputValue();
    const other = watch(await context.newPage());
    await other.goto(link);
    const opened = await settledStill(other);
    for (let i = 0; i < 2; i += 1) assert.ok(Math.abs(opened.position[i] - there.position[i]) < 0.01, 'the same place');
    assert.equal(await other.locator('#with-plan').getAttribute('aria-pressed'), 'false', 'the link opens the comparison: without the plan');
    await other.close();
    await page.bringToFront();
    await stillAfter(page, () => page.locator('#with-plan').click());
  });

  await check('a citizen comments on a place: pinned in the view, listed, stored where it was pointed at', async () => {
    await openPane(page, 'comments');
    const before = await pixels(page);
    await page.locator('#comment-add').click();
    assert.match(await page.locator('#comment-message').textContent(), /place in the view/);
    const box = await page.locator('#viewer').boundingBox();
    await page.locator('#viewer').click({ position: { x: box.width / 2, y: box.height * 0.85 } });
    await page.locator('#comment-form').waitFor({ state: 'visible' });
    await page.locator('#comment-text').fill('The hedge would block my view of the hills');
    await page.locator('#comment-category').selectOption('concern');
    await stillAfter(page, () => page.locator('#comment-send').click());
    await page.locator('#comment-list li').first().waitFor({ state: 'visible', timeout: WAIT });
    assert.match(await page.locator('#comment-list').textContent(), /block my view/);
    assert.match(await page.locator('#comment-message').textContent(), /number 1/);
    assert.equal(await page.locator('#comments-show').getAttribute('aria-pressed'), 'true');
    assert.ok(difference(before, await pixels(page)) > 0, 'the pin is drawn in the view');
    const stored = await page.evaluate(async () => (await (await fetch('/api/comments')).json()).comments);
    assert.equal(stored.length, 1);
    assert.equal(stored[0].category, 'concern');
    assert.ok(['terrain', 'plant'].includes(stored[0].hit.kind), `pointed at the ground or a plant: ${JSON.stringify(stored[0].hit)}`);
    await shot(page, 'citizen-comment');
    await stillAfter(page, () => page.locator('#comments-show').click());
    assert.equal(await page.locator('#comments-show').getAttribute('aria-pressed'), 'false');
    await openPane(page, 'about');
  });

  await check("the planner's viewpoints are places to look from", async () => {
    const buttons = page.locator('#viewpoints button');
    await buttons.first().waitFor({ state: 'visible', timeout: WAIT });
    const scene = await page.evaluate(async () => (await (await fetch('/api/viewpoints')).json()).viewpoints);
    assert.equal(await buttons.count(), scene.length);
    const first = scene[0];
    const camera = await stillAfter(page, () => buttons.first().click());
    assert.ok(Math.hypot(camera.position[0] - first.camera.position[0], camera.position[1] - first.camera.position[1]) < 1, 'at the viewpoint');
    assert.equal(await page.locator('#message').textContent(), first.caption);
    assert.equal(await page.evaluate(() => document.activeElement.id), 'viewer', 'the keys walk after a viewpoint');
    await stillAfter(page, () => page.locator('#go-plan').click());
  });

  await check('a look is chosen from pictures, not parameters', async () => {
    const looks = page.locator('#looks [role="radio"]');
    assert.ok((await looks.count()) >= 3, 'three or more looks');
    await page.waitForFunction(() => [...document.querySelectorAll('#looks img')].every((img) => img.complete && img.naturalWidth > 0), null, { timeout: WAIT });
    const before = await pixels(page);
    const photo = page.locator('#looks [data-preset="photorealism"]');
    await stillAfter(page, () => photo.click());
    assert.equal(await photo.getAttribute('aria-checked'), 'true');
    await linked(page, 'preset', (v) => v === 'photorealism');
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'the look changed the picture');
    await stillAfter(page, () => page.locator('#looks [data-preset=""]').click());
    await linked(page, 'preset', (v) => v === null);
  });

  await check("a tour flies through the planner's three viewpoints with their captions", async () => {
    const before = JSON.parse(await page.locator('#frame').getAttribute('data-camera'));
    await page.locator('#tour').click();
    await page.waitForFunction(() => /\(\d of 3\)/.test(document.getElementById('tour-caption').textContent), null, { timeout: WAIT });
    await page.waitForFunction((yaw) => {
      const camera = JSON.parse(document.getElementById('frame').dataset.camera);
      return camera.position[2] > 0 && Math.abs(camera.pitch - yaw.pitch) > 1;
    }, before, { timeout: WAIT });
    await page.locator('#tour').click();
    await page.waitForFunction(() => document.getElementById('tour-caption').hidden, null, { timeout: WAIT });
    assert.equal(await page.locator('#tour').getAttribute('aria-pressed'), 'false');
    await settledStill(page);
    await stillAfter(page, () => page.locator('#reset-view').click());
  });

  await check("orientation: compass, mini map, bird's-eye view with a scale bar", async () => {
    await page.waitForFunction(() => document.getElementById('minimap-image').naturalWidth > 0, null, { timeout: WAIT });
    assert.match(await page.locator('#compass').getAttribute('aria-label'), /looks (north|east|south|west)/);
    await stillAfter(page, () => page.locator('#plan').click());
    await linked(page, 'mode', (v) => v === 'plan');
    assert.ok(await page.locator('#scalebar').isVisible(), 'a scale bar in the plan view');
    assert.match(await page.locator('#scalebar-label').textContent(), /^\d+ k?m$/);
    const box = await page.locator('#minimap').boundingBox();
    const moved = await stillAfter(page, () => page.mouse.click(box.x + box.width * 0.25, box.y + box.height * 0.25));
    assert.ok(moved.position[0] < initial.position[0] - 100, `the map's north-west corner: ${moved.position}`);
    await stillAfter(page, () => page.locator('#plan').click());
    await stillAfter(page, () => page.locator('#reset-view').click());
  });

  await check('the language switch translates the page', async () => {
    await page.locator('#language').selectOption('de');
    assert.equal(await page.locator('#go-plan').textContent(), 'Zur Planung');
    assert.equal(await page.locator('html').getAttribute('lang'), 'de');
    await page.locator('#language').selectOption('en');
    assert.equal(await page.locator('#go-plan').textContent(), 'Go to the plan');
  });

  await check('planner login: a wrong token is refused, the admin token shows the planner tools', async () => {
    expected.push([step, '/api/auth']);
    const refused = await login(page, 'not the token');
    assert.match(refused, /not accepted/, `the refusal: ${refused}`);
    assert.equal(await page.locator('body').getAttribute('data-mode'), 'citizen');
    await page.locator('#login-cancel').click();
    await login(page, TOKEN);
    assert.equal(await page.locator('body').getAttribute('data-mode'), 'planner');
    assert.ok(await page.locator('#tab-style').isVisible(), 'the style panel');
    await page.waitForFunction(() => /fps|idle/.test(document.getElementById('stats').textContent), null, { timeout: WAIT });
    assert.deepEqual(await axeViolations(page), [], 'axe-core: no serious or critical violations in planner mode');
    await shot(page, 'planner');
    camera = JSON.parse(await page.locator('#frame').getAttribute('data-camera'));
  });

  await check("a planner moderates the comments: hide one, show it again; the citizens' list follows", async () => {
    await openPane(page, 'comments');
    const visibleToAll = () => page.evaluate(async () => (await (await fetch('/api/comments')).json()).comments.length);
    const status = () => page.locator('#comment-list li').first().getAttribute('data-status');
    await page.waitForFunction(() => document.querySelector('#comment-list li button[data-action]'), null, { timeout: WAIT });
    assert.equal(await status(), 'visible');
    const before = await visibleToAll();
    await page.locator('#comment-list li').first().locator('button[data-action="hide"]').click();
    await page.waitForFunction(() => document.querySelector('#comment-list li')?.dataset.status === 'hidden', null, { timeout: WAIT });
    assert.match(await page.locator('#comment-list li').first().textContent(), /Hidden/);
    assert.equal(await visibleToAll(), before - 1, 'hidden from the public list');
    await page.locator('#comment-list li').first().locator('button[data-action="approve"]').click();
    await page.waitForFunction(() => document.querySelector('#comment-list li')?.dataset.status === 'visible', null, { timeout: WAIT });
    assert.equal(await visibleToAll(), before, 'shown again');
    assert.deepEqual(await unlabelled(page), [], 'every moderation control is labelled');
    await openPane(page, 'style');
  });

  await check('a planner saves the view as a place to look from and removes it again', async () => {
    await openPane(page, 'about');
    await page.locator('#viewpoint-name').fill('The bench');
    await page.locator('#viewpoint-caption').fill('Where the new bench would stand');
    await page.locator('#viewpoint-submit').click();
    await page.locator('#viewpoints button.viewpoint', { hasText: 'The bench' }).waitFor({ state: 'visible', timeout: WAIT });
    const listed = await page.evaluate(async () => (await (await fetch('/api/viewpoints')).json()).viewpoints);
    const bench = listed.find((v) => v.name === 'The bench');
    assert.ok(bench && bench.source === 'admin' && bench.caption === 'Where the new bench would stand', JSON.stringify(bench));
    assert.ok(Math.abs(bench.camera.position[0] - camera.position[0]) < 1, 'at the current camera');
    assert.deepEqual(await unlabelled(page), [], 'the viewpoint controls are labelled');
    await page.locator('#viewpoints .remove-viewpoint').click();
    await page.waitForFunction(() => ![...document.querySelectorAll('#viewpoints button.viewpoint')].some((b) => b.textContent === 'The bench'), null, { timeout: WAIT });
    await openPane(page, 'style');
  });

  await check('a meeting: the planner presents, a page joined by /?meeting=CODE follows, detaches and rejoins', async () => {
    await page.locator('#meeting-open').click();
    await page.waitForFunction(() => document.getElementById('meeting').dataset.role === 'presenter', null, { timeout: WAIT });
    const code = await page.locator('#meeting').getAttribute('data-code');
    assert.match(await page.locator('#meeting-title').textContent(), new RegExp(`Meeting ${code}: you present`));
    await page.waitForFunction(() => document.getElementById('meeting-qr').naturalWidth > 0, null, { timeout: WAIT });
    const follower = watch(await context.newPage());
    await follower.goto(`${base}/?meeting=${code}`);
    await follower.waitForFunction(() => document.getElementById('meeting').dataset.role === 'follower', null, { timeout: WAIT });
    await page.waitForFunction(() => /^1 following/.test(document.getElementById('meeting-status').textContent), null, { timeout: WAIT });
    await page.locator('#meeting').scrollIntoViewIfNeeded();
    await shot(page, 'meeting');
    // The presenter's page in front: a page behind others gets no animation frames.
    await page.bringToFront();
    const turned = await stillAfter(page, async () => {
      await page.locator('#viewer').focus();
      await page.keyboard.down('ArrowLeft');
      await page.waitForTimeout(500);
      await page.keyboard.up('ArrowLeft');
    });
    await follower.waitForFunction((yaw) => Math.abs(JSON.parse(document.getElementById('frame').dataset.camera).yaw - yaw) < 0.01, turned.yaw, { timeout: WAIT });
    await follower.locator('#meeting-detach').click();
    await follower.waitForFunction(() => document.getElementById('meeting').dataset.role === 'detached', null, { timeout: WAIT });
    await follower.locator('#meeting-rejoin').click();
    await follower.waitForFunction(() => document.getElementById('meeting').dataset.role === 'follower', null, { timeout: WAIT });
    await page.locator('#meeting-close').click();
    await follower.waitForFunction(() => /meeting ended/.test(document.getElementById('message').textContent), null, { timeout: WAIT });
    assert.ok(await follower.locator('#meeting').isHidden(), 'the meeting panel goes');
    await follower.close();
    await page.bringToFront();
    await page.waitForFunction(() => document.getElementById('meeting').hidden, null, { timeout: WAIT });
    await page.evaluate(() => window.scrollTo(0, 0));
    camera = await settledStill(page);
  });

  await check('dragging changes the view', async () => {
    const before = await pixels(page);
    const box = await page.locator('#viewer').boundingBox();
    let after = await stillAfter(page, async () => {
      await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
      await page.mouse.down();
      for (let i = 1; i <= 10; i += 1) await page.mouse.move(box.x + box.width / 2 + i * 15, box.y + box.height / 2 + i * 3);
      await page.mouse.up();
    });
    if (Math.abs(after.yaw - camera.yaw) <= 5) {
      // A still of an earlier change came first: the drag's follows.
      after = await page.waitForFunction((yaw) => {
        const canvas = document.getElementById('frame');
        const shown = JSON.parse(canvas.dataset.camera);
        return canvas.dataset.still === 'true' && Math.abs(shown.yaw - yaw) > 5 && shown;
      }, camera.yaw, { timeout: WAIT }).then((handle) => handle.jsonValue());
    }
    assert.ok(Math.abs(after.yaw - camera.yaw) > 5, `yaw turned: ${camera.yaw} → ${after.yaw}`);
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'the picture changed');
    camera = after;
  });

  await check('walking with the keyboard follows the terrain', async () => {
    await page.locator('#viewer').focus();
    const after = await stillAfter(page, async () => {
      await page.keyboard.down('KeyW');
      await page.waitForTimeout(800);
      await page.keyboard.up('KeyW');
    });
    const moved = Math.hypot(after.position[0] - camera.position[0], after.position[1] - camera.position[1]);
    assert.ok(moved > 0.5, `walked ${moved.toFixed(2)} m`);
    await linked(page, 'eye_height', (v) => v === '1.7');
    camera = after;
  });

  await check('flying climbs away from the terrain', async () => {
    await page.locator('#fly').click();
    assert.equal(await page.locator('#fly').getAttribute('aria-pressed'), 'true');
    await page.locator('#viewer').focus();
    const after = await stillAfter(page, async () => {
      await page.keyboard.down('KeyE');
      await page.waitForTimeout(800);
      await page.keyboard.up('KeyE');
    });
    assert.ok(after.position[2] > camera.position[2] + 0.5, `climbed: z ${camera.position[2]} → ${after.position[2]}`);
    await linked(page, 'z', (v) => v !== null);
    // Diving into the ground (faster: 20 wheel notches up) lands the eye eye height above it,
    // where the walker stood, and climbing starts from there.
    await page.locator('#viewer').hover();
    for (let i = 0; i < 20; i += 1) await page.mouse.wheel(0, -100);
    const ground = await stillAfter(page, async () => {
      await page.keyboard.down('KeyQ');
      await page.waitForTimeout(1500);
      await page.keyboard.up('KeyQ');
    });
    assert.ok(Math.abs(ground.position[2] - camera.position[2]) < 0.01, `landed at z ${ground.position[2]}, walker ${camera.position[2]}`);
    const up = await stillAfter(page, async () => {
      await page.keyboard.down('KeyE');
      await page.waitForTimeout(300);
      await page.keyboard.up('KeyE');
    });
    assert.ok(up.position[2] > ground.position[2] + 5, `climbs from the ground: z ${ground.position[2]} → ${up.position[2]}`);
    for (let i = 0; i < 20; i += 1) await page.mouse.wheel(0, 100);
    const landed = await stillAfter(page, () => page.locator('#fly').click());
    assert.ok(Math.abs(landed.position[2] - camera.position[2]) < 0.01, 'walking again at the eye height');
    camera = landed;
  });

  await check('a style slider changes the image', async () => {
    await openPane(page, 'style');
    const before = await pixels(page);
    const slider = page.locator('#style-photorealism');
    await stillAfter(page, () => slider.fill('1'));
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'photorealism changed the picture');
    await linked(page, 'style', (v) => v && JSON.parse(v).photorealism === 1);
    await shot(page, 'style-photorealism');
    await stillAfter(page, () => page.locator('#style-reset').click());
    await linked(page, 'style', (v) => v === null);
  });

  await check('a preset switch changes the image; then the keys drive the view, not the menu', async () => {
    const presets = await page.locator('#preset option').evaluateAll((options) => options.map((o) => o.value).filter(Boolean));
    assert.ok(presets.length > 1, `presets offered: ${presets}`);
    const before = await pixels(page);
    const name = presets.includes('van_gogh') ? 'van_gogh' : presets[0];
    const chosen = await stillAfter(page, () => page.locator('#preset').selectOption(name));
    assert.ok(difference(before, await pixels(page)) > CHANGED, `preset ${name} changed the picture`);
    await linked(page, 'preset', (v, a) => v === a, name);
    await shot(page, `preset-${name}`);
    assert.equal(await page.evaluate(() => document.activeElement.id), 'viewer', 'the focus is back on the view');
    const walked = await stillAfter(page, async () => {
      await page.keyboard.down('ArrowDown');
      await page.waitForTimeout(500);
      await page.keyboard.up('ArrowDown');
    });
    assert.equal(await page.locator('#preset').inputValue(), name, '↓ left the preset alone');
    assert.ok(Math.hypot(walked.position[0] - chosen.position[0], walked.position[1] - chosen.position[1]) > 0.3, '↓ walked back');
    await stillAfter(page, () => page.locator('#preset').selectOption(''));
  });

  await check('"Reset style" resets the view and every layer; "Visible" is a layer\'s, not the whole view\'s', async () => {
    assert.ok(await page.locator('#style-visible').isHidden(), 'no "Visible" switch for the whole view');
    await stillAfter(page, () => page.locator('#style-photorealism').fill('1'));
    await page.locator('#style-target').selectOption('existing');
    assert.ok(await page.locator('#style-visible').isVisible(), '"Visible" for a layer');
    await stillAfter(page, () => page.locator('#preset').selectOption('minimalistic'));
    await linked(page, 'layer_styles', (v) => v === JSON.stringify({ existing: { preset: 'minimalistic' } }));
    await linked(page, 'style', (v) => v && JSON.parse(v).photorealism === 1);
    await stillAfter(page, () => page.locator('#style-reset').click());
    await linked(page, 'style', (v) => v === null);
    await linked(page, 'layer_styles', (v) => v === null);
    await page.locator('#style-target').selectOption('');
  });

  await check("a refused style's message goes once the value is fixed", async () => {
    await page.locator('#pane-style details.advanced').evaluate((d) => {
      d.open = true;
      for (const inner of d.querySelectorAll('details')) inner.open = true;
    });
    const hatch = page.locator('#style-hatch_map').locator('xpath=..').locator('input[type="number"]');
    await hatch.fill('9');
    await hatch.dispatchEvent('change');
    await page.waitForFunction(() => /art map/.test(document.getElementById('message').textContent), null, { timeout: WAIT });
    await stillAfter(page, async () => {
      await hatch.fill('0');
      await hatch.dispatchEvent('change');
    });
    await page.waitForFunction(() => document.getElementById('message').textContent === '', null, { timeout: WAIT });
  });

  await check('a vegetation layer gets a style of its own', async () => {
    const before = await pixels(page);
    await page.locator('#style-target').selectOption('existing');
    await stillAfter(page, () => page.locator('#preset').selectOption('photorealism'));
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'the existing plants changed');
    await linked(page, 'layer_styles', (v) => v === JSON.stringify({ existing: { preset: 'photorealism' } }));
    await stillAfter(page, () => page.locator('#style-reset').click());
    await linked(page, 'layer_styles', (v) => v === null);
    await page.locator('#style-target').selectOption('');
  });

  await check('a vegetation layer can be hidden', async () => {
    const before = await pixels(page);
    await page.locator('#style-target').selectOption('existing');
    await stillAfter(page, () => page.locator('#style-visible').uncheck());
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'the existing plants disappeared');
    await linked(page, 'layer_styles', (v) => v === JSON.stringify({ existing: { visible: false } }));
    await stillAfter(page, () => page.locator('#style-reset').click());
    await linked(page, 'layer_styles', (v) => v === null);
    await page.locator('#style-target').selectOption('');
  });

  await check('strokes painted into a TAM ink the next frame; reset restores it', async () => {
    await openPane(page, 'art');
    const tam = page.locator('#art-tams li.artmap[data-index="0"]');
    await tam.waitFor({ timeout: WAIT });
    assert.equal(await tam.getAttribute('data-source'), 'generated');
    assert.equal(await tam.locator('button.choose').getAttribute('aria-pressed'), 'true', 'the style uses TAM 0');
    await page.waitForFunction(() => [...document.querySelectorAll('#pane-art .artmap img')]
      .every((img) => img.complete && img.naturalWidth > 0), null, { timeout: WAIT });
    assert.equal(await tam.locator('img').evaluate((img) => img.naturalWidth), 1536, 'the TAM thumbnail is its strip');
    assert.deepEqual(await unlabelled(page), [], 'every visible control of the art-map panel has a label');
    await page.locator('#art-paint-map').selectOption('tam:0');
    await page.locator('#art-paint-level').selectOption('0');
    await page.locator('#art-brush').fill('24');
    await page.locator('#art-canvas[data-map="tam:0"]').waitFor({ timeout: WAIT });
    const blank = await paintBrightness(page);
    const box = await page.locator('#art-canvas').boundingBox();
    for (let row = 0; row < 5; row += 1) {
      const y = box.y + box.height * (row + 0.5) / 5;
      await page.mouse.move(box.x + 4, y);
      await page.mouse.down();
      for (let i = 1; i <= 10; i += 1) await page.mouse.move(box.x + 4 + (box.width - 8) * i / 10, y + 6 * Math.sin(i));
      await page.mouse.up();
    }
    const painted = await paintBrightness(page);
    assert.ok(painted < blank - 20, `the strokes show on the canvas: ${blank.toFixed(1)} → ${painted.toFixed(1)}`);
    const before = await pixels(page);
    await stillAfter(page, () => page.locator('#art-apply').click());
    await artSource(page, 'tam', 0, 'uploaded');
    const inked = await pixels(page);
    assert.match(await page.locator('#art-paint-status').textContent(), /TAM 0 updated/);
    assert.ok(difference(before, inked) > CHANGED, 'the painted TAM changed the picture');
    assert.ok(brightness(inked) < brightness(before) - 1, `more ink: mean grey ${brightness(before).toFixed(1)} → ${brightness(inked).toFixed(1)}`);
    // The canvas shows the stored map now, the strokes in it.
    await page.waitForFunction(
      ([source, level]) => Math.abs(new Function(`return (${source})`)()(document.getElementById('art-canvas')) - level) < 1,
      [canvasMean.toString(), painted],
      { timeout: WAIT },
    );
    await shot(page, 'art-maps');
    await stillAfter(page, () => tam.locator('button.reset').click());
    await artSource(page, 'tam', 0, 'generated');
    assert.ok(difference(before, await pixels(page)) < CHANGED / 2, 'reset restores the picture');
    assert.equal(await tam.locator('button.reset').count(), 0, 'nothing left to reset');
  });

  await check('strokes painted into one stroke style of a SAM change only that channel', async () => {
    /** SAM 1 (the default `silhouette_map`) as decoded by the page's PNG codec: ink per channel. */
    const channels = () => page.evaluate(async () => {
      const { decodePng } = await import('/png.js');
      const sam = (await decodePng(await (await fetch(`/api/artmaps/sam/1.png?t=${Date.now()}`)).arrayBuffer())).to(4);
      const sums = [0, 0, 0, 0];
      for (let i = 0; i < sam.data.length; i += 1) sums[i % 4] += sam.data[i];
      return { sums, bytes: Array.from(sam.data) };
    });
    const original = await channels();
    await page.locator('#art-sams li.artmap[data-index="1"] button', { hasText: 'Paint' }).click();
    await page.locator('#art-canvas[data-map="sam:1"]').waitFor({ timeout: WAIT });
    assert.ok(await page.locator('#art-channel-field').isVisible(), 'a SAM is painted per stroke style');
    assert.ok(!(await page.locator('#art-level-field').isVisible()), 'tone levels are for TAMs');
    await page.locator('#art-paint-channel').selectOption('1');
    await page.locator('#art-brush').fill('6');
    const box = await page.locator('#art-canvas').boundingBox();
    await page.mouse.move(box.x + 4, box.y + box.height / 2);
    await page.mouse.down();
    for (let i = 1; i <= 10; i += 1) await page.mouse.move(box.x + 4 + (box.width - 8) * i / 10, box.y + box.height / 2);
    await page.mouse.up();
    await stillAfter(page, () => page.locator('#art-apply').click());
    await artSource(page, 'sam', 1, 'uploaded');
    const edited = await channels();
    assert.ok(edited.sums[1] > original.sums[1], `more ink in G: ${original.sums[1]} → ${edited.sums[1]}`);
    for (const c of [0, 2, 3]) {
      assert.ok(edited.bytes.every((v, i) => i % 4 !== c || v === original.bytes[i]), `channel ${c} kept byte for byte`);
    }
    await stillAfter(page, () => page.locator('#art-sams li.artmap[data-index="1"] button.reset').click());
    await artSource(page, 'sam', 1, 'generated');
    assert.deepEqual((await channels()).sums, original.sums, 'reset restores the generated SAM');
  });

  await check('an invalid art map shows the server\'s message', async () => {
    const uploadMap = async (file) => {
      await page.locator('#art-upload-target').selectOption('tam:0');
      await page.locator('#art-upload-file').setInputFiles(file);
      await page.locator('#art-upload-status').evaluate((node) => {
        node.dataset.kind = '';
      });
      await page.locator('#art-upload-submit').click();
      await page.waitForFunction(() => ['ok', 'error'].includes(document.getElementById('art-upload-status').dataset.kind), null, { timeout: WAIT });
      assert.equal(await page.locator('#art-upload-status').getAttribute('data-kind'), 'error');
      return page.locator('#art-upload-status').textContent();
    };
    expected.push([step, '/api/artmaps/tam/0']);
    const garbage = await uploadMap({ name: 'strokes.png', mimeType: 'image/png', buffer: Buffer.from('not a PNG at all\n') });
    assert.match(garbage, /refused the map: art map tam\/0 is not a PNG file/, `the server's message: ${garbage}`);
    // A real PNG of the wrong shape: a SAM strip offered as a TAM.
    const sam = Buffer.from(await (await page.request.get(`${base}/api/artmaps/sam/0.png`)).body());
    const shape = await uploadMap({ name: 'sam.png', mimeType: 'image/png', buffer: sam });
    assert.match(shape, /is 256×32 pixels, expected a strip of 6 square tone images/, `the server's message: ${shape}`);
    assert.equal(await page.locator('#art-tams li.artmap[data-index="0"]').getAttribute('data-source'), 'generated', 'nothing changed');
  });

  await check('an invalid upload shows the server\'s message', async () => {
    const result = await upload(page, {
      name: 'Not a raster',
      kind: 'scalar',
      file: { name: 'notes.txt', mimeType: 'text/plain', buffer: Buffer.from('this is not a raster\n') },
    });
    expected.push([step, '/api/layers']);
    assert.equal(result.kind, 'error');
    assert.match(result.text, /unknown format: expected GeoTIFF/, `the server's message: ${result.text}`);
    await shot(page, 'upload-error');
  });

  let layerId;
  await check('uploading a series: the legend follows a new step, other pages list the layer within 2 s', async () => {
    const other = watch(await context.newPage());
    await other.goto(base);
    await nextStill(other, 0);
    await openPane(other, 'data');
    const first = await upload(page, { name: 'Test series', kind: 'scalar', time: SERIES[0].day, file: SERIES[0].path });
    assert.equal(first.kind, 'ok', first.text);
    const uploaded = Date.now();
    await other.locator('li.layer', { hasText: 'Test series' }).waitFor({ timeout: 2000 });
    console.log(`  the other page listed the layer after ${Date.now() - uploaded} ms`);
    await openPane(page, 'data');
    const item = page.locator('li.layer', { hasText: 'Test series' });
    await item.waitFor({ timeout: WAIT });
    layerId = await item.getAttribute('data-layer');
    const legend = item.locator('img.legend');
    const oneStep = await legend.getAttribute('src');
    const second = await upload(page, { name: 'Test series', kind: 'scalar', time: SERIES[1].day, file: SERIES[1].path });
    assert.equal(second.kind, 'ok', second.text);
    await openPane(page, 'data');
    await page.waitForFunction(() => /2 time steps/.test(document.querySelector('li.layer .summary')?.textContent), null, { timeout: WAIT });
    const twoSteps = await item.locator('img.legend').getAttribute('src');
    assert.notEqual(twoSteps, oneStep, 'a new step gives the legend a new URL (not the cached image)');
    await page.waitForFunction((img) => img.complete && img.naturalWidth > 0, await item.locator('img.legend').elementHandle(), { timeout: WAIT });
    assert.equal(await item.locator('img.legend').evaluate((img) => img.naturalWidth), 320);
    assert.match(await item.locator('img.legend').getAttribute('alt'), /Legend of Test series/);
    await other.waitForFunction(() => /2 time steps/.test(document.querySelector('li.layer .summary')?.textContent), null, { timeout: 2000 });
    await other.close();
    await page.bringToFront();
  });

  await check('a layer covering part of the scene says so and can be gone to', async () => {
    const item = page.locator(`li.layer[data-layer="${layerId}"]`);
    assert.match(await item.locator('.coverage').textContent(), /Covers \d+ % of the scene/);
    const there = await stillAfter(page, () => item.locator('button.goto').click());
    await linked(page, 'mode', (v) => v === 'plan');
    const extent = await page.evaluate(async (id) => (await (await fetch(`/api/layers/${id}`)).json()).scene_extent, layerId);
    assert.ok(there.position[0] > extent[0] && there.position[0] < extent[2], `centred on the layer: ${there.position} in ${extent}`);
    await stillAfter(page, () => page.locator('#plan').click());
  });

  await check('mapping a layer shows it in the frame, the time slider changes the frame', async () => {
    // A link into the layer's part of the scene (the west), looking down at the ground.
    await page.goto(`${base}/?x=-800&y=0&eye_height=1.7&yaw=90&pitch=-40&fov=60`);
    await page.waitForFunction(() => document.body.dataset.mode === 'planner', null, { timeout: WAIT });
    const opened = await settledStill(page);
    assert.ok(Math.abs(opened.position[0] + 800) < 0.01 && Math.abs(opened.yaw - 90) < 0.01, `the link's view: ${JSON.stringify(opened)}`);
    await openPane(page, 'data');
    const target = page.locator(`#map-${layerId}-target`);
    const before = await pixels(page);
    await stillAfter(page, () => target.selectOption('color'));
    const mapped = await pixels(page);
    assert.ok(difference(before, mapped) > CHANGED, 'the colour mapping changed the picture');
    await linked(page, 'mappings', (v, a) => v && JSON.parse(v)[0].layer === a, layerId);
    const slider = page.locator('#time-slider');
    await slider.waitFor({ state: 'visible' });
    const label = await page.locator('#time-label').textContent();
    const last = await slider.getAttribute('max');
    await stillAfter(page, () => slider.fill(last));
    assert.notEqual(await page.locator('#time-label').textContent(), label, 'the time stamp moved');
    await linked(page, 'time', (v) => /^2024-06-11/.test(v));
    assert.ok(difference(mapped, await pixels(page)) > CHANGED, 'the later time step changed the picture');
    await shot(page, 'data-mapping');
    const shown = await page.locator('#time-label').textContent();
    await page.locator('#time-play').click();
    await page.waitForFunction((text) => document.getElementById('time-label').textContent !== text, shown, { timeout: WAIT });
    await page.locator('#time-play').click();
    assert.equal(await page.locator('#time-play').getAttribute('aria-pressed'), 'false', 'paused');
    // Hatch colour (thesis Fig. 9.3): an ink picker instead of the colour map, the ink in the
    // link and the legend, a changed picture.
    const ink = page.locator(`#map-${layerId}-color`);
    assert.ok(await ink.isHidden(), 'no ink picker for the color target');
    // The frames of the last played steps first.
    await settledStill(page);
    const coloured = await pixels(page);
    await stillAfter(page, () => target.selectOption('hatch_color'));
    assert.ok(await ink.isVisible(), 'an ink picker for hatch_color');
    assert.ok(await page.locator(`#map-${layerId}-colormap`).isHidden(), 'no colour map for hatch_color');
    const hatched = await pixels(page);
    assert.ok(difference(coloured, hatched) > CHANGED, `the hatch colour changed the picture (${difference(coloured, hatched).toFixed(2)}; ${await page.locator('#message').textContent()}; ${page.url()})`);
    await linked(page, 'mappings', (v) => v && JSON.parse(v)[0].target === 'hatch_color' && JSON.parse(v)[0].color.length === 3);
    const legend = await page.locator(`li.layer[data-layer="${layerId}"] img.legend`).getAttribute('src');
    assert.match(legend, /target=hatch_color&color=0\.835%2C0\.369%2C0\b/, 'the legend ramps to the default ink');
    await stillAfter(page, () => target.selectOption('color'));
  });

  await check('copy link → open → same camera; the link renders the same picture over REST', async () => {
    await page.locator('#copy-link').click();
    await page.waitForFunction(() => /copied|selected/.test(document.getElementById('message').textContent));
    const link = await page.locator('#link').inputValue();
    const copied = await page.evaluate(() => navigator.clipboard.readText());
    assert.equal(copied, link, 'the clipboard holds the link');
    const shown = JSON.parse(await page.locator('#frame').getAttribute('data-camera'));
    const other = watch(await context.newPage());
    await other.goto(link);
    const opened = await settledStill(other);
    assert.equal(await other.locator('#tab-data').getAttribute('aria-selected'), 'true', 'a link with a data layer opens on the data maps');
    assert.ok(await other.locator('li.layer img.legend').isVisible(), 'with the legend in sight');
    for (let i = 0; i < 3; i += 1) {
      assert.ok(Math.abs(opened.position[i] - shown.position[i]) < 0.01, `position ${i}: ${shown.position} vs ${opened.position}`);
    }
    for (const k of ['yaw', 'pitch', 'fov']) assert.ok(Math.abs(opened[k] - shown[k]) < 0.01, `${k}: ${shown[k]} vs ${opened[k]}`);
    // The link's query on the render endpoint, at the session's frame size.
    const query = new URL(link).search.slice(1);
    const rest = await other.evaluate(async (q) => {
      const canvas = document.getElementById('frame');
      const url = `/api/render?${q}&width=${canvas.width}&height=${canvas.height}&format=png`;
      const image = await createImageBitmap(await (await fetch(url)).blob());
      const small = Object.assign(document.createElement('canvas'), { width: 64, height: 48 });
      const g = small.getContext('2d');
      g.drawImage(image, 0, 0, 64, 48);
      const data = g.getImageData(0, 0, 64, 48).data;
      const grey = [];
      for (let i = 0; i < data.length; i += 4) grey.push((data[i] + data[i + 1] + data[i + 2]) / 3);
      return { grey };
    }, query);
    const session = await pixels(other);
    assert.ok(difference(session, rest) < 4, `the session and GET /api/render show the same picture (${difference(session, rest).toFixed(2)})`);
    await other.close();
    await page.bringToFront();
  });

  await check('the screenshot is a full-quality PNG of the same view', async () => {
    const [download] = await Promise.all([page.waitForEvent('download', { timeout: WAIT }), page.locator('#screenshot').click()]);
    const file = await download.path();
    const bytes = readFileSync(file);
    assert.deepEqual([...bytes.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a], 'a PNG');
    const width = bytes.readUInt32BE(16);
    const viewer = await page.locator('#viewer').boundingBox();
    assert.ok(Math.abs(width - Math.round(viewer.width)) <= 2, `full viewer width ${viewer.width}, got ${width}`);
    // Caption, north arrow, legend and credits over the render: the saved picture differs from
    // the plain render of the same view in its corners.
    const corners = await page.evaluate(async ([png, query]) => {
      const load = async (blob) => {
        const image = await createImageBitmap(blob);
        const c = Object.assign(document.createElement('canvas'), { width: image.width, height: image.height });
        c.getContext('2d').drawImage(image, 0, 0);
        return c.getContext('2d');
      };
      const saved = await load(new Blob([new Uint8Array(png)], { type: 'image/png' }));
      const w = saved.canvas.width;
      const h = saved.canvas.height;
      const plain = await load(await (await fetch(`/api/render?${query}&width=${w}&height=${h}&format=png`)).blob());
      const diff = (x, y, s) => {
        const a = saved.getImageData(x, y, s, s).data;
        const b = plain.getImageData(x, y, s, s).data;
        let d = 0;
        for (let i = 0; i < a.length; i += 1) d += Math.abs(a[i] - b[i]);
        return d / a.length;
      };
      const s = Math.round(w / 30);
      return { caption: diff(s, s, s), north: diff(w - 2 * s, s, s), credit: diff(w - 3 * s, h - s, s) };
    }, [[...bytes], new URL(page.url()).search.slice(1)]);
    for (const [part, d] of Object.entries(corners)) assert.ok(d > 2, `the ${part} is drawn over the picture (${d.toFixed(1)})`);
  });

  await check('deleting a layer asks first', async () => {
    await openPane(page, 'data');
    const item = page.locator(`li.layer[data-layer="${layerId}"]`);
    await item.locator('button.danger').click();
    await page.locator('#confirm').waitFor({ state: 'visible' });
    await page.locator('#confirm button[value="cancel"]').click();
    assert.equal(await item.count(), 1, 'cancel keeps the layer');
    await item.locator('button.danger').click();
    await page.locator('#confirm-ok').click();
    await item.waitFor({ state: 'detached', timeout: WAIT });
    await linked(page, 'mappings', (v) => v === null);
    await linked(page, 'time', (v) => v === null);
  });

  await check('plan view', async () => {
    await settledStill(page);
    const before = await pixels(page);
    await stillAfter(page, () => page.locator('#plan').click());
    await linked(page, 'mode', (v) => v === 'plan');
    assert.ok(difference(before, await pixels(page)) > CHANGED, 'the plan differs from the perspective view');
    await shot(page, 'plan');
    await stillAfter(page, () => page.locator('#plan').click());
    await linked(page, 'mode', (v) => v === null);
  });

  await check('a dropped session reconnects with back-off and keeps the view', async () => {
    const other = watch(await context.newPage());
    const sessions = [];
    // The page's side of each session, connected through to the server.
    await other.routeWebSocket(/\/api\/ws/, (ws) => {
      ws.connectToServer();
      sessions.push(ws);
    });
    await other.goto(base);
    await nextStill(other, 0);
    const first = await other.locator('#frame').getAttribute('data-session');
    const turned = await stillAfter(other, async () => {
      await other.locator('#viewer').focus();
      await other.keyboard.down('ArrowLeft');
      await other.waitForTimeout(500);
      await other.keyboard.up('ArrowLeft');
    });
    sessions[0].close({ code: 1001, reason: 'dropped by the test' });
    await other.waitForFunction(() => document.getElementById('connection').dataset.state === 'waiting', null, { timeout: WAIT });
    assert.match(await other.locator('#connection').textContent(), /retrying in \d+ s/);
    await other.waitForFunction((old) => {
      const canvas = document.getElementById('frame');
      return canvas.dataset.session !== old && canvas.dataset.still === 'true' && Number(canvas.dataset.frameId) >= 1;
    }, first, { timeout: WAIT });
    assert.equal(await other.locator('#connection').getAttribute('data-state'), 'open');
    assert.equal(sessions.length, 2, 'one new session');
    const again = JSON.parse(await other.locator('#frame').getAttribute('data-camera'));
    assert.ok(Math.abs(again.yaw - turned.yaw) < 0.01, `the view survived: yaw ${turned.yaw} → ${again.yaw}`);
    await other.close();
    await page.bringToFront();
  });

  await check('a link the server refuses falls back to the default view with the reason', async () => {
    const other = watch(await context.newPage());
    // The session and the probe render are refused with 422.
    expected.push([step, '/api/ws?x=5000'], [step, '/api/render?x=5000']);
    await other.goto(`${base}/?x=5000&y=0&eye_height=1.7&yaw=10&pitch=0&fov=60`);
    const shown = await nextStill(other, 0);
    assert.match(await other.locator('#message').textContent(), /refused \(position 5000,0 is outside the terrain/);
    assert.deepEqual(shown.position.slice(0, 2), initial.position.slice(0, 2), 'the default view');
    await linked(other, 'x', (v) => v !== '5000');
    await other.close();
    await page.bringToFront();
  });

  await check('logout hides the planner controls', async () => {
    await page.locator('#logout').click();
    assert.equal(await page.locator('body').getAttribute('data-mode'), 'citizen');
    for (const id of ['#tab-style', '#tab-upload', '#tab-art']) assert.ok(await page.locator(id).isHidden(), `${id} hidden`);
    assert.deepEqual(await jargonIn(page), [], 'no jargon after logout');
  });

  await check('a phone: touch gestures, pinch zoom, 44 px controls, no jargon, accessible', async () => {
    const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium', args: FLAGS });
    try {
      const mobile = await browser.newContext({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
      await mobile.addInitScript((scale) => localStorage.setItem('landsketch.renderScale', scale), String(RENDER_SCALE));
      const phone = watch(await mobile.newPage());
      await phone.goto(base);
      const opened = await nextStill(phone, 0);
      assert.match(await phone.locator('#welcome-title').textContent(), /Boulder/, 'the welcome on the phone');
      const overflow = await phone.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
      assert.ok(overflow <= 0, `no sideways scrolling (${overflow} px too wide)`);
      assert.match(await phone.locator('#hint-text').textContent(), /pinch/, 'touch hints on first use');
      assert.ok(await phone.locator('#nav-help').isVisible(), 'the navigation help is visible on touch');
      for (const id of ['#fly', '#plan', '#go-plan', '#with-plan', '#screenshot', '#copy-link', '#tab-about']) assert.ok(await phone.locator(id).isVisible(), `${id} visible`);
      assert.deepEqual(await smallControls(phone), [], 'every control at least 44 × 44 px');
      assert.deepEqual(await jargonIn(phone), [], 'no jargon on the phone');
      if (shots) await phone.screenshot({ path: join(shots, 'phone.jpg'), type: 'jpeg', quality: 80 });
      // Pinch: two fingers spread apart narrow the field of view.
      const box = await phone.locator('#viewer').boundingBox();
      const cdp = await mobile.newCDPSession(phone);
      const cx = box.x + box.width / 2;
      const cy = box.y + box.height / 2;
      const touch = (type, spread) => cdp.send('Input.dispatchTouchEvent', {
        type,
        touchPoints: type === 'touchEnd' ? [] : [{ x: cx - spread, y: cy, id: 1 }, { x: cx + spread, y: cy, id: 2 }],
      });
      const zoomed = await stillAfter(phone, async () => {
        await touch('touchStart', 20);
        for (let spread = 30; spread <= 120; spread += 10) await touch('touchMove', spread);
        await touch('touchEnd', 0);
      });
      assert.ok(zoomed.fov < opened.fov - 5, `pinching zoomed in: fov ${opened.fov} → ${zoomed.fov}`);
      // A swipe on the page below the view scrolls the page, not the camera.
      const below = (await phone.locator('#panel').boundingBox()).y + 20;
      const swipe = (type, y) => cdp.send('Input.dispatchTouchEvent', { type, touchPoints: type === 'touchEnd' ? [] : [{ x: cx, y, id: 3 }] });
      await swipe('touchStart', Math.min(below, 820));
      for (let y = Math.min(below, 820) - 30; y > 300; y -= 30) await swipe('touchMove', y);
      await swipe('touchEnd', 0);
      await phone.waitForTimeout(600);
      assert.ok(await phone.evaluate(() => window.scrollY) > 0, 'the page scrolled');
      const yaw = Number(new URL(phone.url()).searchParams.get('yaw'));
      assert.ok(Math.abs(yaw - zoomed.yaw) < 0.01, `the camera kept its heading: ${zoomed.yaw} → ${yaw}`);

      assert.deepEqual(await axeViolations(phone), [], 'axe-core on the phone');

      // Commenting on the phone: a tap on the view places the comment, the form fits the
      // screen with 44 px controls, and the comment is listed.
      await phone.evaluate(() => window.scrollTo(0, 0));
      await openPane(phone, 'comments');
      await phone.locator('#comment-add').click();
      const view = await phone.locator('#viewer').boundingBox();
      await phone.locator('#viewer').tap({ position: { x: view.width / 2, y: view.height * 0.8 } });
      await phone.locator('#comment-form').waitFor({ state: 'visible', timeout: WAIT });
      assert.deepEqual(await smallControls(phone), [], 'the comment form\'s controls are at least 44 × 44 px');
      const wide = await phone.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
      assert.ok(wide <= 0, `the comment form needs no sideways scrolling (${wide} px too wide)`);
      await phone.locator('#comment-text').fill('Please keep the footpath open');
      await phone.locator('#comment-send').click();
      await phone.waitForFunction(() => /footpath open/.test(document.getElementById('comment-list').textContent), null, { timeout: WAIT });
      assert.equal(await phone.locator('#comments-show').getAttribute('aria-pressed'), 'true', 'the comments are pinned in the view');
      if (shots) await phone.screenshot({ path: join(shots, 'phone-comment.jpg'), type: 'jpeg', quality: 80 });

      // The rest of the first-time flow on the phone: go to the plan, without it, share the link;
      // the link opens the same view with the comparison.
      await openPane(phone, 'about');
      // A still of the comment's pins may still be on its way: wait for the plan's.
      await phone.locator('#go-plan').tap();
      await phone.waitForFunction((from) => {
        const canvas = document.getElementById('frame');
        const camera = JSON.parse(canvas.dataset.camera ?? '{}');
        return canvas.dataset.still === 'true' && camera.position
          && Math.hypot(camera.position[0] - from[0], camera.position[1] - from[1]) > 50;
      }, zoomed.position, { timeout: WAIT });
      const atPlan = JSON.parse(await phone.locator('#frame').getAttribute('data-camera'));
      await stillAfter(phone, () => phone.locator('#with-plan').tap());
      assert.equal(await phone.locator('#with-plan').getAttribute('aria-pressed'), 'false');
      await linked(phone, 'layer_styles', (v) => v === JSON.stringify({ planned: { visible: false } }));
      const shared = await mobile.newPage();
      await shared.goto(phone.url());
      const opened2 = await nextStill(shared, 0);
      assert.ok(Math.hypot(opened2.position[0] - atPlan.position[0], opened2.position[1] - atPlan.position[1]) < 1, 'the link opens the same place');
      assert.equal(await shared.locator('#with-plan').getAttribute('aria-pressed'), 'false', 'and without the plan');
      await shared.close();
    } finally {
      await browser.close();
    }
  });

  await check('no console errors', async () => {
    const unexpected = problems.filter((p) => !expected.some(([s, part]) => p.step === s && (p.url?.includes(part) || p.text.includes(part))));
    assert.deepEqual(unexpected, [], 'console errors');
  });
} finally {
  await context.close();
  rmSync(profile, { recursive: true, force: true });
}

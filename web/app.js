// The landsketch viewer: a WebSocket session shows the landscape, the panels change the view,
// and the page's address always holds the view as `GET /api/render` parameters.

import { ApiError, deleteLayer, getBlob, getJSON, resolveStyles } from './api.js';
import { ArtMapsPanel } from './artmaps.js';
import { Connection, statsText } from './connection.js';
import { DataPanel } from './data-panel.js';
import { cameraMessage, dataMessage, defaultView, fromQuery, pageLink, renderUrl, styleMessage, toQuery } from './link.js';
import { Navigator } from './navigation.js';
import { StyleModel, StylePanel } from './style-panel.js';
import { setupUpload } from './upload.js';

const $ = (id) => document.getElementById(id);
const SCALE_KEY = 'landsketch.renderScale';
const DEFAULT_SCALE = '0.5';
const STILL_QUALITY = 90;
const LINK_DELAY_MS = 300;
const RESIZE_DELAY_MS = 250;
/** Mapping targets the renderer draws (the `mappings` field of `POST /api/render`, README "Render parameters"). */
const MAPPING_TARGETS = ['color', 'hatch_tone', 'hatch_color', 'hatch_pattern', 'silhouette_style', 'silhouette_density', 'abstraction'];

/** Everything the page knows: the scene, the view, the session and what the server supports. */
const app = {
  scene: null,
  base: null,
  view: null,
  frameCamera: null,
  connection: null,
  dirty: new Set(),
  flushing: null,
  opened: false,
  probed: false,
};

/** Shows a message under the view; `kind` is `error` or `info`. */
function say(text, kind = 'error') {
  const node = $('message');
  node.dataset.kind = kind;
  node.textContent = text;
}

/** The still-frame size: the viewer's pixels times the chosen resolution, within the server's limits. */
function stillSize(scale = Number($('render-scale').value)) {
  const viewer = $('viewer');
  const ratio = window.devicePixelRatio || 1;
  const side = (css, max) => Math.max(16, Math.min(max, Math.round(css * ratio * scale)));
  return {
    width: side(viewer.clientWidth, app.scene.max_width),
    height: side(viewer.clientHeight, app.scene.max_height),
  };
}

function sessionUrl() {
  const { width, height } = stillSize();
  return `/api/ws?${toQuery(app.view, { width, height, format: 'jpeg', quality: STILL_QUALITY })}`;
}

/** Marks parts of the view as changed; they are sent once per animation frame. */
function changed(...parts) {
  for (const part of parts) app.dirty.add(part);
  if (parts.includes('style')) app.art?.showChosen();
  if (app.flushing == null) app.flushing = requestAnimationFrame(flush);
  scheduleLink();
}

function flush() {
  app.flushing = null;
  const connection = app.connection;
  if (!connection.open) return;
  for (const part of app.dirty) {
    if (part === 'camera') connection.send(cameraMessage(app.view));
    else if (part === 'style') connection.send(styleMessage(app.view));
    else if (part === 'data') connection.send(dataMessage(app.view));
    else if (part === 'size') connection.send({ type: 'size', ...stillSize() });
  }
  app.dirty.clear();
}

/** Puts the view into the address bar and the link field. */
function updateLink() {
  const link = pageLink(app.view);
  $('link').value = link;
  window.history.replaceState(null, '', link);
}

let linkTimer = null;
/** `updateLink` once the view has not changed for a moment. */
function scheduleLink() {
  clearTimeout(linkTimer);
  linkTimer = setTimeout(updateLink, LINK_DELAY_MS);
}

function drawFrame({ meta, header, bitmap }) {
  const canvas = $('frame');
  if (header.still || canvas.dataset.frameId == null) {
    canvas.width = header.width;
    canvas.height = header.height;
  }
  canvas.getContext('2d').drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  bitmap.close();
  canvas.dataset.frameId = String(header.id);
  canvas.dataset.still = String(header.still);
  if (meta?.camera) {
    app.frameCamera = meta.camera;
    canvas.dataset.camera = JSON.stringify(meta.camera);
  }
  $('placeholder').hidden = true;
}

function showStats(stats) {
  $('stats').textContent = statsText(stats);
}

let countdown = null;
function showStatus({ state, delayMs }) {
  const node = $('connection');
  node.dataset.state = state;
  clearInterval(countdown);
  $('reconnect').hidden = state !== 'waiting';
  if (state === 'open') {
    node.textContent = 'connected';
    app.opened = true;
  } else if (state === 'connecting') {
    node.textContent = 'connecting…';
  } else {
    const until = performance.now() + delayMs;
    const tick = () => {
      node.textContent = `disconnected — retrying in ${Math.max(0, Math.ceil((until - performance.now()) / 1000))} s`;
    };
    tick();
    countdown = setInterval(tick, 250);
    if (!app.opened && !app.probed) probeView();
  }
}

/**
 * A session that never opened may have been refused for its view (a bad link): asks the
 * render endpoint, which answers with the reason, and falls back to the default view.
 */
async function probeView() {
  app.probed = true;
  try {
    await getBlob(renderUrl(app.view, 16, 16, 'jpeg'));
  } catch (error) {
    if (error instanceof ApiError && error.status >= 400 && error.status < 500) {
      say(`This link's view was refused (${error.message}); showing the default view.`);
      app.view = fromQuery('', app.base);
      app.styles.refresh();
      updateLink();
      app.connection.connect();
    }
  }
}

function serverError(message) {
  const where = message.parameter ? ` (${message.parameter})` : '';
  say(`${message.message}${where}`);
  // A walk off the terrain: back to where the last frame was.
  if (message.parameter === 'position' && app.frameCamera && app.view.z == null) {
    [app.view.x, app.view.y] = app.frameCamera.position;
    scheduleLink();
  }
}

/** Shows the camera mode on the Fly and Plan buttons. */
function showMode() {
  $('fly').setAttribute('aria-pressed', String(app.view.z != null && !app.view.plan));
  $('fly').disabled = Boolean(app.view.plan);
  $('plan').setAttribute('aria-pressed', String(Boolean(app.view.plan)));
}

function setFly(fly) {
  const view = app.view;
  // Flying starts at the eye's height above sea level, which the frames tell.
  if (view.plan || (fly && !app.frameCamera)) return;
  view.z = fly ? app.frameCamera.position[2] : null;
  showMode();
  changed('camera');
}

/** Plan view on (north up, centred where the camera is, half the scene across) or off. */
function setPlan(plan) {
  app.view.plan = plan ? { width: app.base.planWidth / 2 } : null;
  showMode();
  changed('camera');
}

function resetView() {
  const base = app.base;
  Object.assign(app.view, {
    x: base.x, y: base.y, z: null, plan: null, eyeHeight: base.eyeHeight, yaw: base.yaw, pitch: base.pitch, fov: base.fov, roll: 0,
  });
  showMode();
  changed('camera');
}

async function screenshot() {
  const button = $('screenshot');
  button.disabled = true;
  button.textContent = 'Rendering…';
  try {
    const { width, height } = stillSize(1);
    const blob = await getBlob(renderUrl(app.view, width, height, 'png'));
    const url = URL.createObjectURL(blob);
    const a = Object.assign(document.createElement('a'), { href: url, download: `landsketch-${width}x${height}.png` });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
    say(`Screenshot ${width} × ${height} saved.`, 'info');
  } catch (error) {
    say(`Screenshot failed: ${error.message}`);
  } finally {
    button.disabled = false;
    button.textContent = 'Screenshot';
  }
}

async function copyLink() {
  const link = pageLink(app.view);
  const field = $('link');
  field.value = link;
  try {
    await navigator.clipboard.writeText(link);
    say('Link copied.', 'info');
  } catch {
    field.select();
    say('Copy the selected link (the clipboard is not available).', 'info');
  }
}

/**
 * The style controls: a target (the whole view, the terrain or a vegetation layer), its preset
 * and its fields.
 */
function setupStyle() {
  const scene = app.scene;
  const model = new StyleModel(resolveStyles);
  const target = $('style-target');
  for (const name of ['terrain', ...scene.layers.map((l) => l.name)]) target.append(new Option(name, name));
  const preset = $('preset');
  for (const p of scene.presets) preset.append(new Option(p.name.replaceAll('_', ' '), p.name));
  const panel = new StylePanel($('style-fields'), scene.style_schema, (name, value) => {
    model.set(app.view, target.value, name, value);
    changed('style');
  });
  /** Shows the chosen preset and the fields as last resolved. */
  const show = () => {
    const chosen = model.presetOf(app.view, target.value);
    preset.value = chosen;
    $('preset-description').textContent = scene.presets.find((p) => p.name === chosen)?.description ?? '';
    panel.show(model.styleOf(target.value));
    app.art?.showChosen();
  };
  /** Shows the edited style now and again once the server has resolved the view's styles. */
  const refresh = async () => {
    show();
    try {
      if (await model.refresh(app.view)) show();
    } catch (error) {
      say(`Cannot show the style: ${error.message}`);
    }
  };
  target.addEventListener('change', refresh);
  preset.addEventListener('change', () => {
    model.setPreset(app.view, target.value, preset.value);
    refresh();
    changed('style');
  });
  $('style-reset').addEventListener('click', () => {
    model.reset(app.view, target.value);
    refresh();
    changed('style');
  });
  refresh();
  app.styles = {
    refresh,
    /** The edited style's value of field `name`. */
    get: (name) => model.styleOf(target.value)[name],
    /** Sets field `name` of the edited style. */
    set: (name, value) => {
      model.set(app.view, target.value, name, value);
      show();
      changed('style');
    },
  };
}

function setupArt() {
  app.art = new ArtMapsPanel({ chosen: app.styles.get, onChoose: app.styles.set });
  app.art.refresh();
}

async function refreshLayers(data) {
  try {
    const { layers } = await getJSON('/api/layers');
    data.show(layers, app.view.mappings, app.view.time);
  } catch (error) {
    say(`Cannot list the data layers: ${error.message}`);
  }
}

/** Shows `mappings` in the view; without any, the time goes too. */
function setMappings(mappings) {
  app.view.mappings = mappings;
  if (!mappings.length) app.view.time = null;
  changed('data');
}

function setupData(openapi) {
  const schemas = openapi.components?.schemas ?? {};
  const confirm = $('confirm');
  const viewFields = schemas.ViewParams?.properties ?? {};
  const data = new DataPanel({
    targets: 'mappings' in viewFields ? MAPPING_TARGETS : [],
    colormaps: schemas.ColorMapName?.enum ?? [],
    timeSupported: 'time' in viewFields,
    onMappings: setMappings,
    onTime: (time) => {
      app.view.time = time;
      changed('data');
    },
    onDelete: (layer) => {
      $('confirm-text').textContent = `Delete the layer “${layer.name}” and all its time steps? This cannot be undone.`;
      confirm.returnValue = '';
      confirm.showModal();
      confirm.addEventListener('close', async () => {
        if (confirm.returnValue !== 'ok') return;
        try {
          await deleteLayer(layer.id);
          say(`Deleted “${layer.name}”.`, 'info');
          if (app.view.mappings.some((m) => m.layer === layer.id)) {
            setMappings(app.view.mappings.filter((m) => m.layer !== layer.id));
          }
        } catch (error) {
          say(`Cannot delete “${layer.name}”: ${error.message}`);
        }
        refreshLayers(data);
      }, { once: true });
    },
  });
  app.data = data;
  setupUpload(() => refreshLayers(data));
  refreshLayers(data);
}

/** ARIA tabs: click or arrow keys switch the panes. */
function setupTabs() {
  const tabs = [...document.querySelectorAll('[role="tab"]')];
  const select = (tab) => {
    for (const t of tabs) {
      const on = t === tab;
      t.setAttribute('aria-selected', String(on));
      t.tabIndex = on ? 0 : -1;
      $(t.getAttribute('aria-controls')).hidden = !on;
    }
  };
  for (const [i, tab] of tabs.entries()) {
    tab.addEventListener('click', () => select(tab));
    tab.addEventListener('keydown', (e) => {
      const step = { ArrowRight: 1, ArrowLeft: -1 }[e.key];
      if (!step) return;
      const next = tabs[(i + step + tabs.length) % tabs.length];
      select(next);
      next.focus();
    });
  }
  const toggle = $('panel-toggle');
  toggle.addEventListener('click', () => {
    const panel = $('panel');
    panel.hidden = !panel.hidden;
    toggle.setAttribute('aria-expanded', String(!panel.hidden));
  });
}

function setupViewer() {
  const scale = $('render-scale');
  scale.value = localStorage.getItem(SCALE_KEY) ?? DEFAULT_SCALE;
  scale.addEventListener('change', () => {
    localStorage.setItem(SCALE_KEY, scale.value);
    changed('size');
  });
  const viewer = $('viewer');
  const navigator = new Navigator(viewer, {
    getView: () => app.view,
    extent: app.scene.extent,
    onChange: () => changed('camera'),
    onSpeed: (speed) => {
      $('speed').textContent = `${speed < 10 ? speed.toFixed(1) : Math.round(speed)} m/s`;
    },
  });
  navigator.setSpeed(navigator.speed);
  let resizeTimer = null;
  new ResizeObserver(() => {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => changed('size'), RESIZE_DELAY_MS);
  }).observe(viewer);
  $('fly').addEventListener('click', () => setFly(app.view.z == null));
  $('plan').addEventListener('click', () => setPlan(!app.view.plan));
  $('reset-view').addEventListener('click', resetView);
  $('screenshot').addEventListener('click', screenshot);
  $('copy-link').addEventListener('click', copyLink);
  window.addEventListener('keydown', (e) => {
    const free = e.target === viewer || e.target === document.body;
    if (!free || e.ctrlKey || e.metaKey || e.altKey) return;
    if (e.code === 'KeyF') setFly(app.view.z == null);
    else if (e.code === 'KeyP' && !$('plan').hidden) setPlan(!app.view.plan);
  });
}

function setupConnection() {
  const connection = new Connection(sessionUrl);
  app.connection = connection;
  connection.addEventListener('status', (e) => showStatus(e.detail));
  connection.addEventListener('hello', (e) => {
    $('frame').dataset.session = String(e.detail.session);
    // The session opened with the current view in its URL; only later changes need sending,
    // and the data controls once more for their warnings.
    app.dirty.clear();
    if (app.view.mappings.length) changed('data');
  });
  connection.addEventListener('data', (e) => app.data?.showWarnings(e.detail.warnings ?? []));
  connection.addEventListener('frame', (e) => drawFrame(e.detail));
  connection.addEventListener('stats', (e) => showStats(e.detail));
  connection.addEventListener('art_maps', () => app.art?.refresh());
  connection.addEventListener('error', (e) => serverError(e.detail));
  $('reconnect').addEventListener('click', () => connection.connect());
  window.addEventListener('online', () => connection.connect());
  window.addEventListener('pagehide', () => connection.stop());
  connection.connect();
}

async function main() {
  let scene;
  let openapi;
  try {
    [scene, openapi] = await Promise.all([getJSON('/api/scene'), getJSON('/api/openapi.json')]);
  } catch (error) {
    say(`The server is not ready: ${error.message}. Reload the page in a moment.`);
    return;
  }
  app.scene = scene;
  $('scene-name').textContent = scene.name;
  document.title = `landsketch — ${scene.name}`;
  app.base = defaultView(scene);
  const warnings = [];
  app.view = fromQuery(window.location.search, app.base, warnings);
  if (warnings.length) say(warnings.join('; '));
  const camera = openapi.components?.schemas?.CameraParams?.properties ?? {};
  $('plan').hidden = !('mode' in camera);
  showMode();
  setupTabs();
  setupStyle();
  setupData(openapi);
  setupArt();
  setupViewer();
  setupConnection();
  updateLink();
}

main();

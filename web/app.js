// The landsketch viewer: a WebSocket session shows the landscape, the panels change the view,
// and the page's address always holds the view as `GET /api/render` parameters.

import { ApiError, checkAuth, deleteLayer, deleteViewpoint, getBlob, getJSON, resolveStyles, saveViewpoint, setAdminToken, waitUntilReady } from './api.js';
import { ArtMapsPanel } from './artmaps.js';
import { CommentsPanel } from './comments.js';
import { Connection, statsText } from './connection.js';
import { DataPanel, legendUrl } from './data-panel.js';
import { direction, LANGUAGES, currentLanguage, setLanguage, startLanguage, t, translate } from './i18n.js';
import { cameraMessage, dataMessage, defaultView, fromQuery, pageLink, renderUrl, styleMessage, toQuery } from './link.js';
import { keepInside, Navigator } from './navigation.js';
import { horizontalFov, MiniMap, showCompass, showScaleBar } from './orientation.js';
import { composeReport, reportText } from './report.js';
import { StyleModel, StylePanel } from './style-panel.js';
import { showViewpoints, viewpointBody, viewpointCamera } from './viewpoints.js';
import { setupUpload } from './upload.js';

const $ = (id) => document.getElementById(id);
const SCALE_KEY = 'landsketch.renderScale';
/** Full resolution by default: a half-size frame stretched to the viewer looks soft. */
const DEFAULT_SCALE = '1';
/** The planner's admin token for this browser session (`''`: a server without one). */
const TOKEN_KEY = 'landsketch.adminToken';
/** Set once the gesture hints were dismissed. */
const HINT_KEY = 'landsketch.hintSeen';
/** The named looks a citizen chooses from: a preset each (`''` the default pen sketch). */
const LOOKS = [['looks.sketch', ''], ['looks.colour', 'half_npr'], ['looks.photo', 'photorealism'], ['looks.book', 'childrens_book']];
/** Size of a look's picture. */
const LOOK_SIZE = { width: 144, height: 90 };
/** "Go to the plan": the eye above the ground and the distance from the plan's edge, in metres. */
const PLAN_EYE = 25;
const PLAN_MARGIN = 80;
/** "Fly up for an overview": metres the eye rises and the downward look in degrees. */
const FLY_LIFT = 120;
const FLY_PITCH = -20;
/** The default view's downward look on a portrait screen, in degrees. */
const PORTRAIT_PITCH = -10;
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
  mode: 'citizen',
  /** The planner's viewpoints (`GET /api/viewpoints`): what a tour plays when there are any. */
  viewpoints: [],
  /** The accepted-control count when the server last refused one: a newer frame clears its message. */
  refusedAt: null,
};

/** Shows a message under the view; `kind` is `error` or `info`. */
function say(text, kind = 'error') {
  const node = $('message');
  node.dataset.kind = kind;
  node.textContent = text;
  app.refusedAt = null;
}

/** Gives the keyboard back to the view (after a control was used), so the arrow keys walk. */
function focusView() {
  $('viewer').focus({ preventScroll: true });
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
  if (parts.includes('camera')) showOrientation();
  if (parts.includes('style')) showPlanState();
  $('rendering').hidden = false;
  scheduleLink();
}

function flush() {
  app.flushing = null;
  const connection = app.connection;
  if (!connection.open) return;
  // A follower that moves, or changes its view, goes on on its own (from the presenter's view).
  if (app.meeting?.role === 'follower' && [...app.dirty].some((part) => part !== 'size')) {
    connection.send({ type: 'detach' });
  }
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
  $('rendering').hidden = header.still;
  // A refused control's message goes once a frame shows a control accepted after it.
  if (app.refusedAt != null && header.seq > app.refusedAt) {
    $('message').textContent = '';
    app.refusedAt = null;
  }
  if (meta?.camera) {
    app.frameCamera = meta.camera;
    canvas.dataset.camera = JSON.stringify(meta.camera);
    if (app.meeting?.role === 'follower' || app.touring) adoptCamera(meta.camera);
    else landIfGrounded(meta.camera, header.seq);
  }
  $('placeholder').hidden = true;
}

function showStats(stats) {
  $('stats').textContent = statsText(stats);
}

let countdown = null;
function showStatus(status) {
  const { state, delayMs } = status;
  app.status = status;
  const node = $('connection');
  node.dataset.state = state;
  clearInterval(countdown);
  $('reconnect').hidden = state !== 'waiting';
  if (state === 'open') {
    node.textContent = t('conn.open');
    app.opened = true;
  } else if (state === 'connecting') {
    node.textContent = t('conn.connecting');
  } else {
    const until = performance.now() + delayMs;
    const tick = () => {
      node.textContent = t('conn.retry', { s: Math.max(0, Math.ceil((until - performance.now()) / 1000)) });
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
      say(t('msg.refused', { reason: error.message }));
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
  app.refusedAt = app.connection.sent;
  // A walk off the terrain: back to where the last frame was.
  if (message.parameter === 'position' && app.frameCamera && app.view.z == null) {
    [app.view.x, app.view.y] = app.frameCamera.position;
    scheduleLink();
  }
}

/**
 * Flying into the ground lands the eye on it (the server raises it to eye height above the
 * ground): the view flies on from there, so climbing starts at once. Only the frame of the
 * latest control tells where the eye is now.
 */
function landIfGrounded(camera, seq) {
  const view = app.view;
  if (view.z == null || view.plan || seq !== app.connection.sent || !(camera.position[2] > view.z + 0.01)) return;
  view.z = camera.position[2];
  scheduleLink();
}

/** Shows the camera mode on the Fly and Plan buttons. */
function showMode() {
  $('fly').setAttribute('aria-pressed', String(app.view.z != null && !app.view.plan));
  $('fly').disabled = Boolean(app.view.plan);
  $('plan').setAttribute('aria-pressed', String(Boolean(app.view.plan)));
}

/** Flying on (the eye lifts for an overview and looks down a little) or off (walking again). */
function setFly(fly) {
  const view = app.view;
  // Flying starts at the eye's height above sea level, which the frames tell.
  if (view.plan || (fly && !app.frameCamera)) return;
  view.z = fly ? app.frameCamera.position[2] + FLY_LIFT : null;
  if (fly) view.pitch = FLY_PITCH;
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
  setCamera({ x: base.x, y: base.y, eyeHeight: base.eyeHeight, yaw: base.yaw, pitch: base.pitch, fov: base.fov });
}

/** Puts the camera of the view at `camera` (walking unless it says otherwise). */
function setCamera(camera) {
  Object.assign(app.view, { z: null, plan: null, roll: 0, ...camera });
  keepInside(app.view, app.scene.extent);
  showMode();
  changed('camera');
}

/** A plan view over `part` (`{min, max}` in scene metres), with a margin. */
function showArea(part) {
  const width = Math.max(part.max[0] - part.min[0], part.max[1] - part.min[1], 20) * 1.3;
  setCamera({ x: (part.min[0] + part.max[0]) / 2, y: (part.min[1] + part.max[1]) / 2, plan: { width } });
}

/** The scene's planned layer (`[about] plan_layer`) with its extent, or null. */
function planLayer() {
  const name = app.scene.about?.plan_layer;
  return app.scene.layers.find((l) => l.name === name) ?? null;
}

/**
 * "Go to the plan": a raised eye between the scene's start and the planned area, looking at
 * its middle from far enough to see all of it.
 */
function goToPlan() {
  const camera = planCamera();
  if (camera) setCamera(camera);
  else say(t('msg.noPlan'));
}

/** The planner's viewpoints as buttons in the About pane (none: the list is hidden). */
async function loadViewpoints() {
  let viewpoints = [];
  try {
    viewpoints = (await getJSON('/api/viewpoints')).viewpoints ?? [];
  } catch {
    viewpoints = [];
  }
  app.viewpoints = viewpoints;
  $('viewpoints-section').hidden = viewpoints.length === 0;
  const remove = app.mode === 'planner' ? removeViewpoint : null;
  showViewpoints($('viewpoints'), viewpoints, (viewpoint) => {
    setCamera(viewpointCamera(viewpoint.camera ?? {}, app.base));
    if (viewpoint.caption) say(viewpoint.caption, 'info');
    $('viewer').focus();
  }, remove, (viewpoint) => t('viewpoints.remove', { name: viewpoint.name }));
}

/** The planner saves the current view (camera, look, data) as a viewpoint. */
async function saveCurrentViewpoint() {
  const name = $('viewpoint-name').value.trim();
  const status = $('viewpoint-status');
  if (!name) {
    status.dataset.kind = 'error';
    status.textContent = t('viewpoints.needName');
    return;
  }
  try {
    await saveViewpoint(name, viewpointBody(app.view, cameraMessage(app.view), $('viewpoint-caption').value.trim()));
    status.dataset.kind = 'ok';
    status.textContent = t('viewpoints.saved', { name });
    $('viewpoint-name').value = '';
    $('viewpoint-caption').value = '';
    await loadViewpoints();
  } catch (error) {
    status.dataset.kind = 'error';
    status.textContent = t('viewpoints.refused', { reason: error.message });
  }
}

async function removeViewpoint(viewpoint) {
  try {
    await deleteViewpoint(viewpoint.name);
    await loadViewpoints();
  } catch (error) {
    say(t('viewpoints.refused', { reason: error.message }));
  }
}

/** The camera of "Go to the plan", or null without a planned layer. */
function planCamera() {
  const plan = planLayer();
  if (!plan?.extent) return null;
  const { min, max } = plan.extent;
  const centre = [(min[0] + max[0]) / 2, (min[1] + max[1]) / 2];
  let away = [app.base.x - centre[0], app.base.y - centre[1]];
  const length = Math.hypot(...away);
  away = length > 1 ? away.map((v) => v / length) : [0, -1];
  const distance = Math.max(max[0] - min[0], max[1] - min[1]) * 0.6 + PLAN_MARGIN;
  const x = centre[0] + away[0] * distance;
  const y = centre[1] + away[1] * distance;
  const yaw = ((Math.atan2(centre[0] - x, centre[1] - y) * 180) / Math.PI + 360) % 360;
  const pitch = -(Math.atan2(PLAN_EYE, distance) * 180) / Math.PI;
  const inside = { x, y };
  keepInside(inside, app.scene.extent);
  return { ...inside, eyeHeight: PLAN_EYE, yaw, pitch, fov: 60 };
}

/** Takes the camera of a frame the session did not ask for (a presenter's, a tour's) as the view's. */
function adoptCamera(camera) {
  const view = app.view;
  if (camera.mode === 'plan' || !camera.position) return;
  [view.x, view.y, view.z] = camera.position;
  view.plan = null;
  for (const name of ['yaw', 'pitch', 'fov']) if (camera[name] != null) view[name] = camera[name];
  showMode();
  showOrientation();
  scheduleLink();
}

/** The tour: the start, an overview from above it and the plan, each with a caption. */
function tourViewpoints() {
  const base = app.base;
  const at = (camera) => {
    const { type, ...params } = cameraMessage({ ...app.view, z: null, plan: null, roll: 0, ...camera });
    return params;
  };
  const stops = [
    { camera: at({ x: base.x, y: base.y, eyeHeight: base.eyeHeight, yaw: base.yaw, pitch: base.pitch, fov: base.fov }), key: 'start' },
    { camera: at({ x: base.x, y: base.y, eyeHeight: FLY_LIFT, yaw: base.yaw, pitch: FLY_PITCH, fov: base.fov }), key: 'overview' },
  ];
  const plan = planCamera();
  if (plan) stops.push({ camera: at(plan), key: 'plan' });
  return stops.map(({ camera, key }) => ({ camera, name: t(`tour.${key}`), caption: t(`tour.${key}Caption`) }));
}

function toggleTour() {
  if (app.touring) {
    app.connection.send({ type: 'tour', action: 'stop' });
    return;
  }
  app.touring = true;
  $('tour').setAttribute('aria-pressed', 'true');
  // The planner's viewpoints when there are any (the server plays them with their captions),
  // else a tour the browser makes: the start, an overview and the plan.
  const planned = (app.viewpoints ?? []).length > 0;
  app.connection.send({ type: 'tour', action: 'start', ...(planned ? {} : { viewpoints: tourViewpoints() }), dwell_s: 3 });
}

/** A `tour` message: the caption of the viewpoint reached, or the end of the tour. */
function showTour(message) {
  const caption = $('tour-caption');
  if (message.event === 'finished' || message.event === 'stopped') {
    app.touring = false;
    $('tour').setAttribute('aria-pressed', 'false');
    caption.hidden = true;
    return;
  }
  app.touring = true;
  const step = t('tour.step', { name: message.name ?? '', i: message.index + 1, n: message.count });
  caption.textContent = message.caption ? `${step}: ${message.caption}` : step;
  caption.hidden = false;
}

/** The session's meeting: the presenter's code, QR and followers, or a follower's choices. */
function showMeeting(message) {
  app.meeting = message;
  const { code, role } = message;
  $('meeting').hidden = false;
  $('meeting').dataset.code = code;
  $('meeting').dataset.role = role;
  $('meeting-title').textContent = t(`meeting.${{ presenter: 'presenting', follower: 'following', detached: 'detached' }[role]}`, { code });
  const url = new URL(message.join_url, window.location.href).href;
  $('meeting-status').textContent = role === 'presenter' ? t('meeting.followers', { n: message.followers, url }) : '';
  $('meeting-caption').textContent = message.caption ?? '';
  const qr = $('meeting-qr');
  qr.hidden = role !== 'presenter';
  if (role === 'presenter' && qr.dataset.code !== code) {
    qr.src = message.qr_url;
    qr.alt = t('meeting.qr', { code });
    qr.dataset.code = code;
  }
  $('meeting-detach').hidden = role !== 'follower';
  $('meeting-rejoin').hidden = role !== 'detached';
  $('meeting-close').hidden = role !== 'presenter';
  $('meeting-open').hidden = true;
}

/** The meeting panel goes; `message` (a `meeting_ended`) says why. */
function meetingEnded(message = null) {
  app.meeting = null;
  $('meeting').hidden = true;
  $('meeting-open').hidden = false;
  if (message) say(t('meeting.ended', { reason: message.reason }), 'info');
}

function setupMeeting() {
  $('meeting-open').addEventListener('click', () => {
    app.connection.send({ type: 'open_meeting', token: sessionStorage.getItem(TOKEN_KEY) || null });
  });
  $('meeting-close').addEventListener('click', () => {
    app.connection.send({ type: 'close_meeting' });
    meetingEnded();
  });
  $('meeting-detach').addEventListener('click', () => app.connection.send({ type: 'detach' }));
  $('meeting-rejoin').addEventListener('click', () => app.connection.send({ type: 'rejoin' }));
  app.connection.addEventListener('meeting', (e) => showMeeting(e.detail));
  app.connection.addEventListener('meeting_ended', (e) => meetingEnded(e.detail));
  app.connection.addEventListener('tour', (e) => showTour(e.detail));
  // `/?meeting=CODE`: follow that meeting once the session is open (again after a reconnect).
  const code = new URLSearchParams(window.location.search).get('meeting');
  if (code) {
    app.connection.addEventListener('hello', () => app.connection.send({ type: 'join', code }));
  }
}

/** The plan layer's own style in the view (hidden, highlighted or as the rest). */
function planStyle() {
  const plan = planLayer();
  return plan ? app.view.layerStyles[plan.name] ?? null : null;
}

/** Whether the view highlights the plan (style `focus`: the plan in colour, the rest lighter). */
function planHighlighted() {
  return (app.view.style.focus ?? 0) > 0;
}

/** Shows or hides the planned layer and highlights it (style `focus`) or not. */
function setPlanState(shown, highlight) {
  const plan = planLayer();
  if (!plan) return;
  const styles = { ...app.view.layerStyles };
  if (shown) delete styles[plan.name];
  else styles[plan.name] = { visible: false };
  app.view.layerStyles = styles;
  const style = { ...app.view.style };
  if (shown && highlight) style.focus = 1;
  else delete style.focus;
  app.view.style = style;
  app.styles.refresh();
  changed('style');
}

/** The plan buttons and the legend as the view has them. */
function showPlanState() {
  if (!app.scene) return;
  for (const button of $('looks').querySelectorAll('[role="radio"]')) {
    button.setAttribute('aria-checked', String(button.dataset.preset === app.view.preset));
  }
  if (!planLayer()) return;
  const style = planStyle();
  const shown = style?.visible !== false;
  $('with-plan').setAttribute('aria-pressed', String(shown));
  $('highlight-plan').setAttribute('aria-pressed', String(shown && planHighlighted()));
  $('highlight-plan').disabled = !shown;
  $('legend-planned-text').textContent = t(shown ? 'legend.planned' : 'legend.plannedOff');
}

/** Compass, scale bar and mini map for the current camera. */
function showOrientation() {
  const view = app.view;
  if (!view) return;
  showCompass($('compass'), view.plan ? 0 : view.yaw);
  const viewer = $('viewer');
  showScaleBar($('scalebar'), $('scalebar-label'), view.plan?.width, viewer.clientWidth);
  app.minimap?.show(view, viewer.clientWidth / Math.max(1, viewer.clientHeight));
}

/** The legend rows of a report picture: existing and (when shown) planned plants. */
function reportLegend() {
  const rows = [{ label: t('legend.existing'), color: '#1c1c22' }];
  if (planLayer() && planStyle()?.visible !== false) rows.push({ label: t('legend.planned'), color: '#c2410c' });
  return rows;
}

/** Loads the legends of the mapped data layers for a report picture. */
async function reportLegendImages() {
  const layers = app.data?.layers ?? [];
  const images = app.view.mappings.map((m) => layers.find((l) => l.id === m.layer) && legendUrl(layers.find((l) => l.id === m.layer), m)).filter(Boolean);
  return Promise.all(images.map((src) => new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img);
    img.onerror = () => reject(new Error('legend'));
    img.src = src;
  })));
}

/** Saves the view at full resolution with caption, north arrow, legend, scale note and credits. */
async function screenshot() {
  const button = $('screenshot');
  button.disabled = true;
  button.textContent = t('tool.rendering');
  try {
    const { width, height } = stillSize(1);
    const blob = await getBlob(renderUrl(app.view, width, height, 'png'));
    const image = await createImageBitmap(blob);
    const view = app.view;
    const title = app.scene.about?.title ?? app.scene.name;
    const plan = planLayer() ? t(planStyle()?.visible === false ? 'shot.withoutPlan' : 'shot.withPlan') : null;
    const text = reportText(view, {
      caption: t('shot.caption', { title, dir: direction(view.yaw) }),
      planCaption: t('shot.plan', { title }),
      plan,
      width: t('shot.width', { m: Math.round(view.plan?.width ?? 0) }),
      eye: t('shot.distance', { h: view.z == null ? view.eyeHeight.toFixed(1) : Math.round(view.z - (app.frameCamera?.position[2] ?? view.z) + view.eyeHeight) }),
      credit: [t('shot.credit'), app.scene.about?.attribution].filter(Boolean).join(' · '),
    });
    const canvas = composeReport(image, text, view.plan ? 0 : view.yaw, reportLegend(), await reportLegendImages());
    image.close();
    const png = await new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
    const url = URL.createObjectURL(png);
    const a = Object.assign(document.createElement('a'), { href: url, download: `landsketch-${width}x${height}.png` });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
    say(t('shot.saved', { w: width, h: height }), 'info');
  } catch (error) {
    say(t('shot.failed', { reason: error.message }));
  } finally {
    button.disabled = false;
    button.textContent = t('tool.screenshot');
  }
}

async function copyLink() {
  const link = pageLink(app.view);
  const field = $('link');
  field.value = link;
  try {
    await navigator.clipboard.writeText(link);
    say(t('link.copied'), 'info');
  } catch {
    field.select();
    say(t('link.select'), 'info');
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
    // "Visible" hides one layer; the whole view has no such switch (it would hide every plant).
    const visible = panel.rowOf('visible');
    if (visible) visible.hidden = !target.value;
    app.art?.showChosen();
    showPlanState();
  };
  /** Shows the edited style now and again once the server has resolved the view's styles. */
  const refresh = async () => {
    show();
    try {
      if (await model.refresh(app.view)) show();
    } catch (error) {
      say(t('msg.style', { reason: error.message }));
    }
  };
  target.addEventListener('change', refresh);
  preset.addEventListener('change', () => {
    model.setPreset(app.view, target.value, preset.value);
    refresh();
    changed('style');
  });
  $('style-reset').addEventListener('click', () => {
    model.resetAll(app.view);
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
    /** Chooses the view's preset (a citizen's look). */
    look: (name) => {
      model.setPreset(app.view, '', name);
      refresh();
      changed('style');
    },
  };
}

/** The citizen's looks: a few presets with a small picture of each, rendered by the server. */
function setupLooks() {
  const box = $('looks');
  const offered = new Set(app.scene.presets.map((p) => p.name));
  const start = { ...app.base, style: {}, layerStyles: {}, mappings: [] };
  for (const [key, preset] of LOOKS) {
    if (preset && !offered.has(preset)) continue;
    const button = document.createElement('button');
    button.type = 'button';
    button.className = 'look';
    button.setAttribute('role', 'radio');
    button.dataset.preset = preset;
    const img = Object.assign(document.createElement('img'), {
      alt: '', width: LOOK_SIZE.width, height: LOOK_SIZE.height, loading: 'lazy',
      src: renderUrl({ ...start, preset }, LOOK_SIZE.width, LOOK_SIZE.height, 'jpeg'),
    });
    const label = document.createElement('span');
    label.dataset.i18n = key;
    label.textContent = t(key);
    button.append(img, label);
    button.addEventListener('click', () => app.styles.look(preset));
    box.append(button);
  }
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
    say(t('msg.layers', { reason: error.message }));
  }
}

/**
 * Other pages' uploads and deletions, told by the server's `changed` messages
 * (`{"what": "layers", "change": "added" | "changed" | "removed" | "reload", "id"}`): the list
 * is fetched again and a new layer is announced.
 */
async function layersChanged(data, message) {
  const known = new Set(data.layers.map((l) => l.id));
  await refreshLayers(data);
  const added = message.change === 'added' && data.layers.find((l) => l.id === message.id && !known.has(l.id));
  if (added) say(t('msg.newLayer', { name: added.name }), 'info');
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
    extent: app.scene.extent,
    onGoTo: showArea,
    onMappings: setMappings,
    onTime: (time) => {
      app.view.time = time;
      changed('data');
    },
    onDelete: (layer) => {
      $('confirm-text').textContent = t('msg.confirmDelete', { name: layer.name });
      confirm.returnValue = '';
      confirm.showModal();
      confirm.addEventListener('close', async () => {
        if (confirm.returnValue !== 'ok') return;
        try {
          await deleteLayer(layer.id);
          say(t('msg.deleted', { name: layer.name }), 'info');
          if (app.view.mappings.some((m) => m.layer === layer.id)) {
            setMappings(app.view.mappings.filter((m) => m.layer !== layer.id));
          }
        } catch (error) {
          if (error instanceof ApiError && error.status === 401) expired();
          say(t('msg.deleteFailed', { name: layer.name, reason: error.message }));
        }
        refreshLayers(data);
      }, { once: true });
    },
  });
  app.data = data;
  setupUpload(() => refreshLayers(data));
  refreshLayers(data);
}

/** ARIA tabs: click or arrow keys switch the panes (the planner's only in planner mode). */
function setupTabs() {
  const all = [...document.querySelectorAll('[role="tab"]')];
  const select = (tab) => {
    for (const other of all) {
      const on = other === tab;
      other.setAttribute('aria-selected', String(on));
      other.tabIndex = on ? 0 : -1;
      $(other.getAttribute('aria-controls')).hidden = !on;
    }
  };
  for (const tab of all) {
    tab.addEventListener('click', () => select(tab));
    tab.addEventListener('keydown', (e) => {
      const step = { ArrowRight: 1, ArrowLeft: -1 }[e.key];
      if (!step) return;
      const tabs = all.filter((other) => other.getClientRects().length);
      const i = tabs.indexOf(tab);
      const next = tabs[(i + step + tabs.length) % tabs.length];
      select(next);
      next.focus();
    });
  }
  app.selectTab = (name) => select($(`tab-${name}`));
  const toggle = $('panel-toggle');
  toggle.addEventListener('click', () => {
    const panel = $('panel');
    panel.hidden = !panel.hidden;
    document.body.classList.toggle('panel-closed', panel.hidden);
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
  $('go-plan').addEventListener('click', goToPlan);
  $('viewpoint-save').addEventListener('submit', (e) => {
    e.preventDefault();
    saveCurrentViewpoint();
  });
  $('tour').addEventListener('click', toggleTour);
  $('tour').hidden = false;
  $('with-plan').addEventListener('click', () => setPlanState(planStyle()?.visible === false, false));
  $('highlight-plan').addEventListener('click', () => setPlanState(true, !planHighlighted()));
  for (const id of ['go-plan', 'with-plan', 'highlight-plan']) $(id).hidden = !planLayer();
  $('legend-planned').hidden = !planLayer();
  $('screenshot').addEventListener('click', screenshot);
  $('copy-link').addEventListener('click', copyLink);
  window.addEventListener('keydown', (e) => {
    const free = e.target === viewer || e.target === document.body;
    if (!free || e.ctrlKey || e.metaKey || e.altKey) return;
    if (e.code === 'KeyF') setFly(app.view.z == null);
    else if (e.code === 'KeyP' && !$('plan').hidden) setPlan(!app.view.plan);
  });
  // After a choice in a menu, a check box or a button of the view, the keys walk again.
  document.addEventListener('change', (e) => {
    if (e.target.matches('select, input[type="checkbox"]') && !e.target.closest('dialog, form')) focusView();
  });
  document.addEventListener('click', (e) => {
    const button = e.target.closest('button');
    if (button && !button.matches('[role="tab"]') && button.closest('.toolbar, .looks, .layer, #pane-style')) focusView();
  });
  const minimap = new MiniMap($('minimap-image'), $('minimap'), app.scene.extent, (query) => `/api/render?${query}`,
    ([x, y]) => setCamera(app.view.plan ? { x, y, plan: app.view.plan } : { x, y, yaw: app.view.yaw, pitch: app.view.pitch, fov: app.view.fov, eyeHeight: app.view.eyeHeight }));
  const plan = planLayer();
  minimap.setMarks(plan?.extent ? [plan.extent] : [], []);
  app.minimap = minimap;
  showOrientation();
  setupHint(viewer);
}

/** The gesture hints, shown until dismissed once (touch or mouse wording). */
function setupHint(viewer) {
  const hint = $('hint');
  let seen = null;
  try {
    seen = localStorage.getItem(HINT_KEY);
  } catch {
    // No storage: the hints show on every visit.
  }
  const touch = window.matchMedia('(pointer: coarse)').matches;
  $('hint-text').dataset.i18n = touch ? 'hint.touch' : 'hint.mouse';
  $('hint-text').textContent = t($('hint-text').dataset.i18n);
  $('nav-help').dataset.i18n = touch ? 'hint.touch' : 'hint.mouse';
  $('nav-help').textContent = t($('nav-help').dataset.i18n);
  hint.hidden = Boolean(seen);
  const close = () => {
    hint.hidden = true;
    try {
      localStorage.setItem(HINT_KEY, '1');
    } catch {
      // Shown again next time.
    }
  };
  $('hint-close').addEventListener('click', () => {
    close();
    focusView();
  });
  viewer.addEventListener('pointerdown', close, { once: true });
}

/** Citizen or planner: the planner's controls show only after a login. */
function setMode(mode) {
  app.mode = mode;
  document.body.dataset.mode = mode;
  const selected = document.querySelector('[role="tab"][aria-selected="true"]');
  if (mode === 'planner') app.selectTab('style');
  else if (selected?.classList.contains('planner-only')) app.selectTab('about');
  // Planners see every comment with its moderation and can remove viewpoints; citizens not.
  app.comments?.refresh();
  if (app.scene) loadViewpoints();
}

/** Enters planner mode with `token` if the server admits it; the token lasts for this browser session. */
async function login(token) {
  await checkAuth(token);
  sessionStorage.setItem(TOKEN_KEY, token);
  setAdminToken(token);
  setMode('planner');
}

function logout(message = 'login.out') {
  sessionStorage.removeItem(TOKEN_KEY);
  setAdminToken(null);
  setMode('citizen');
  say(t(message), 'info');
}

/** A write was refused for the token: back to citizen mode with the reason. */
function expired() {
  logout('login.expired');
}

function setupLogin() {
  const dialog = $('login-dialog');
  const status = $('login-status');
  const field = $('login-token');
  const open = async () => {
    status.textContent = '';
    field.value = '';
    dialog.showModal();
    // A server without a token admits this computer (loopback) as is: no field to fill.
    try {
      const info = await checkAuth('');
      field.closest('.field').hidden = true;
      $('login-help').textContent = info.token_required ? t('login.help') : t('login.open');
    } catch {
      field.closest('.field').hidden = false;
      $('login-help').textContent = t('login.help');
      field.focus();
    }
  };
  $('login').addEventListener('click', open);
  $('login-cancel').addEventListener('click', () => {
    dialog.close();
    focusView();
  });
  $('login-form').addEventListener('submit', async (e) => {
    e.preventDefault();
    try {
      await login(field.value.trim());
      dialog.close();
      say(t('login.ok'), 'info');
      focusView();
    } catch (error) {
      status.dataset.kind = 'error';
      status.textContent = t('login.wrong', { reason: error.message });
    }
  });
  $('logout').addEventListener('click', () => logout());
  const stored = sessionStorage.getItem(TOKEN_KEY);
  if (stored != null) login(stored).catch(() => logout('login.expired'));
}

/** The language menu. */
function setupLanguage() {
  const select = $('language');
  for (const [code, name] of LANGUAGES) select.append(new Option(name, code));
  select.value = currentLanguage();
  select.addEventListener('change', () => {
    setLanguage(select.value);
    if (app.art?.list) app.art.refresh();
    if (app.status) showStatus(app.status);
    showWelcome();
    showPlanState();
    showOrientation();
  });
}

/** The welcome: the scene file's `[about]` title, description and plan summary. */
function showWelcome() {
  const about = app.scene.about ?? {};
  $('welcome-title').textContent = about.title ?? app.scene.name;
  $('welcome-description').textContent = about.description ?? '';
  $('welcome-plan').textContent = about.plan_summary ?? '';
  $('welcome-plan').hidden = !about.plan_summary;
  showGround();
}

/** The land-cover classes on the ground as rows of the legend: their colour and name. */
function showGround() {
  const rows = (app.scene.ground ?? []).map((ground) => {
    const li = Object.assign(document.createElement('li'), { className: 'ground-class' });
    const swatch = Object.assign(document.createElement('span'), { className: 'swatch' });
    swatch.style.background = ground.color;
    swatch.setAttribute('aria-hidden', 'true');
    li.append(swatch, Object.assign(document.createElement('span'), { textContent: t('legend.ground', { name: ground.name }) }));
    return li;
  });
  $('legend-ground').replaceChildren(...rows);
  $('legend-ground').hidden = rows.length === 0;
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
  connection.addEventListener('changed', (e) => {
    if (e.detail.what === 'layers' && app.data) layersChanged(app.data, e.detail);
  });
  connection.addEventListener('status', (e) => {
    if (e.detail.state !== 'open') $('rendering').hidden = true;
  });
  connection.addEventListener('error', (e) => serverError(e.detail));
  $('reconnect').addEventListener('click', () => connection.connect());
  window.addEventListener('online', () => connection.connect());
  window.addEventListener('pagehide', () => connection.stop());
  connection.connect();
}

async function main() {
  startLanguage();
  translate();
  let scene;
  let openapi;
  try {
    // While the server loads its scene, say how far it has come where the picture will be.
    await waitUntilReady((health) => {
      const stage = t(`stage.${health.stage ?? 'starting'}`);
      $('placeholder').textContent = t('msg.loading', { stage, percent: Math.round(health.percent ?? 0) });
    });
    $('placeholder').textContent = t('view.waiting');
    [scene, openapi] = await Promise.all([getJSON('/api/scene'), getJSON('/api/openapi.json')]);
  } catch (error) {
    say(t('msg.notReady', { reason: error.message }));
    return;
  }
  app.scene = scene;
  $('scene-name').textContent = scene.about?.title ?? scene.name;
  document.title = `landsketch — ${scene.name}`;
  app.base = defaultView(scene);
  const warnings = [];
  app.view = fromQuery(window.location.search, app.base, warnings);
  // A portrait screen shows the default view looking a little down: not half sky.
  const viewer = $('viewer');
  if (!new URLSearchParams(window.location.search).has('pitch') && viewer.clientHeight > viewer.clientWidth * 1.2) {
    app.view.pitch = Math.min(app.view.pitch, PORTRAIT_PITCH);
  }
  if (warnings.length) say(warnings.join('; '));
  const camera = openapi.components?.schemas?.CameraParams?.properties ?? {};
  $('plan').hidden = !('mode' in camera);
  showMode();
  setupTabs();
  setupLanguage();
  showWelcome();
  setupStyle();
  setupLooks();
  setupData(openapi);
  setupArt();
  setupViewer();
  setupLogin();
  setupConnection();
  setupMeeting();
  app.comments = new CommentsPanel({ $, t, app });
  app.comments.load();
  loadViewpoints();
  app.connection.addEventListener('changed', (e) => {
    if (e.detail.what === 'viewpoints') loadViewpoints();
  });
  // A link showing data opens on the data maps, their legends in sight.
  if (app.view.mappings.length) app.selectTab('data');
  showPlanState();
  updateLink();
  document.body.dataset.ready = 'true';
}

main();

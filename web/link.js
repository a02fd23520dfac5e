// The view a page shows, and its encodings: the query string of `GET /api/render` (which is
// also the page's own link and the initial view of a WebSocket session) and the control
// messages of a session. One encoding serves the link, the screenshot and the session, so a
// link renders the same view everywhere.

/** Eye height above the terrain when walking (README "Render parameters"). */
export const DEFAULT_EYE_HEIGHT = 1.7;

/** Decimals kept in links: millimetres and thousandths of a degree. */
const DECIMALS = 3;

/**
 * A view: camera (walking when `z` is null, flying otherwise; a plan view centred on x, y when
 * `plan` is `{width}`), style preset and overrides, per-layer styles (layer name → style
 * fields, optionally a `preset`), data mappings and time: the default view
 * of `scene` (`GET /api/scene`). `planWidth` is the width a plan view starts with: the whole
 * scene.
 */
export function defaultView(scene) {
  const sceneCamera = scene.default_camera;
  const [x, y] = sceneCamera.position;
  const { min, max } = scene.extent;
  return {
    planWidth: Math.max(max[0] - min[0], max[1] - min[1]),
    x,
    y,
    z: null,
    eyeHeight: DEFAULT_EYE_HEIGHT,
    yaw: sceneCamera.yaw,
    pitch: sceneCamera.pitch,
    fov: sceneCamera.fov,
    roll: 0,
    plan: null,
    preset: '',
    style: {},
    layerStyles: {},
    mappings: [],
    time: null,
  };
}

function round(value) {
  return Number(value.toFixed(DECIMALS));
}

/** The render-query parameters of `view`, in a stable order. */
export function viewParams(view) {
  let params;
  if (view.plan) {
    // A plan view is north up.
    params = [['mode', 'plan'], ['center', `${round(view.x)},${round(view.y)}`], ['plan_width', round(view.plan.width)], ['yaw', 0]];
  } else {
    params = [['x', round(view.x)], ['y', round(view.y)]];
    if (view.z == null) params.push(['eye_height', round(view.eyeHeight)]);
    else params.push(['z', round(view.z)]);
    params.push(['yaw', round(view.yaw)], ['pitch', round(view.pitch)], ['fov', round(view.fov)]);
  }
  if (view.roll) params.push(['roll', round(view.roll)]);
  if (view.preset) params.push(['preset', view.preset]);
  if (Object.keys(view.style).length) params.push(['style', JSON.stringify(view.style)]);
  if (Object.keys(view.layerStyles).length) params.push(['layer_styles', JSON.stringify(view.layerStyles)]);
  if (view.mappings.length) params.push(['mappings', JSON.stringify(view.mappings)]);
  if (view.time) params.push(['time', view.time]);
  return params;
}

/** The query string (without `?`) of `view`, plus `extra` parameters (size, format). */
export function toQuery(view, extra = {}) {
  const query = new URLSearchParams(viewParams(view).map(([k, v]) => [k, String(v)]));
  for (const [k, v] of Object.entries(extra)) query.set(k, String(v));
  return query.toString();
}

/** A number parameter, or `fallback` when absent or not a number. */
function number(query, name, fallback) {
  const text = query.get(name);
  if (text == null || text.trim() === '') return fallback;
  const value = Number(text);
  return Number.isFinite(value) ? value : fallback;
}

/**
 * The view a page link describes, starting from `base`: the parameters of `GET /api/render`
 * (`x`, `y`, `z` or `eye_height`, `yaw`, `pitch`, `fov`, `roll`; `mode=plan` with `center` and
 * `plan_width`; `preset`, `style`, `layer_styles`, `mappings`, `time`). Size and format parameters belong to
 * the viewer and are ignored; malformed JSON is reported through `warnings`.
 */
export function fromQuery(search, base, warnings = []) {
  const query = new URLSearchParams(search);
  const view = { ...base, style: { ...base.style }, layerStyles: { ...base.layerStyles }, mappings: [...base.mappings] };
  if (query.get('mode') === 'plan') {
    const [x, y] = (query.get('center') ?? '').split(',').map(Number);
    if (Number.isFinite(x) && Number.isFinite(y)) [view.x, view.y] = [x, y];
    const width = number(query, 'plan_width', null);
    view.plan = { width: width ?? base.planWidth };
  } else if (query.has('x') && query.has('y')) {
    view.x = number(query, 'x', view.x);
    view.y = number(query, 'y', view.y);
    view.z = query.has('z') ? number(query, 'z', null) : null;
  }
  view.eyeHeight = number(query, 'eye_height', view.eyeHeight);
  for (const name of ['pitch', 'fov', 'roll']) view[name] = number(query, name, view[name]);
  if (!view.plan) view.yaw = number(query, 'yaw', view.yaw);
  view.preset = query.get('preset') ?? view.preset;
  view.time = query.get('time') ?? view.time;
  const json = (name, accept, fallback) => {
    if (!query.has(name)) return fallback;
    try {
      const value = JSON.parse(query.get(name));
      if (accept(value)) return value;
    } catch {
      // Reported below.
    }
    warnings.push(`the link's ${name} is not valid; left out`);
    return fallback;
  };
  const isObject = (v) => v && typeof v === 'object' && !Array.isArray(v);
  view.style = json('style', isObject, view.style);
  view.layerStyles = json('layer_styles', isObject, view.layerStyles);
  view.mappings = json('mappings', Array.isArray, view.mappings);
  return view;
}

/**
 * The WebSocket `camera` control message of `view` (walking: `[x, y]` and the eye height;
 * a plan view: centre and width, north up).
 */
export function cameraMessage(view) {
  if (view.plan) {
    return { type: 'camera', mode: 'plan', center: [view.x, view.y], width: view.plan.width, yaw: 0, roll: view.roll };
  }
  const message = { type: 'camera', mode: 'perspective', yaw: view.yaw, pitch: view.pitch, fov: view.fov, roll: view.roll };
  if (view.z == null) {
    message.position = [view.x, view.y];
    message.eye_height = view.eyeHeight;
  } else {
    message.position = [view.x, view.y, view.z];
  }
  return message;
}

/** The WebSocket `style` control message of `view`: its preset and overrides replace the session's. */
export function styleMessage(view) {
  return { type: 'style', preset: view.preset || null, style: view.style, layer_styles: view.layerStyles, replace: true };
}

/** The WebSocket `data` control message of `view`: its mappings and time replace the session's. */
export function dataMessage(view) {
  const message = { type: 'data', mappings: view.mappings };
  if (view.time) message.time = view.time;
  return message;
}

/** The page link of `view`: this page with the view's render query. */
export function pageLink(view, location = window.location) {
  return `${location.origin}${location.pathname}?${toQuery(view)}`;
}

/** The `GET /api/render` URL of `view` at a size and format. */
export function renderUrl(view, width, height, format = 'png') {
  return `/api/render?${toQuery(view, { width, height, format })}`;
}

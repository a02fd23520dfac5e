// Unit tests of web/link.js: the view's encodings (page link / render query, WebSocket controls).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  cameraMessage, dataMessage, DEFAULT_EYE_HEIGHT, defaultView, fromQuery, pageLink, renderUrl, styleMessage, toQuery, viewParams,
} from '../../web/link.js';

/** The parts of `GET /api/scene` that `defaultView` reads. */
const SCENE = {
  default_camera: { position: [120.5, -40.25, 1830.2], yaw: 45, pitch: -5, fov: 60 },
  extent: { min: [-1000, -500], max: [1000, 2500] },
};

const base = () => defaultView(SCENE);

/** A walking view with everything a link can carry. */
function richView() {
  return {
    ...base(),
    x: 12.345,
    y: -678.5,
    eyeHeight: 2.5,
    yaw: 271.25,
    pitch: -12.5,
    fov: 75,
    roll: 3.5,
    preset: 'pencil_sketch',
    style: { hatch_density: 1.5, line_color: [0.1, 0.2, 0.3], note: 'a & b = c #1 ?' },
    layerStyles: { terrain: { preset: 'watercolor', paper_grain: 0.2 }, 'oaks & pines': { leaf_mode: 'cards' } },
    mappings: [
      { layer: 'plume', target: 'color', colormap: 'viridis', range: [0, 10], reverse: true },
      { layer: 'soil', target: 'hatch_color', color: [0.8, 0.4, 0] },
    ],
    time: '2024-06-01T12:30:00+02:00',
  };
}

test('defaultView is the scene default camera, walking, with nothing else set', () => {
  assert.deepEqual(base(), {
    planWidth: 3000,
    x: 120.5,
    y: -40.25,
    z: null,
    eyeHeight: DEFAULT_EYE_HEIGHT,
    yaw: 45,
    pitch: -5,
    fov: 60,
    roll: 0,
    plan: null,
    preset: '',
    style: {},
    layerStyles: {},
    mappings: [],
    time: null,
  });
});

test('a walking view with camera, style, layer styles, mappings and time survives the link', () => {
  const view = richView();
  const query = toQuery(view);
  const warnings = [];
  assert.deepEqual(fromQuery(query, base(), warnings), view);
  assert.deepEqual(warnings, []);
  // The same with the leading `?` of `location.search`.
  assert.deepEqual(fromQuery(`?${query}`, base()), view);
});

test('the default view encodes as the camera alone, in a stable order', () => {
  assert.equal(toQuery(base()), 'x=120.5&y=-40.25&eye_height=1.7&yaw=45&pitch=-5&fov=60');
  assert.deepEqual(fromQuery(toQuery(base()), base()), base());
});

test('link parameters carry the render API names, JSON-encoded and percent-escaped', () => {
  const query = new URLSearchParams(toQuery(richView()));
  assert.deepEqual([...query.keys()], ['x', 'y', 'eye_height', 'yaw', 'pitch', 'fov', 'roll', 'preset', 'style', 'layer_styles', 'mappings', 'time']);
  assert.deepEqual(JSON.parse(query.get('mappings')), richView().mappings);
  // `+` of the time zone must not turn into a space, `&` and `#` of a JSON string must not split the link.
  const raw = toQuery(richView());
  assert.match(raw, /time=2024-06-01T12%3A30%3A00%2B02%3A00$/);
  assert.doesNotMatch(raw, /#/);
  assert.equal(query.get('time'), '2024-06-01T12:30:00+02:00');
});

test('a flying view keeps its height and drops the eye height', () => {
  const view = { ...base(), z: 2105.75, pitch: -30 };
  const params = Object.fromEntries(viewParams(view));
  assert.equal(params.z, 2105.75);
  assert.ok(!('eye_height' in params));
  assert.deepEqual(fromQuery(toQuery(view), base()), view);
});

test('a plan view is north up: yaw 0 in the link, the walking yaw kept', () => {
  const view = { ...base(), x: 10, y: 20, plan: { width: 750.5 } };
  const params = viewParams(view);
  assert.deepEqual(params, [['mode', 'plan'], ['center', '10,20'], ['plan_width', 750.5], ['yaw', 0]]);
  const back = fromQuery(toQuery(view), base());
  assert.deepEqual(back, view);
  assert.equal(back.yaw, SCENE.default_camera.yaw);
});

test('a plan link without a width starts with the whole scene', () => {
  const view = fromQuery('mode=plan&center=5,6', base());
  assert.deepEqual(view.plan, { width: 3000 });
  assert.deepEqual([view.x, view.y], [5, 6]);
});

test('links round to three decimals: millimetres and thousandths of a degree', () => {
  const view = { ...base(), x: 1.23456, y: -0.0004, yaw: 359.99949, pitch: 1e-7, fov: 59.9996 };
  const params = Object.fromEntries(viewParams(view));
  assert.deepEqual([params.x, params.y, params.yaw, params.pitch, params.fov], [1.235, -0, 359.999, 0, 60]);
  assert.equal(new URLSearchParams(toQuery(view)).get('y'), '0');
});

test('size and format belong to the caller: toQuery adds them, fromQuery ignores them', () => {
  const query = new URLSearchParams(toQuery(base(), { width: 800, height: 600, format: 'jpeg', quality: 90 }));
  assert.equal(query.get('width'), '800');
  assert.equal(query.get('format'), 'jpeg');
  const view = fromQuery(query.toString(), base());
  assert.deepEqual(view, base());
  assert.ok(!('width' in view) && !('format' in view));
});

test('malformed JSON in a link is left out with a warning; the rest of the link still applies', () => {
  const warnings = [];
  const view = fromQuery('x=1&y=2&preset=ink&style={bad&layer_styles=[1,2]&mappings={"layer":"a"}', base(), warnings);
  assert.deepEqual(warnings, [
    "the link's style is not valid; left out",
    "the link's layer_styles is not valid; left out",
    "the link's mappings is not valid; left out",
  ]);
  assert.deepEqual(view, { ...base(), x: 1, y: 2, preset: 'ink' });
});

test('JSON of the wrong shape is refused like malformed JSON', () => {
  for (const [name, text] of [['style', 'null'], ['style', '"pencil"'], ['style', '[]'], ['layer_styles', '3'], ['mappings', '{}'], ['mappings', 'null']]) {
    const warnings = [];
    const view = fromQuery(new URLSearchParams([[name, text]]).toString(), base(), warnings);
    assert.deepEqual(warnings, [`the link's ${name} is not valid; left out`], `${name}=${text}`);
    assert.deepEqual(view, base(), `${name}=${text}`);
  }
});

test('numbers that are missing, empty or not numbers fall back to the base view', () => {
  const view = fromQuery('x=abc&y=&yaw=NaN&pitch=Infinity&fov=%20&roll=1e400&eye_height=3', base());
  assert.deepEqual(view, { ...base(), eyeHeight: 3 });
  // A position needs both coordinates.
  assert.deepEqual(fromQuery('x=5', base()), base());
  // An unreadable height walks instead of flying.
  assert.equal(fromQuery('x=1&y=2&z=high', base()).z, null);
  // A plan centre that is not two numbers keeps the position.
  const plan = fromQuery('mode=plan&center=1&plan_width=wide', base());
  assert.deepEqual([plan.x, plan.y, plan.plan.width], [base().x, base().y, 3000]);
});

test('fromQuery does not change the base view it starts from', () => {
  const start = { ...base(), style: { a: 1 }, layerStyles: { terrain: { b: 2 } }, mappings: [{ layer: 'x' }] };
  const frozen = structuredClone(start);
  const view = fromQuery('', start);
  view.style.c = 3;
  view.layerStyles.trees = {};
  view.mappings.push({ layer: 'y' });
  assert.deepEqual(start, frozen);
});

test('camera messages: walking, flying and plan', () => {
  assert.deepEqual(cameraMessage({ ...base(), roll: 2 }), {
    type: 'camera', mode: 'perspective', yaw: 45, pitch: -5, fov: 60, roll: 2, position: [120.5, -40.25], eye_height: 1.7,
  });
  assert.deepEqual(cameraMessage({ ...base(), z: 1900 }), {
    type: 'camera', mode: 'perspective', yaw: 45, pitch: -5, fov: 60, roll: 0, position: [120.5, -40.25, 1900],
  });
  assert.deepEqual(cameraMessage({ ...base(), plan: { width: 400 } }), {
    type: 'camera', mode: 'plan', center: [120.5, -40.25], width: 400, yaw: 0, roll: 0,
  });
});

test('style and data messages replace the session state', () => {
  assert.deepEqual(styleMessage(base()), { type: 'style', preset: null, style: {}, layer_styles: {}, replace: true });
  const view = richView();
  assert.deepEqual(styleMessage(view), { type: 'style', preset: 'pencil_sketch', style: view.style, layer_styles: view.layerStyles, replace: true });
  assert.deepEqual(dataMessage(base()), { type: 'data', mappings: [] });
  assert.deepEqual(dataMessage(view), { type: 'data', mappings: view.mappings, time: view.time });
});

test('page links and render URLs', () => {
  const location = { origin: 'http://example.org:8080', pathname: '/viewer/' };
  const link = pageLink(richView(), location);
  assert.ok(link.startsWith('http://example.org:8080/viewer/?x=12.345&'));
  assert.deepEqual(fromQuery(new URL(link).search, base()), richView());
  assert.equal(renderUrl(base(), 320, 240), '/api/render?x=120.5&y=-40.25&eye_height=1.7&yaw=45&pitch=-5&fov=60&width=320&height=240&format=png');
  assert.match(renderUrl(base(), 16, 16, 'jpeg'), /&format=jpeg$/);
});

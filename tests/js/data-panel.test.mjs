// Unit tests of the pure helpers of web/data-panel.js: colours, times and the time slider,
// legend queries.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { coverage, formatTime, hexOf, legendQuery, legendUrl, positionOf, rgbOf, timeAt } from '../../web/data-panel.js';

test('colours: #rrggbb ↔ sRGB 0…1 with three decimals', () => {
  assert.deepEqual(rgbOf('#ff8000'), [1, 0.502, 0]);
  assert.equal(hexOf([1, 0.502, 0]), '#ff8000');
  assert.equal(hexOf([0, 0.4470588, 0.698]), '#0072b2');
  for (const hex of ['#000000', '#d55e00', '#0072b2', '#009e73', '#ffffff']) assert.equal(hexOf(rgbOf(hex)), hex);
});

test('formatTime shows UTC minutes and leaves what is not a time as it is', () => {
  assert.equal(formatTime('2024-06-01T00:00:00Z'), '2024-06-01 00:00 UTC');
  assert.equal(formatTime('2024-06-01T12:34:56.789+02:00'), '2024-06-01 10:34 UTC');
  assert.equal(formatTime('not a time'), 'not a time');
  assert.equal(formatTime('2024-13-45T00:00:00Z'), '2024-13-45T00:00:00Z');
});

const TIMES = ['2024-01-01T00:00:00Z', '2024-01-02T00:00:00Z', '2024-01-04T00:00:00Z'].map(Date.parse);

test('the time slider has 8 sub-steps between time steps, interpolated', () => {
  assert.equal(timeAt(TIMES, 0), '2024-01-01T00:00:00Z');
  assert.equal(timeAt(TIMES, 4), '2024-01-01T12:00:00Z');
  assert.equal(timeAt(TIMES, 8), '2024-01-02T00:00:00Z');
  assert.equal(timeAt(TIMES, 12), '2024-01-03T00:00:00Z');
  assert.equal(timeAt(TIMES, 16), '2024-01-04T00:00:00Z');
  assert.equal(timeAt([TIMES[0]], 0), '2024-01-01T00:00:00Z', 'one time step');
});

test('positionOf is the nearest sub-step of a time, within the steps', () => {
  for (let position = 0; position <= 16; position += 1) assert.equal(positionOf(TIMES, timeAt(TIMES, position)), position);
  assert.equal(positionOf(TIMES, '2024-01-01T01:00:00Z'), 0);
  assert.equal(positionOf(TIMES, '2024-01-01T02:00:00Z'), 1);
  assert.equal(positionOf(TIMES, '2023-12-01T00:00:00Z'), 0, 'before the first step');
  assert.equal(positionOf(TIMES, '2025-01-01T00:00:00Z'), 16, 'after the last step');
  assert.equal(positionOf(TIMES, 'not a time'), 0);
  assert.equal(positionOf([TIMES[0]], '2024-01-01T00:00:00Z'), 0);
});

test('legendQuery carries the colour map or hatch colour, range and reverse', () => {
  assert.equal(legendQuery(undefined), '');
  assert.equal(legendQuery({ target: 'color', colormap: 'viridis' }), 'colormap=viridis');
  assert.equal(legendQuery({ target: 'color', colormap: 'magma', range: [-1.5, 10], reverse: true }), 'colormap=magma&range=-1.5%2C10&reverse=true');
  assert.equal(legendQuery({ target: 'hatch_color', color: [0.8, 0.4, 0], colormap: 'ignored' }), 'target=hatch_color&color=0.8%2C0.4%2C0');
  assert.equal(legendQuery({ target: 'hatch_tone', reverse: false }), '');
});

test('the legend URL changes with a new time step or range (no stale cached image)', () => {
  const layer = { id: 'a b', steps: [{ time: '2024-06-01T00:00:00Z' }], min: 0, max: 5 };
  const one = legendUrl(layer, { target: 'color', colormap: 'viridis' });
  assert.match(one, /^\/api\/layers\/a%20b\/legend\.png\?colormap=viridis&v=/);
  const two = legendUrl({ ...layer, steps: [...layer.steps, { time: '2024-06-11T00:00:00Z' }], max: 7 }, { target: 'color', colormap: 'viridis' });
  assert.notEqual(one, two);
  assert.match(legendUrl(layer, undefined), /legend\.png\?v=/);
});

test('coverage: the share of the scene a layer covers and the covered part', () => {
  const scene = { min: [-100, -100], max: [100, 100] };
  assert.deepEqual(coverage(scene, [-100, -100, 0, 100]), { share: 0.5, part: { min: [-100, -100], max: [0, 100] } });
  assert.deepEqual(coverage(scene, [-500, -500, 500, 500]), { share: 1, part: scene });
  assert.deepEqual(coverage(scene, [200, 200, 300, 300]), { share: 0, part: null });
});

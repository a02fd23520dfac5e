// Unit tests of the camera arithmetic of web/navigation.js (the server's `move` convention:
// yaw 0 is north (+y), 90 east (+x)).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { keepInside, moveView, pinch, turnView } from '../../web/navigation.js';

const near = (actual, expected, message) => {
  for (const [key, value] of Object.entries(expected)) {
    assert.ok(Math.abs(actual[key] - value) < 1e-9, `${message ?? ''} ${key}: ${actual[key]} ≠ ${value}`);
  }
};
const walking = (extra = {}) => ({ x: 0, y: 0, z: null, eyeHeight: 1.7, yaw: 0, pitch: 0, plan: null, ...extra });

test('walking forward follows the heading; right is 90° clockwise of it', () => {
  const north = walking();
  moveView(north, 10, 0, 0);
  near(north, { x: 0, y: 10 });
  const east = walking({ yaw: 90 });
  moveView(east, 10, 0, 0);
  near(east, { x: 10, y: 0 });
  const right = walking();
  moveView(right, 0, 5, 0);
  near(right, { x: 5, y: 0 });
  const back = walking({ yaw: 180 });
  moveView(back, -2, 0, 0);
  near(back, { x: 0, y: 2 });
});

test('walking ignores the pitch and changes the eye height, never below 10 cm', () => {
  const view = walking({ pitch: -60 });
  moveView(view, 10, 0, 0.5);
  near(view, { x: 0, y: 10, eyeHeight: 2.2 });
  assert.equal(view.z, null);
  moveView(view, 0, 0, -100);
  assert.equal(view.eyeHeight, 0.1);
});

test('flying moves along the view direction', () => {
  const view = walking({ z: 100, pitch: -30, eyeHeight: 1.7 });
  moveView(view, 10, 0, 1);
  near(view, { x: 0, y: 10 * Math.cos(Math.PI / 6), z: 100 + 1 - 5 });
  assert.equal(view.eyeHeight, 1.7);
});

test('a plan view pans north up whatever the yaw', () => {
  const view = walking({ yaw: 123, plan: { width: 100 } });
  moveView(view, 3, 4, 0);
  near(view, { x: 4, y: 3 });
});

test('turnView wraps the yaw to 0…360 and keeps the pitch within ±89°', () => {
  const view = walking({ yaw: 350, pitch: 80 });
  turnView(view, 20, 20);
  near(view, { yaw: 10, pitch: 89 });
  turnView(view, -30, -200);
  near(view, { yaw: 340, pitch: -89 });
  turnView(view, 720, 0);
  near(view, { yaw: 340 });
});

test('keepInside holds the camera a metre inside the scene', () => {
  const extent = { min: [-100, 0], max: [100, 50] };
  const view = walking({ x: -500, y: 60 });
  keepInside(view, extent);
  near(view, { x: -99, y: 49 });
  const inside = walking({ x: 3, y: 4 });
  keepInside(inside, extent);
  near(inside, { x: 3, y: 4 });
});

test('a pinch zooms: spreading narrows the field of view or the plan view, within bounds', () => {
  const view = { fov: 60, plan: null };
  pinch(view, 2);
  assert.equal(view.fov, 30);
  pinch(view, 100);
  assert.equal(view.fov, 10, 'no narrower than 10°');
  pinch(view, 0.01);
  assert.equal(view.fov, 100, 'no wider than 100°');
  const plan = { fov: 60, plan: { width: 1000 } };
  pinch(plan, 4);
  assert.deepEqual([plan.plan.width, plan.fov], [250, 60]);
  pinch(plan, Number.NaN);
  assert.equal(plan.plan.width, 250, 'a bad ratio changes nothing');
});

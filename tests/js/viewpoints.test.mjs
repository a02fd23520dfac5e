// Unit tests of web/viewpoints.js: a viewpoint's camera as the page's view fields.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { viewpointCamera } from '../../web/viewpoints.js';

const base = { x: 0, y: 0, eyeHeight: 1.7, yaw: 10, pitch: -2, fov: 60, planWidth: 2000 };

test('a walking viewpoint keeps the eye height, a flying one its z', () => {
  assert.deepEqual(viewpointCamera({ position: [-150, 150], yaw: 287, pitch: 0 }, base), {
    x: -150, y: 150, z: null, eyeHeight: 1.7, yaw: 287, pitch: 0, fov: 60, plan: null,
  });
  const flying = viewpointCamera({ position: [-120, -60, 2500], eye_height: 150, yaw: 329, pitch: -27 }, base);
  assert.equal(flying.z, 2500);
  assert.equal(flying.eyeHeight, 150);
});

test('a plan viewpoint opens a plan view at its centre and width', () => {
  const plan = viewpointCamera({ mode: 'plan', center: [-270, 187], width: 600, yaw: 0 }, base);
  assert.deepEqual([plan.x, plan.y, plan.plan], [-270, 187, { width: 600 }]);
  assert.deepEqual(viewpointCamera({ mode: 'plan' }, base).plan, { width: 2000 });
});

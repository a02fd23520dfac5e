// Unit tests of web/viewpoints.js: a viewpoint's camera as the page's view fields.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import { viewpointBody, viewpointCamera } from '../../web/viewpoints.js';

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

test('a saved viewpoint holds the camera, and the look and data only when the view has them', () => {
  const camera = { type: 'camera', mode: 'perspective', position: [10, 20], eye_height: 1.7, yaw: 90, pitch: -3, fov: 60, roll: 0 };
  const plain = viewpointBody({ preset: '', style: {}, layerStyles: {}, mappings: [] }, camera, 'The bench');
  assert.deepEqual(plain, { caption: 'The bench', camera: { mode: 'perspective', position: [10, 20], eye_height: 1.7, yaw: 90, pitch: -3, fov: 60, roll: 0 } });
  const styled = viewpointBody(
    { preset: 'photorealism', style: { ink: [0, 0, 0] }, layerStyles: { planned: { visible: false } }, mappings: [{ layer: 'plume' }], time: '2024-01-01T00:00:00Z' },
    camera,
    '',
  );
  assert.equal(styled.preset, 'photorealism');
  assert.deepEqual(styled.layer_styles, { planned: { visible: false } });
  assert.deepEqual(styled.mappings, [{ layer: 'plume' }]);
  assert.equal(styled.time, '2024-01-01T00:00:00Z');
});

// Unit tests of web/comments.js: the author token, the pixel under a pointer, the view a
// comment is made in.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { authorToken, commentView, framePixel } from '../../web/comments.js';

function memoryStorage() {
  const items = new Map();
  return { getItem: (k) => items.get(k) ?? null, setItem: (k, v) => items.set(k, String(v)) };
}

test('the author token is made once and kept', () => {
  const storage = memoryStorage();
  let made = 0;
  const random = () => `token-${++made}-0123456789abcdef`;
  const first = authorToken(storage, random);
  assert.equal(authorToken(storage, random), first);
  assert.equal(made, 1);
  storage.setItem('landsketch-author', 'bad token!');
  assert.notEqual(authorToken(storage, random), 'bad token!', 'a damaged token is replaced');
});

test('the pixel under a pointer scales with the stretched canvas and stays inside it', () => {
  const rect = { left: 10, top: 20, width: 900, height: 564 };
  assert.deepEqual(framePixel(rect, 450, 282, 10, 20), [0, 0]);
  assert.deepEqual(framePixel(rect, 450, 282, 10 + 450, 20 + 282), [225, 141]);
  assert.deepEqual(framePixel(rect, 450, 282, 2000, 2000), [449, 281]);
  assert.deepEqual(framePixel(rect, 450, 282, -5, -5), [0, 0]);
});

test('a comment carries the camera of the frame, its size and the styles that decide what is drawn', () => {
  const view = { x: 1, y: 2, plan: null, roll: 0, preset: 'full_npr', style: {}, layerStyles: { planned: { visible: false } } };
  const camera = { position: [1, 2, 3], yaw: 90, pitch: -5, fov: 60 };
  assert.deepEqual(commentView(view, camera, 450, 282), {
    camera: { position: [1, 2, 3], yaw: 90, pitch: -5, fov: 60, roll: 0 },
    width: 450,
    height: 282,
    preset: 'full_npr',
    layer_styles: { planned: { visible: false } },
  });
  const plan = { ...view, plan: { width: 600 }, preset: null, layerStyles: {} };
  assert.deepEqual(commentView(plan, camera, 100, 80), { camera: { mode: 'plan', center: [1, 2], width: 600, yaw: 0 }, width: 100, height: 80 });
});

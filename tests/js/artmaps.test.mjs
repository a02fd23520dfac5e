// Unit tests of the stroke painting of web/artmaps.js: where painted strokes land in a TAM
// (the chosen tone level and every darker one) or a SAM (one channel), and how ink adds up.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { inked, paintStrokes, parseKey, tileOffset } from '../../web/artmaps.js';
import { decodePng, Pixels } from '../../web/png.js';

test('parseKey splits a map key', () => {
  assert.deepEqual(parseKey('tam:2'), ['tam', 2]);
  assert.deepEqual(parseKey('sam:0'), ['sam', 0]);
});

test('tileOffset: a TAM tile is one tone level of the strip, a SAM tile one channel', () => {
  const tam = { kind: 'tam', width: 4, height: 4 };
  // Strip of 3 levels of 4 × 4: 12 pixels a row.
  assert.equal(tileOffset(tam, 12, 0, 0, 0), 0);
  assert.equal(tileOffset(tam, 12, 3, 0, 0), 3);
  assert.equal(tileOffset(tam, 12, 0, 0, 1), 4);
  assert.equal(tileOffset(tam, 12, 1, 2, 2), 2 * 12 + 8 + 1);
  const sam = { kind: 'sam', width: 8, height: 2 };
  assert.equal(tileOffset(sam, 8, 0, 0, 3), 3);
  assert.equal(tileOffset(sam, 8, 2, 1, 1), (8 + 2) * 4 + 1);
});

test('inked: strokes darken TAM paper and add to SAM ink coverage', () => {
  assert.equal(inked('tam', 255, 0), 255, 'no stroke');
  assert.equal(inked('tam', 255, 255), 0, 'full ink');
  assert.equal(inked('tam', 255, 128), 127);
  assert.equal(inked('tam', 100, 128), 50, 'on grey: paper × (1 − coverage)');
  assert.equal(inked('sam', 0, 0), 0);
  assert.equal(inked('sam', 0, 200), 200, 'on empty SAM: the coverage');
  assert.equal(inked('sam', 128, 128), 192, '1 − (1 − own)(1 − coverage)');
  assert.equal(inked('sam', 255, 17), 255, 'full ink stays');
});

test('paintStrokes into a TAM level also darkens every darker level, not the lighter ones', () => {
  const tile = { kind: 'tam', width: 2, height: 2 };
  const base = new Pixels(6, 2, 1, new Uint8Array(12).fill(255));
  const cover = new Uint8Array([255, 128, 0, 0]);
  const painted = paintStrokes(base, tile, 1, cover);
  assert.deepEqual([...painted.data], [
    255, 255, 0, 127, 0, 127, // row 0: level 0 untouched, levels 1 and 2 inked
    255, 255, 255, 255, 255, 255,
  ]);
  assert.deepEqual([...base.data], new Array(12).fill(255), 'the base map is left as it is');
  // Painting the darkest level touches only it.
  assert.deepEqual([...paintStrokes(base, tile, 2, cover).data].slice(0, 6), [255, 255, 255, 255, 0, 127]);
});

test('paintStrokes into a SAM touches one channel', () => {
  const tile = { kind: 'sam', width: 2, height: 1 };
  const base = new Pixels(2, 1, 4, new Uint8Array([10, 20, 128, 40, 50, 60, 70, 80]));
  const painted = paintStrokes(base, tile, 2, new Uint8Array([128, 255]));
  assert.deepEqual([...painted.data], [10, 20, 192, 40, 50, 60, 255, 80]);
});

test('paintStrokes on a TAM of the repository: no strokes change nothing, strokes keep the nesting', async () => {
  const bytes = readFileSync(new URL('../../data/artmaps/tam_lines.png', import.meta.url));
  const tam = await decodePng(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
  const tile = { kind: 'tam', width: 256, height: 256 };
  const none = paintStrokes(tam, tile, 0, new Uint8Array(256 * 256));
  assert.ok(Buffer.from(none.data).equals(Buffer.from(tam.data)));
  // A stroke across row 100 into level 3: levels 0–2 keep their pixels, levels 3–5 are inked there.
  const cover = new Uint8Array(256 * 256);
  cover.fill(255, 100 * 256, 101 * 256);
  const painted = paintStrokes(tam, tile, 3, cover);
  for (let level = 0; level < 6; level += 1) {
    const row = painted.data.subarray(100 * 1536 + level * 256, 100 * 1536 + (level + 1) * 256);
    if (level < 3) assert.deepEqual([...row], [...tam.data.subarray(100 * 1536 + level * 256, 100 * 1536 + (level + 1) * 256)], `level ${level}`);
    else assert.ok(row.every((v) => v === 0), `level ${level}`);
  }
  assert.ok(Buffer.from(painted.data.subarray(101 * 1536)).equals(Buffer.from(tam.data.subarray(101 * 1536))), 'other rows');
});

// Unit tests of web/png.js, the art-map PNG codec, on the project's own art maps and on
// images it writes.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';
import * as zlib from 'node:zlib';

import { decodePng, encodePng, Pixels } from '../../web/png.js';

const root = new URL('../../', import.meta.url);
/** The bytes of a file of the repository as an `ArrayBuffer`. */
function file(path) {
  const bytes = readFileSync(new URL(path, root));
  return bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
}

async function bytesOf(blob) {
  return new Uint8Array(await blob.arrayBuffer());
}

test('decodes the TAMs of the repository: 6 grey tone levels, lightest first, at their stated darkness', async () => {
  for (const name of ['lines', 'crosshatch', 'scribble', 'stipple']) {
    const tam = await decodePng(file(`data/artmaps/tam_${name}.png`));
    assert.deepEqual([tam.width, tam.height, tam.channels, tam.data.length], [1536, 256, 1, 1536 * 256], name);
    // data/artmaps/README.md: mean darkness 0.10, 0.26, 0.42, 0.58, 0.74, 0.90 (255 = paper).
    const darkness = Array.from({ length: 6 }, (_, level) => {
      let sum = 0;
      for (let y = 0; y < 256; y += 1) for (let x = 0; x < 256; x += 1) sum += tam.data[y * 1536 + level * 256 + x];
      return 1 - sum / (256 * 256 * 255);
    });
    [0.1, 0.26, 0.42, 0.58, 0.74, 0.9].forEach((stated, level) => {
      assert.ok(Math.abs(darkness[level] - stated) < 0.005, `${name} level ${level}: darkness ${darkness[level].toFixed(4)}, stated ${stated}`);
    });
  }
});

test('decodes a SAM of the repository: RGBA, one stroke style a channel, ink on the contour', async () => {
  const sam = await decodePng(file('data/artmaps/sam_0.png'));
  assert.deepEqual([sam.width, sam.height, sam.channels], [256, 32, 4]);
  // Row 0 lies on the contour: every style has ink there, and more of it than in the last row.
  const ink = (y, channel) => {
    let sum = 0;
    for (let x = 0; x < sam.width; x += 1) sum += sam.data[(y * sam.width + x) * 4 + channel];
    return sum;
  };
  for (let channel = 0; channel < 4; channel += 1) {
    assert.ok(ink(0, channel) > 0 && ink(0, channel) > ink(31, channel), `channel ${channel}`);
  }
});

test('re-encoding a decoded art map gives the same pixels', async () => {
  for (const path of ['data/artmaps/tam_crosshatch.png', 'data/artmaps/sam_2.png']) {
    const decoded = await decodePng(file(path));
    const again = await decodePng((await (await encodePng(decoded)).arrayBuffer()));
    assert.deepEqual([again.width, again.height, again.channels], [decoded.width, decoded.height, decoded.channels], path);
    assert.ok(Buffer.from(again.data).equals(Buffer.from(decoded.data)), path);
  }
});

test('encodes grey, grey + alpha, RGB and RGBA as valid PNGs that decode to the same pixels', async () => {
  for (const channels of [1, 2, 3, 4]) {
    const image = new Pixels(5, 3, channels);
    image.data.forEach((_, i) => { image.data[i] = (i * 37 + channels) & 0xff; });
    const blob = await encodePng(image);
    assert.equal(blob.type, 'image/png');
    const bytes = await bytesOf(blob);
    assert.deepEqual([...bytes.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
    // IHDR: width, height, depth 8, the colour type of the channels.
    const view = new DataView(bytes.buffer);
    assert.equal(new TextDecoder().decode(bytes.subarray(12, 16)), 'IHDR');
    assert.deepEqual([view.getUint32(16), view.getUint32(20), bytes[24], bytes[25]], [5, 3, 8, { 1: 0, 2: 4, 3: 2, 4: 6 }[channels]]);
    const back = await decodePng(bytes.buffer);
    assert.deepEqual([back.width, back.height, back.channels, [...back.data]], [5, 3, channels, [...image.data]]);
  }
});

test('chunk CRCs are right (zlib CRC-32 of type and body)', { skip: !zlib.crc32 && 'node:zlib has crc32 from Node 20.15' }, async () => {
  const bytes = await bytesOf(await encodePng(new Pixels(2, 2, 1, new Uint8Array([0, 64, 128, 255]))));
  const view = new DataView(bytes.buffer);
  const types = [];
  for (let at = 8; at < bytes.length;) {
    const length = view.getUint32(at);
    types.push(new TextDecoder().decode(bytes.subarray(at + 4, at + 8)));
    assert.equal(view.getUint32(at + 8 + length), zlib.crc32(bytes.subarray(at + 4, at + 8 + length)), types.at(-1));
    at += 12 + length;
  }
  assert.deepEqual(types, ['IHDR', 'IDAT', 'IEND']);
});

test('refuses what it cannot read, saying why', async () => {
  await assert.rejects(decodePng(new TextEncoder().encode('GIF89a, not a PNG at all, no no no').buffer), { message: 'not a PNG file' });
  await assert.rejects(decodePng(new ArrayBuffer(8)), { message: 'not a PNG file' });
  // An 8-bit palette PNG (a glTF test texture of the repository).
  await assert.rejects(decodePng(file('data/test/gltf/BoxTextured-glTF/CesiumLogoFlat.png')), /only 8-bit grey, grey \+ alpha, RGB and RGBA PNGs/);
  // A header that claims more rows than the image data holds.
  const bytes = await bytesOf(await encodePng(new Pixels(4, 2, 1)));
  new DataView(bytes.buffer).setUint32(20, 3);
  await assert.rejects(decodePng(bytes.buffer), { message: 'the PNG is truncated' });
});

test('Pixels.to converts between channel counts: grey ↔ colour, missing alpha opaque', () => {
  const rgba = new Pixels(2, 1, 4, new Uint8Array([255, 0, 0, 128, 10, 20, 30, 255]));
  assert.deepEqual([...rgba.to(3).data], [255, 0, 0, 10, 20, 30]);
  // Grey by Rec. 601 luma.
  assert.deepEqual([...rgba.to(1).data], [76, 18]);
  assert.deepEqual([...rgba.to(2).data], [76, 128, 18, 255]);
  const grey = new Pixels(2, 1, 1, new Uint8Array([7, 200]));
  assert.deepEqual([...grey.to(4).data], [7, 7, 7, 255, 200, 200, 200, 255]);
  assert.deepEqual([...grey.to(2).data], [7, 255, 200, 255]);
  // Same channel count: a copy.
  const copy = grey.to(1);
  copy.data[0] = 0;
  assert.equal(grey.data[0], 7);
});

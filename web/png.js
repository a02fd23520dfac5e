// A small PNG codec for art maps (README "Art maps over the API"): 8-bit grey, grey + alpha,
// RGB and RGBA, not interlaced. The canvas cannot be used for these bytes: it premultiplies
// alpha, and a SAM's alpha channel is the ink of its heaviest stroke style, not opacity.

const SIGNATURE = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];
/** Channels by PNG colour type (0 grey, 2 RGB, 4 grey + alpha, 6 RGBA). */
const CHANNELS = { 0: 1, 2: 3, 4: 2, 6: 4 };
const COLOR_TYPE = { 1: 0, 2: 4, 3: 2, 4: 6 };

/** An image's pixels: `channels` bytes a pixel, rows top to bottom. */
export class Pixels {
  constructor(width, height, channels, data = new Uint8Array(width * height * channels)) {
    this.width = width;
    this.height = height;
    this.channels = channels;
    this.data = data;
  }

  /** The same image with `channels` channels: grey ↔ colour, a missing alpha opaque. */
  to(channels) {
    if (channels === this.channels) return new Pixels(this.width, this.height, channels, this.data.slice());
    const out = new Pixels(this.width, this.height, channels);
    const from = this.channels;
    for (let p = 0, n = this.width * this.height; p < n; p += 1) {
      const s = p * from;
      const colour = from >= 3 ? [this.data[s], this.data[s + 1], this.data[s + 2]] : [this.data[s], this.data[s], this.data[s]];
      const alpha = from === 2 || from === 4 ? this.data[s + from - 1] : 255;
      const grey = Math.round(0.299 * colour[0] + 0.587 * colour[1] + 0.114 * colour[2]);
      const values = { 1: [grey], 2: [grey, alpha], 3: colour, 4: [...colour, alpha] }[channels];
      out.data.set(values, p * channels);
    }
    return out;
  }
}

async function transform(bytes, stream) {
  const piped = new Blob([bytes]).stream().pipeThrough(stream);
  return new Uint8Array(await new Response(piped).arrayBuffer());
}

const CRC_TABLE = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k += 1) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});

function crc32(bytes) {
  let c = 0xffffffff;
  for (const b of bytes) c = CRC_TABLE[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

function paeth(a, b, c) {
  const p = a + b - c;
  const pa = Math.abs(p - a);
  const pb = Math.abs(p - b);
  const pc = Math.abs(p - c);
  if (pa <= pb && pa <= pc) return a;
  return pb <= pc ? b : c;
}

/** Decodes a PNG (`ArrayBuffer`); throws an `Error` saying what it cannot read. */
export async function decodePng(buffer) {
  const bytes = new Uint8Array(buffer);
  const view = new DataView(buffer);
  if (bytes.length < 33 || SIGNATURE.some((b, i) => bytes[i] !== b)) throw new Error('not a PNG file');
  let header = null;
  const parts = [];
  for (let at = 8; at + 8 <= bytes.length;) {
    const length = view.getUint32(at);
    const type = String.fromCharCode(...bytes.subarray(at + 4, at + 8));
    const body = bytes.subarray(at + 8, at + 8 + length);
    if (type === 'IHDR') {
      header = { width: view.getUint32(at + 8), height: view.getUint32(at + 12), depth: body[8], colour: body[9], interlace: body[12] };
    } else if (type === 'IDAT') {
      parts.push(body);
    } else if (type === 'IEND') {
      break;
    }
    at += 12 + length;
  }
  const channels = CHANNELS[header?.colour];
  if (!header || header.depth !== 8 || !channels || header.interlace !== 0) {
    throw new Error('only 8-bit grey, grey + alpha, RGB and RGBA PNGs without interlacing can be edited here');
  }
  const raw = await transform(new Blob(parts), new DecompressionStream('deflate'));
  const { width, height } = header;
  const stride = width * channels;
  if (raw.length < height * (stride + 1)) throw new Error('the PNG is truncated');
  const out = new Pixels(width, height, channels);
  const data = out.data;
  for (let y = 0; y < height; y += 1) {
    const filter = raw[y * (stride + 1)];
    const src = y * (stride + 1) + 1;
    const row = y * stride;
    if (filter > 4) throw new Error(`unknown PNG filter ${filter}`);
    for (let x = 0; x < stride; x += 1) {
      const a = x >= channels ? data[row + x - channels] : 0;
      const b = y > 0 ? data[row - stride + x] : 0;
      let predictor = 0;
      if (filter === 1) predictor = a;
      else if (filter === 2) predictor = b;
      else if (filter === 3) predictor = (a + b) >> 1;
      else if (filter === 4) predictor = paeth(a, b, x >= channels && y > 0 ? data[row - stride + x - channels] : 0);
      data[row + x] = (raw[src + x] + predictor) & 0xff;
    }
  }
  return out;
}

function chunk(type, body) {
  const out = new Uint8Array(12 + body.length);
  const view = new DataView(out.buffer);
  view.setUint32(0, body.length);
  out.set([...type].map((ch) => ch.charCodeAt(0)), 4);
  out.set(body, 8);
  view.setUint32(8 + body.length, crc32(out.subarray(4, 8 + body.length)));
  return out;
}

/** Encodes `pixels` (1, 2, 3 or 4 channels) as a PNG `Blob`. */
export async function encodePng(pixels) {
  const { width, height, channels, data } = pixels;
  const stride = width * channels;
  const raw = new Uint8Array(height * (stride + 1));
  for (let y = 0; y < height; y += 1) raw.set(data.subarray(y * stride, (y + 1) * stride), y * (stride + 1) + 1);
  const header = new Uint8Array(13);
  const view = new DataView(header.buffer);
  view.setUint32(0, width);
  view.setUint32(4, height);
  header.set([8, COLOR_TYPE[channels], 0, 0, 0], 8);
  const compressed = await transform(raw, new CompressionStream('deflate'));
  const parts = [new Uint8Array(SIGNATURE), chunk('IHDR', header), chunk('IDAT', compressed), chunk('IEND', new Uint8Array())];
  return new Blob(parts, { type: 'image/png' });
}

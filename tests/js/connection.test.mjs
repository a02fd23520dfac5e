// Unit tests of web/connection.js: the binary frame header, the reconnect back-off, and the
// session's bookkeeping (reconnects, latency, dropped frames) over a fake WebSocket.
import assert from 'node:assert/strict';
import { afterEach, beforeEach, describe, test } from 'node:test';

import { backoffDelay, Connection, HEADER_LEN, parseHeader, statsText } from '../../web/connection.js';

// Node 18 has no global CustomEvent (the browsers and Node 19+ do).
globalThis.CustomEvent ??= class CustomEvent extends Event {
  constructor(type, init = {}) {
    super(type, init);
    this.detail = init.detail ?? null;
  }
};

/**
 * The header of the Rust test `frame_header_round_trips_and_rejects_other_bytes`
 * (server/src/api/ws.rs): JPEG, frame 7, seq 0x01020304, 1024 × 768, 512 ms, still, quality 90.
 */
const RUST_HEADER = [
  0x4c, 0x53, 0x01, 0x01, // "LS", version 1, format 1 (JPEG)
  0x07, 0x00, 0x00, 0x00, // frame id 7
  0x04, 0x03, 0x02, 0x01, // seq 0x01020304
  0x00, 0x04, 0x00, 0x03, // 1024 × 768
  0x00, 0x02, 0x01, 0x5a, // 512 ms, still, quality 90
];

/** A binary message: header fields written byte by byte (little-endian), then `image`. */
function frameBytes({ format = 0, id = 1, seq = 0, width = 320, height = 240, renderMs = 0, still = 0, quality = 0 }, image = [0x89, 0x50, 0x4e, 0x47]) {
  const le = (value, n) => Array.from({ length: n }, (_, i) => (value >>> (8 * i)) & 0xff);
  return new Uint8Array([
    0x4c, 0x53, 1, format, ...le(id, 4), ...le(seq, 4), ...le(width, 2), ...le(height, 2), ...le(renderMs, 2), still, quality, ...image,
  ]).buffer;
}

describe('parseHeader', () => {
  test('reads the header the server writes', () => {
    assert.equal(HEADER_LEN, RUST_HEADER.length);
    assert.deepEqual(parseHeader(new Uint8Array(RUST_HEADER).buffer), {
      format: 'jpeg', id: 7, seq: 0x01020304, width: 1024, height: 768, renderMs: 512, still: true, quality: 90,
    });
  });

  test('reads an interactive PNG frame followed by its image, with full-range fields', () => {
    const bytes = frameBytes({ id: 0xffffffff, seq: 0x80000001, width: 65535, height: 1, renderMs: 65535 }, new Array(1000).fill(7));
    assert.deepEqual(parseHeader(bytes), {
      format: 'png', id: 0xffffffff, seq: 0x80000001, width: 65535, height: 1, renderMs: 65535, still: false, quality: 0,
    });
  });

  test('refuses bytes that are not a frame', () => {
    const good = new Uint8Array(RUST_HEADER);
    const changed = (at, value) => {
      const bytes = good.slice();
      bytes[at] = value;
      return bytes.buffer;
    };
    assert.equal(parseHeader(good.slice(0, HEADER_LEN - 1).buffer), null, 'short');
    assert.equal(parseHeader(new ArrayBuffer(0)), null, 'empty');
    assert.equal(parseHeader(changed(0, 0x4d)), null, 'magic');
    assert.equal(parseHeader(changed(1, 0x54)), null, 'magic');
    assert.equal(parseHeader(changed(2, 2)), null, 'protocol version');
    assert.equal(parseHeader(changed(3, 2)), null, 'format');
    // A bare PNG (the same check as the Rust test's).
    assert.equal(parseHeader(new TextEncoder().encode('PNG\r\n\x1a\n................').buffer), null, 'PNG');
  });
});

describe('backoffDelay', () => {
  test('doubles from 0.5 s and stops at 15 s', () => {
    const middle = () => 0.5;
    assert.deepEqual([0, 1, 2, 3, 4, 5, 6, 10, 50].map((a) => backoffDelay(a, middle)), [500, 1000, 2000, 4000, 8000, 15000, 15000, 15000, 15000]);
  });

  test('jitters by ±25 %', () => {
    assert.equal(backoffDelay(0, () => 0), 375);
    assert.equal(backoffDelay(0, () => 0.999999), 625);
    assert.equal(backoffDelay(20, () => 0), 11250);
    assert.equal(backoffDelay(20, () => 0.999999), 18750);
    for (let attempt = 0; attempt < 12; attempt += 1) {
      const base = Math.min(15000, 500 * 2 ** attempt);
      const delay = backoffDelay(attempt);
      assert.ok(delay >= base * 0.75 && delay <= base * 1.25, `attempt ${attempt}: ${delay}`);
    }
  });
});

test('statsText shows the figures that are known', () => {
  assert.equal(statsText({ fps: 0, latencyMs: null, rttMs: null, renderMs: null, frames: 0 }), 'idle');
  assert.equal(statsText({ fps: 0, latencyMs: null, rttMs: 3, renderMs: 40, frames: 1 }), 'idle · rtt 3 ms · render 40 ms');
  assert.equal(statsText({ fps: 12.04, latencyMs: 84.6, rttMs: 2.4, renderMs: 40, frames: 9 }), '12.0 fps · latency 85 ms · rtt 2 ms · render 40 ms');
  assert.equal(statsText({ fps: 9.96, latencyMs: null, rttMs: 0, renderMs: 0 }), '10.0 fps · rtt 0 ms · render 0 ms');
});

/** A WebSocket that the test opens, feeds and closes. */
class FakeSocket extends EventTarget {
  static CONNECTING = 0;
  static OPEN = 1;
  static CLOSING = 2;
  static CLOSED = 3;
  static all = [];

  constructor(url) {
    super();
    this.url = url;
    this.readyState = FakeSocket.CONNECTING;
    this.binaryType = 'blob';
    this.sent = [];
    this.closedWith = null;
    FakeSocket.all.push(this);
  }

  send(text) {
    assert.equal(this.readyState, FakeSocket.OPEN, 'send on a socket that is not open');
    this.sent.push(JSON.parse(text));
  }

  close(code, reason) {
    this.closedWith = [code, reason];
    this.readyState = FakeSocket.CLOSING;
  }

  /** The server's side: the socket opens, a message (text or `ArrayBuffer`) comes in, the socket closes. */
  open() {
    this.readyState = FakeSocket.OPEN;
  }

  message(data) {
    this.dispatchEvent(Object.assign(new Event('message'), { data }));
  }

  json(message) {
    this.message(JSON.stringify(message));
  }

  drop() {
    this.readyState = FakeSocket.CLOSED;
    this.dispatchEvent(new Event('close'));
  }
}

describe('Connection', () => {
  const saved = {};
  let timeouts;
  let intervals;
  let decoded;

  beforeEach(() => {
    for (const name of ['WebSocket', 'window', 'setTimeout', 'clearTimeout', 'setInterval', 'clearInterval', 'createImageBitmap']) {
      saved[name] = Object.getOwnPropertyDescriptor(globalThis, name);
    }
    saved.random = Math.random;
    FakeSocket.all = [];
    timeouts = new Map();
    intervals = new Map();
    decoded = [];
    let nextTimer = 1;
    const define = (name, value) => Object.defineProperty(globalThis, name, { value, configurable: true, writable: true });
    define('WebSocket', FakeSocket);
    define('window', { location: { protocol: 'https:', host: 'landsketch.example:8443' } });
    define('setTimeout', (fn, ms) => {
      timeouts.set(nextTimer, { fn, ms });
      return nextTimer++;
    });
    define('clearTimeout', (id) => timeouts.delete(id));
    define('setInterval', (fn, ms) => {
      intervals.set(nextTimer, { fn, ms });
      return nextTimer++;
    });
    define('clearInterval', (id) => intervals.delete(id));
    define('createImageBitmap', async (blob) => {
      const bitmap = { bytes: new Uint8Array(await blob.arrayBuffer()), type: blob.type, closed: false, close() { this.closed = true; } };
      decoded.push(bitmap);
      return bitmap;
    });
    Math.random = () => 0.5;
  });

  afterEach(() => {
    for (const [name, descriptor] of Object.entries(saved)) {
      if (name === 'random') continue;
      if (descriptor) Object.defineProperty(globalThis, name, descriptor);
      else delete globalThis[name];
    }
    Math.random = saved.random;
  });

  /** A connection whose events are recorded in `events` as `[type, detail]`. */
  function connection(url = () => '/api/ws?x=1&y=2') {
    const c = new Connection(url);
    const events = [];
    for (const type of ['status', 'hello', 'frame', 'data', 'art_maps', 'error', 'stats']) {
      c.addEventListener(type, (e) => events.push([type, e.detail]));
    }
    return { c, events, of: (type) => events.filter(([t]) => t === type).map(([, d]) => d) };
  }

  /** Fires the one pending time-out (the reconnect) and returns its delay. */
  function fireRetry() {
    assert.equal(timeouts.size, 1, 'one reconnect pending');
    const [[id, { fn, ms }]] = timeouts;
    timeouts.delete(id);
    fn();
    return ms;
  }

  test('opens the session URL over wss on an https page, binary frames as ArrayBuffer', () => {
    let asked = 0;
    const { c, of } = connection(() => `/api/ws?n=${++asked}`);
    c.connect();
    const [socket] = FakeSocket.all;
    assert.equal(socket.url, 'wss://landsketch.example:8443/api/ws?n=1');
    assert.equal(socket.binaryType, 'arraybuffer');
    assert.deepEqual(of('status'), [{ state: 'connecting', attempt: 0 }]);
    assert.equal(c.open, false);
    // A second connect while connecting or open opens nothing.
    c.connect();
    socket.open();
    c.connect();
    assert.equal(FakeSocket.all.length, 1);
    assert.equal(c.open, true);
  });

  test('reconnects with growing delays, capped, asking for the URL again each time', () => {
    let asked = 0;
    const { c, of } = connection(() => `/api/ws?n=${++asked}`);
    c.connect();
    const delays = [];
    for (let i = 0; i < 8; i += 1) {
      FakeSocket.all.at(-1).drop();
      delays.push(fireRetry());
    }
    assert.deepEqual(delays, [500, 1000, 2000, 4000, 8000, 15000, 15000, 15000]);
    assert.equal(FakeSocket.all.length, 9);
    assert.equal(FakeSocket.all.at(-1).url, 'wss://landsketch.example:8443/api/ws?n=9');
    const waiting = of('status').filter((s) => s.state === 'waiting');
    assert.deepEqual(waiting.map((s) => s.attempt), [1, 2, 3, 4, 5, 6, 7, 8]);
    assert.deepEqual(waiting.map((s) => s.delayMs), delays);
    assert.deepEqual(of('status').at(-1), { state: 'connecting', attempt: 8 });
  });

  test('a hello resets the back-off; the next drop waits 0.5 s again', () => {
    const { c, of } = connection();
    c.connect();
    for (let i = 0; i < 3; i += 1) {
      FakeSocket.all.at(-1).drop();
      fireRetry();
    }
    const socket = FakeSocket.all.at(-1);
    socket.open();
    socket.json({ type: 'hello', session: 5 });
    assert.equal(c.attempt, 0);
    assert.deepEqual(of('status').at(-1), { state: 'open' });
    assert.deepEqual(of('hello'), [{ type: 'hello', session: 5 }]);
    // The hello starts the pings: one now, then every 10 s.
    assert.deepEqual(socket.sent, [{ type: 'ping', id: 1 }]);
    assert.deepEqual([...intervals.values()].map((i) => i.ms), [10000]);
    socket.drop();
    assert.deepEqual(of('status').at(-1), { state: 'waiting', delayMs: 500, attempt: 1 });
    assert.equal(intervals.size, 0, 'pings stop with the session');
  });

  test('connect() while waiting reconnects at once and cancels the pending retry', () => {
    const { c } = connection();
    c.connect();
    FakeSocket.all[0].drop();
    assert.equal(timeouts.size, 1);
    c.connect();
    assert.equal(timeouts.size, 0);
    assert.equal(FakeSocket.all.length, 2);
  });

  test('stop() closes the session for good', () => {
    const { c, of } = connection();
    c.connect();
    const socket = FakeSocket.all[0];
    socket.open();
    socket.json({ type: 'hello', session: 1 });
    c.stop();
    assert.deepEqual(socket.closedWith, [1000, 'page closed']);
    socket.drop();
    assert.equal(timeouts.size, 0);
    assert.equal(intervals.size, 0);
    assert.ok(!of('status').some((s) => s.state === 'waiting'));
    assert.equal(c.send({ type: 'camera' }), false);
  });

  test('the close of a replaced socket is ignored', () => {
    const { c } = connection();
    c.connect();
    const first = FakeSocket.all[0];
    first.drop();
    fireRetry();
    first.drop();
    assert.equal(timeouts.size, 0);
    assert.equal(c.socket, FakeSocket.all[1]);
  });

  test('controls are not sent while closed; pings do not count in seq; rejected controls do not either', async () => {
    const { c, of } = connection();
    c.connect();
    const socket = FakeSocket.all[0];
    assert.equal(c.send({ type: 'camera', yaw: 1 }), false);
    socket.open();
    socket.json({ type: 'hello', session: 1 });
    assert.equal(c.send({ type: 'camera', yaw: 1 }), true);
    assert.equal(c.send({ type: 'camera', yaw: 2 }), true);
    assert.equal(c.send({ type: 'camera', yaw: 3 }), true);
    assert.equal(c.sent, 3);
    socket.json({ type: 'error', code: 'invalid_parameter', message: 'yaw', parameter: 'yaw' });
    assert.equal(c.sent, 2);
    // A failed render is not a rejected control.
    socket.json({ type: 'error', code: 'render_failed', message: 'GPU lost' });
    assert.equal(c.sent, 2);
    assert.deepEqual(of('error').map((e) => e.code), ['invalid_parameter', 'render_failed']);
    assert.deepEqual(socket.sent.map((m) => m.type), ['ping', 'camera', 'camera', 'camera']);

    socket.json({ type: 'frame', id: 1, seq: 2, camera: { position: [1, 2, 3] } });
    await c.binary(frameBytes({ id: 1, seq: 2, format: 1, renderMs: 33, still: 1, quality: 90 }, [0xff, 0xd8, 0xff]));
    const [frame] = of('frame');
    assert.deepEqual(frame.meta, { type: 'frame', id: 1, seq: 2, camera: { position: [1, 2, 3] } });
    assert.equal(frame.header.seq, 2);
    assert.ok(frame.latencyMs >= 0, 'latency of control 2');
    assert.deepEqual([...decoded[0].bytes], [0xff, 0xd8, 0xff]);
    assert.equal(decoded[0].type, 'image/jpeg');
    const [stats] = of('stats');
    assert.equal(stats.renderMs, 33);
    assert.equal(stats.frames, 1);
    assert.equal(stats.latencyMs, frame.latencyMs);
  });

  test('a frame decoded after a newer one is dropped; a message that is not a frame is ignored', async () => {
    const { c, of } = connection();
    c.connect();
    const socket = FakeSocket.all[0];
    socket.open();
    socket.json({ type: 'hello', session: 1 });
    // Binary messages go to the decoder; the older one finishes last.
    socket.message(frameBytes({ id: 5 }));
    socket.message(frameBytes({ id: 4 }));
    await new Promise((resolve) => setImmediate(resolve));
    assert.deepEqual(of('frame').map((f) => f.header.id), [5]);
    assert.deepEqual(decoded.map((b) => b.closed), [false, true]);
    await c.binary(frameBytes({ id: 5 }));
    assert.equal(of('frame').length, 1, 'a frame id shown already');
    socket.json({ type: 'frame', id: 6 });
    await c.binary(new Uint8Array([1, 2, 3]).buffer);
    assert.equal(of('frame').length, 1);
    assert.equal(c.pendingMeta, null);
    // A new session starts counting frame ids again.
    socket.json({ type: 'hello', session: 2 });
    await c.binary(frameBytes({ id: 1 }));
    assert.deepEqual(of('frame').map((f) => f.header.id), [5, 1]);
  });

  test('pongs give the round trip; data, art_maps and garbage text', () => {
    const { c, of } = connection();
    c.connect();
    const socket = FakeSocket.all[0];
    socket.open();
    socket.json({ type: 'hello', session: 1 });
    socket.json({ type: 'pong', id: 99 });
    assert.equal(c.stats.rttMs, null, 'an unknown pong');
    socket.json({ type: 'pong', id: 1 });
    assert.ok(c.stats.rttMs >= 0);
    assert.equal(of('stats').length, 1);
    socket.json({ type: 'data', time: '2024-01-01T00:00:00Z', warnings: ['w'] });
    socket.json({ type: 'art_maps', tams: 4, sams: 4 });
    socket.message('not json');
    socket.json({ type: 'something new' });
    assert.deepEqual(of('data'), [{ type: 'data', time: '2024-01-01T00:00:00Z', warnings: ['w'] }]);
    assert.deepEqual(of('art_maps'), [{ type: 'art_maps', tams: 4, sams: 4 }]);
  });
});

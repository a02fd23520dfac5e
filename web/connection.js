// The WebSocket session (`GET /api/ws`, README "WebSocket"): JSON control messages out; JSON
// status messages and binary frames (20-byte header, then PNG or JPEG) in. Reconnects with
// exponential back-off and keeps the figures of the fps/latency readout.

/** Length of a binary frame's header. */
export const HEADER_LEN = 20;
const PROTOCOL = 1;
const FIRST_DELAY_MS = 500;
const MAX_DELAY_MS = 15000;
const PING_INTERVAL_MS = 10000;
const FPS_WINDOW_MS = 3000;
/** Error codes with which the server rejects a control message (it does not count in `seq`). */
const REJECTED = new Set(['bad_request', 'invalid_parameter', 'too_large', 'not_found']);

/**
 * Reads a binary frame's header (little-endian): magic `LS`, version, format, frame id, seq,
 * width, height, render ms, kind, quality. `null` when the bytes are not a frame.
 */
export function parseHeader(buffer) {
  if (buffer.byteLength < HEADER_LEN) return null;
  const view = new DataView(buffer, 0, HEADER_LEN);
  if (view.getUint8(0) !== 0x4c || view.getUint8(1) !== 0x53 || view.getUint8(2) !== PROTOCOL) return null;
  const format = view.getUint8(3);
  if (format > 1) return null;
  return {
    format: format === 0 ? 'png' : 'jpeg',
    id: view.getUint32(4, true),
    seq: view.getUint32(8, true),
    width: view.getUint16(12, true),
    height: view.getUint16(14, true),
    renderMs: view.getUint16(16, true),
    still: view.getUint8(18) === 1,
    quality: view.getUint8(19),
  };
}

/** The delay before reconnect attempt `attempt` (0, 1, …): doubling from 0.5 s to 15 s, ±25 % jitter. */
export function backoffDelay(attempt, random = Math.random) {
  const base = Math.min(MAX_DELAY_MS, FIRST_DELAY_MS * 2 ** attempt);
  return Math.round(base * (0.75 + 0.5 * random()));
}

/**
 * The readout of a session's `stats`: `12.0 fps · latency 85 ms · rtt 3 ms · render 40 ms`,
 * figures not known yet left out; `idle` instead of `0.0 fps` (no frames come while the view
 * rests, which is no fault).
 */
export function statsText(stats) {
  const parts = [stats.fps > 0 ? `${stats.fps.toFixed(1)} fps` : 'idle'];
  if (stats.latencyMs != null) parts.push(`latency ${Math.round(stats.latencyMs)} ms`);
  if (stats.rttMs != null) parts.push(`rtt ${Math.round(stats.rttMs)} ms`);
  if (stats.renderMs != null) parts.push(`render ${stats.renderMs} ms`);
  return parts.join(' · ');
}

/**
 * A session that reconnects by itself. Events: `status` (detail: `{state, delayMs?, attempt?}`
 * with state `connecting`, `open`, `waiting`), `hello`, `frame` (detail: `{meta, header,
 * bitmap, latencyMs}`), `data` (the answer to a `data` control: time and warnings), `art_maps` (the server's art
 * maps changed: their counts; a new frame follows), `changed` (comments, layers, viewpoints or
 * art maps changed on the server: `{what, change, id?}`), `meeting` (the session's meeting:
 * code, role, caption, followers, join and QR URLs), `meeting_ended`, `tour` (a tour's
 * progress), `error`
 * (a server `error` message), `stats`.
 */
export class Connection extends EventTarget {
  /** `url()` gives the session URL (with the current view) at each (re)connect. */
  constructor(url) {
    super();
    this.url = url;
    this.socket = null;
    this.attempt = 0;
    this.retryTimer = null;
    this.pingTimer = null;
    this.pendingMeta = null;
    this.sent = 0;
    this.sentAt = new Map();
    this.frameTimes = [];
    this.lastDrawnId = 0;
    this.stats = { fps: 0, latencyMs: null, rttMs: null, renderMs: null, frames: 0 };
    this.pings = new Map();
    this.pingId = 0;
    this.stopped = false;
  }

  /** Opens the session (or reopens it now, skipping a pending back-off). */
  connect() {
    clearTimeout(this.retryTimer);
    this.retryTimer = null;
    if (this.socket && this.socket.readyState <= WebSocket.OPEN) return;
    this.stopped = false;
    const scheme = window.location.protocol === 'https:' ? 'wss' : 'ws';
    const socket = new WebSocket(`${scheme}://${window.location.host}${this.url()}`);
    socket.binaryType = 'arraybuffer';
    this.socket = socket;
    this.status({ state: 'connecting', attempt: this.attempt });
    socket.addEventListener('message', (event) => this.receive(event.data));
    socket.addEventListener('close', () => this.closed(socket));
  }

  /** Closes the session for good (no reconnect). */
  stop() {
    this.stopped = true;
    clearTimeout(this.retryTimer);
    clearInterval(this.pingTimer);
    this.socket?.close(1000, 'page closed');
  }

  /** Whether the session is open. */
  get open() {
    return this.socket?.readyState === WebSocket.OPEN;
  }

  /** Sends a control message; false when the session is not open (the view is sent on reconnect). */
  send(message) {
    if (!this.open) return false;
    if (message.type !== 'ping') {
      this.sent += 1;
      this.sentAt.set(this.sent, performance.now());
    }
    this.socket.send(JSON.stringify(message));
    return true;
  }

  status(detail) {
    this.dispatchEvent(new CustomEvent('status', { detail }));
  }

  closed(socket) {
    if (socket !== this.socket) return;
    clearInterval(this.pingTimer);
    this.socket = null;
    this.pendingMeta = null;
    if (this.stopped) return;
    const delayMs = backoffDelay(this.attempt);
    this.attempt += 1;
    this.status({ state: 'waiting', delayMs, attempt: this.attempt });
    this.retryTimer = setTimeout(() => this.connect(), delayMs);
  }

  receive(data) {
    if (typeof data !== 'string') {
      this.binary(data);
      return;
    }
    let message;
    try {
      message = JSON.parse(data);
    } catch {
      return;
    }
    switch (message.type) {
      case 'hello':
        this.attempt = 0;
        this.sent = 0;
        this.sentAt.clear();
        this.lastDrawnId = 0;
        clearInterval(this.pingTimer);
        this.pingTimer = setInterval(() => this.ping(), PING_INTERVAL_MS);
        this.ping();
        this.status({ state: 'open' });
        this.dispatchEvent(new CustomEvent('hello', { detail: message }));
        break;
      case 'frame':
        this.pendingMeta = message;
        break;
      case 'data':
      case 'art_maps':
      case 'changed':
      case 'meeting':
      case 'meeting_ended':
      case 'tour':
        this.dispatchEvent(new CustomEvent(message.type, { detail: message }));
        break;
      case 'pong':
        this.pong(message.id);
        break;
      case 'error':
        if (REJECTED.has(message.code) && this.sent > 0) {
          this.sentAt.delete(this.sent);
          this.sent -= 1;
        }
        this.dispatchEvent(new CustomEvent('error', { detail: message }));
        break;
      default:
        break;
    }
  }

  async binary(buffer) {
    const header = parseHeader(buffer);
    const meta = this.pendingMeta;
    this.pendingMeta = null;
    if (!header) return;
    const now = performance.now();
    let latencyMs = null;
    for (const [seq, at] of this.sentAt) {
      if (seq > header.seq) break;
      if (seq === header.seq) latencyMs = now - at;
      this.sentAt.delete(seq);
    }
    this.frameTimes.push(now);
    while (this.frameTimes.length && this.frameTimes[0] < now - FPS_WINDOW_MS) this.frameTimes.shift();
    const stats = this.stats;
    stats.frames += 1;
    stats.fps = this.frameTimes.length > 1 ? ((this.frameTimes.length - 1) * 1000) / (now - this.frameTimes[0]) : 0;
    stats.renderMs = header.renderMs;
    if (latencyMs != null) stats.latencyMs = latencyMs;
    const type = header.format === 'png' ? 'image/png' : 'image/jpeg';
    let bitmap;
    try {
      bitmap = await createImageBitmap(new Blob([buffer.slice(HEADER_LEN)], { type }));
    } catch {
      return;
    }
    // Decoding is asynchronous: a frame that finishes after a newer one is dropped.
    if (header.id <= this.lastDrawnId) {
      bitmap.close();
      return;
    }
    this.lastDrawnId = header.id;
    this.dispatchEvent(new CustomEvent('frame', { detail: { meta, header, bitmap, latencyMs } }));
    this.dispatchEvent(new CustomEvent('stats', { detail: stats }));
  }

  ping() {
    this.pingId += 1;
    this.pings.set(this.pingId, performance.now());
    this.send({ type: 'ping', id: this.pingId });
  }

  pong(id) {
    const at = this.pings.get(id);
    if (at == null) return;
    this.pings.clear();
    this.stats.rttMs = performance.now() - at;
    this.dispatchEvent(new CustomEvent('stats', { detail: this.stats }));
  }
}

// Walking navigation on the viewer: mouse drag looks around, WASD/arrow keys walk, the wheel
// sets the walking speed, Q/E lower and raise the eye; on touch screens one finger looks, two
// fingers walk and pinching zooms (the field of view). In a plan view, dragging pans the map
// and the wheel or a pinch zooms. The camera is
// the client's (`view`); the server puts a walking eye at its height above the terrain.

/** Walking speed bounds in metres per second; the wheel steps by a factor of 1.25. */
const MIN_SPEED = 0.5;
const MAX_SPEED = 500;
const SPEED_STEP = 1.25;
/** Degrees per second of turning with the left/right arrow keys. */
const TURN_RATE = 60;
/** Fastest climb of Q/E, relative to the walking speed. */
const CLIMB_FACTOR = 0.5;
/** Metres of terrain kept between the camera and the scene's edge. */
const EDGE_MARGIN = 1;
/** Speed-up while Shift is held. */
const RUN_FACTOR = 4;
/** Smallest and largest plan-view width in metres. */
const MIN_PLAN_WIDTH = 10;
const MAX_PLAN_WIDTH = 100000;
/** Field of view a pinch zooms within, in degrees. */
const MIN_FOV = 10;
const MAX_FOV = 100;

const KEYS = {
  KeyW: ['forward', 1],
  ArrowUp: ['forward', 1],
  KeyS: ['forward', -1],
  ArrowDown: ['forward', -1],
  KeyD: ['right', 1],
  KeyA: ['right', -1],
  ArrowRight: ['turn', 1],
  ArrowLeft: ['turn', -1],
  KeyE: ['up', 1],
  PageUp: ['up', 1],
  KeyQ: ['up', -1],
  PageDown: ['up', -1],
};

const clamp = (value, lo, hi) => Math.min(hi, Math.max(lo, value));
const radians = (degrees) => (degrees * Math.PI) / 180;

/**
 * Moves `view` by `forward`, `right` and `up` metres along its heading (the server's `move`
 * convention: yaw 0 is north, 90 east). Walking keeps the eye on the terrain and `up` changes
 * the eye height; flying moves along the view direction; a plan view pans with north up.
 */
export function moveView(view, forward, right, up) {
  const yaw = radians(view.plan ? 0 : view.yaw);
  const pitch = radians(view.z == null || view.plan ? 0 : view.pitch);
  const ahead = forward * Math.cos(pitch);
  view.x += ahead * Math.sin(yaw) + right * Math.cos(yaw);
  view.y += ahead * Math.cos(yaw) - right * Math.sin(yaw);
  if (view.z == null) view.eyeHeight = Math.max(0.1, view.eyeHeight + up);
  else view.z += up + forward * Math.sin(pitch);
}

/** Keeps `view` inside the scene's `extent` (`{min: [x, y], max: [x, y]}`). */
export function keepInside(view, extent) {
  view.x = clamp(view.x, extent.min[0] + EDGE_MARGIN, extent.max[0] - EDGE_MARGIN);
  view.y = clamp(view.y, extent.min[1] + EDGE_MARGIN, extent.max[1] - EDGE_MARGIN);
}

/** Turns `view` by yaw and pitch degrees; yaw wraps to 0…360, pitch stays within ±89. */
export function turnView(view, yaw, pitch) {
  view.yaw = (((view.yaw + yaw) % 360) + 360) % 360;
  view.pitch = clamp(view.pitch + pitch, -89, 89);
}

/**
 * A pinch by `ratio` (the fingers' new distance over the old): spreading zooms in — a narrower
 * field of view, or a narrower plan view.
 */
export function pinch(view, ratio) {
  if (!(ratio > 0)) return;
  if (view.plan) view.plan.width = clamp(view.plan.width / ratio, MIN_PLAN_WIDTH, MAX_PLAN_WIDTH);
  else view.fov = clamp(view.fov / ratio, MIN_FOV, MAX_FOV);
}

/** Mouse, keyboard, wheel and touch input on `surface`, applied to the view `getView()` gives. */
export class Navigator {
  /**
   * `options`: `getView()`, `extent` (scene extent), `onChange()` after every change of the
   * camera, `onSpeed(speed)` when the walking speed changes.
   */
  constructor(surface, options) {
    this.surface = surface;
    this.options = options;
    this.speed = 4;
    this.held = new Map();
    this.running = false;
    this.pointers = new Map();
    this.lastTick = null;
    this.frame = null;
    surface.addEventListener('pointerdown', (e) => this.pointerDown(e));
    surface.addEventListener('pointermove', (e) => this.pointerMove(e));
    for (const type of ['pointerup', 'pointercancel']) surface.addEventListener(type, (e) => this.pointerUp(e));
    surface.addEventListener('wheel', (e) => this.wheel(e), { passive: false });
    window.addEventListener('keydown', (e) => this.key(e, true));
    window.addEventListener('keyup', (e) => this.key(e, false));
    window.addEventListener('blur', () => this.held.clear());
  }

  changed() {
    const view = this.options.getView();
    keepInside(view, this.options.extent);
    this.options.onChange();
  }

  /** Sets the walking speed (clamped) and reports it. */
  setSpeed(speed) {
    this.speed = clamp(speed, MIN_SPEED, MAX_SPEED);
    this.options.onSpeed?.(this.speed);
  }

  /** Keys act when the viewer or nothing in particular has the focus (not in a form field). */
  key(event, down) {
    const binding = KEYS[event.code];
    if (!binding) return;
    const target = event.target;
    if (down && target !== this.surface && target !== document.body && target !== document.documentElement) return;
    if (event.altKey || event.ctrlKey || event.metaKey) return;
    event.preventDefault();
    if (down) this.held.set(event.code, binding);
    else this.held.delete(event.code);
    this.running = event.shiftKey;
    if (this.held.size && this.frame == null) {
      this.lastTick = performance.now();
      this.frame = requestAnimationFrame((t) => this.tick(t));
    }
  }

  tick(now) {
    this.frame = null;
    if (!this.held.size) return;
    const dt = Math.min(0.1, Math.max(0, (now - this.lastTick) / 1000));
    this.lastTick = now;
    const axes = { forward: 0, right: 0, up: 0, turn: 0 };
    for (const [axis, sign] of this.held.values()) axes[axis] += sign;
    const view = this.options.getView();
    const step = this.speed * (this.running ? RUN_FACTOR : 1) * dt;
    if (view.plan) {
      const pan = (view.plan.width / 4) * dt * (this.running ? RUN_FACTOR : 1);
      moveView(view, axes.forward * pan, (axes.right + axes.turn) * pan, 0);
      if (axes.up) this.zoomPlan(view, SPEED_STEP ** (-axes.up * dt * 4));
    } else {
      turnView(view, axes.turn * TURN_RATE * dt, 0);
      moveView(view, axes.forward * step, axes.right * step, axes.up * step * CLIMB_FACTOR);
    }
    this.changed();
    this.frame = requestAnimationFrame((t) => this.tick(t));
  }

  zoomPlan(view, factor) {
    view.plan.width = clamp(view.plan.width * factor, MIN_PLAN_WIDTH, MAX_PLAN_WIDTH);
  }

  wheel(event) {
    event.preventDefault();
    const factor = event.deltaY > 0 ? 1 / SPEED_STEP : SPEED_STEP;
    const view = this.options.getView();
    if (view.plan) {
      this.zoomPlan(view, 1 / factor);
      this.changed();
    } else {
      this.setSpeed(this.speed * factor);
    }
  }

  pointerDown(event) {
    this.surface.focus({ preventScroll: true });
    this.surface.setPointerCapture(event.pointerId);
    this.pointers.set(event.pointerId, { x: event.clientX, y: event.clientY });
  }

  pointerUp(event) {
    this.pointers.delete(event.pointerId);
  }

  /** Distance between the first two pointers on the surface (0 with fewer). */
  spread() {
    const [a, b] = this.pointers.values();
    return a && b ? Math.hypot(a.x - b.x, a.y - b.y) : 0;
  }

  pointerMove(event) {
    const last = this.pointers.get(event.pointerId);
    if (!last) return;
    const dx = event.clientX - last.x;
    const dy = event.clientY - last.y;
    const before = this.spread();
    this.pointers.set(event.pointerId, { x: event.clientX, y: event.clientY });
    const after = this.spread();
    const view = this.options.getView();
    const rect = this.surface.getBoundingClientRect();
    const count = this.pointers.size;
    if (count >= 2 && before > 0 && after > 0) pinch(view, after / before);
    if (view.plan) {
      // Grab the map: it follows the pointer (one finger or the mouse; two fingers pan at half rate).
      const metres = view.plan.width / Math.max(1, rect.width) / count;
      moveView(view, dy * metres, -dx * metres, 0);
    } else if (count >= 2) {
      // Two fingers walk: pushing them up walks forward, sideways steps sideways.
      const metres = (this.speed * 2) / Math.max(1, rect.height) / count;
      moveView(view, -dy * metres * 10, dx * metres * 10, 0);
    } else {
      // Grab the landscape: it follows the pointer across the field of view.
      const degrees = view.fov / Math.max(1, rect.height);
      turnView(view, -dx * degrees, dy * degrees);
    }
    this.changed();
  }
}

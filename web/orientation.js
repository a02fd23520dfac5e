// Orientation aids over the view: the mini map (a small plan-view render of the whole scene
// from `GET /api/render?mode=plan`, with "you are here", the view cone, the planned areas and
// the viewpoints drawn over it in the browser), the compass and the scale bar of the plan view.

import { direction, t } from './i18n.js';

/** Pixels of the mini map's render (square). */
export const MINIMAP_SIZE = 160;

/**
 * The plan view that shows the whole scene `extent` (`{min, max}`) on a square map: its
 * centre and width in metres.
 */
export function overview(extent) {
  const [x0, y0] = extent.min;
  const [x1, y1] = extent.max;
  return { center: [(x0 + x1) / 2, (y0 + y1) / 2], width: Math.max(x1 - x0, y1 - y0) };
}

/** Scene metres `[x, y]` → pixel `[px, py]` of a `size`-pixel square map of `map` (`overview`), north up. */
export function toMap(map, size, [x, y]) {
  const scale = size / map.width;
  return [size / 2 + (x - map.center[0]) * scale, size / 2 - (y - map.center[1]) * scale];
}

/** Pixel `[px, py]` of the map → scene metres `[x, y]` (the inverse of `toMap`). */
export function fromMap(map, size, [px, py]) {
  const scale = map.width / size;
  return [map.center[0] + (px - size / 2) * scale, map.center[1] - (py - size / 2) * scale];
}

/** The horizontal field of view (degrees) of a vertical `fov` on a frame `aspect` (width / height) wide. */
export function horizontalFov(fov, aspect) {
  const half = (fov * Math.PI) / 360;
  return (360 / Math.PI) * Math.atan(Math.tan(half) * aspect);
}

/**
 * A round length for a scale bar at most `maxMetres` long: 1, 2 or 5 times a power of ten
 * (metres), or null when under a metre.
 */
export function niceLength(maxMetres) {
  if (!(maxMetres >= 1)) return null;
  const power = 10 ** Math.floor(Math.log10(maxMetres));
  return [5, 2, 1].map((f) => f * power).find((m) => m <= maxMetres);
}

/** The mini map: the scene's plan render with the camera, its view cone, planned areas and viewpoints. */
export class MiniMap {
  /**
   * `image` (an `<img>`) and `canvas` (the overlay, same size); `extent` of the scene;
   * `renderUrl(query)` the plan render's URL; `onPick([x, y])` when the map is tapped.
   */
  constructor(image, canvas, extent, renderUrl, onPick) {
    this.image = image;
    this.canvas = canvas;
    this.map = overview(extent);
    this.areas = [];
    this.points = [];
    this.view = null;
    const [cx, cy] = this.map.center;
    image.src = renderUrl(`mode=plan&center=${cx.toFixed(1)},${cy.toFixed(1)}&plan_width=${this.map.width.toFixed(1)}&yaw=0`
      + `&width=${MINIMAP_SIZE}&height=${MINIMAP_SIZE}&format=jpeg`);
    const pick = (px, py) => onPick(fromMap(this.map, MINIMAP_SIZE, [px, py]));
    canvas.addEventListener('click', (e) => {
      const rect = canvas.getBoundingClientRect();
      pick(((e.clientX - rect.left) / rect.width) * MINIMAP_SIZE, ((e.clientY - rect.top) / rect.height) * MINIMAP_SIZE);
    });
    canvas.addEventListener('keydown', (e) => {
      if (e.key !== 'Enter' && e.key !== ' ') return;
      e.preventDefault();
      pick(MINIMAP_SIZE / 2, MINIMAP_SIZE / 2);
    });
  }

  /** Sets the outlined areas (`[{min, max}]`, scene metres) and the viewpoints (`[[x, y]]`). */
  setMarks(areas, points) {
    this.areas = areas;
    this.points = points;
    this.draw();
  }

  /** Draws the camera of `view` (position, heading, field of view on a frame `aspect` wide). */
  show(view, aspect) {
    this.view = { x: view.x, y: view.y, yaw: view.plan ? 0 : view.yaw, fov: view.fov, plan: view.plan, aspect };
    this.draw();
  }

  draw() {
    const g = this.canvas.getContext('2d');
    const size = MINIMAP_SIZE;
    g.clearRect(0, 0, size, size);
    g.lineWidth = 2;
    for (const { min, max } of this.areas) {
      const [ax, ay] = toMap(this.map, size, [min[0], max[1]]);
      const [bx, by] = toMap(this.map, size, [max[0], min[1]]);
      g.strokeStyle = '#c2410c';
      g.setLineDash([4, 3]);
      g.strokeRect(ax, ay, bx - ax, by - ay);
    }
    g.setLineDash([]);
    for (const point of this.points) {
      const [px, py] = toMap(this.map, size, point);
      g.fillStyle = '#1f5fa8';
      g.fillRect(px - 3, py - 3, 6, 6);
    }
    const view = this.view;
    if (!view) return;
    const [px, py] = toMap(this.map, size, [view.x, view.y]);
    if (view.plan) {
      // The plan view's frame.
      const half = (view.plan.width / this.map.width) * size / 2;
      g.strokeStyle = '#1f5fa8';
      g.strokeRect(px - half, py - half / view.aspect, half * 2, (half * 2) / view.aspect);
    } else {
      const spread = (horizontalFov(view.fov, view.aspect) * Math.PI) / 360;
      const heading = (view.yaw * Math.PI) / 180;
      const reach = size * 0.3;
      g.fillStyle = 'rgba(31, 95, 168, 0.25)';
      g.beginPath();
      g.moveTo(px, py);
      for (const a of [heading - spread, heading + spread]) g.lineTo(px + Math.sin(a) * reach, py - Math.cos(a) * reach);
      g.closePath();
      g.fill();
    }
    g.fillStyle = '#d00';
    g.strokeStyle = '#fff';
    g.beginPath();
    g.arc(px, py, 4.5, 0, Math.PI * 2);
    g.fill();
    g.stroke();
    this.canvas.title = t('map.here');
  }
}

/** Turns the compass `node` to the view's heading and names it. */
export function showCompass(node, yaw) {
  node.style.setProperty('--heading', `${-yaw}deg`);
  const deg = Math.round((((yaw % 360) + 360) % 360));
  node.setAttribute('aria-label', t('view.compass', { dir: direction(yaw), deg }));
}

/** Shows the scale bar of a plan view `planWidth` metres across a viewer `pixels` wide (hidden otherwise). */
export function showScaleBar(box, label, planWidth, pixels) {
  const metres = planWidth && pixels ? niceLength(planWidth / 4) : null;
  box.hidden = metres == null;
  if (metres == null) return;
  box.querySelector('.bar-line').style.width = `${(metres / planWidth) * pixels}px`;
  label.textContent = metres >= 1000 ? `${metres / 1000} km` : `${metres} m`;
}

// The data panel: the stored layers (`GET /api/layers`) with their legends
// (`/api/layers/{id}/legend.png`, drawn with the layer's mapping), a mapping choice per layer
// (target, colour map or hatch colour, range), the server's suitability warnings (thesis
// Table 9.1), a delete button, and the time slider with play/pause and speed.

import { t } from './i18n.js';

/** Sub-steps of the time slider between two time steps of the data. */
const SUBSTEPS = 8;
/** Default inks of `hatch_color` mappings (the server's `fields::HATCH_COLORS`, Okabe–Ito). */
const HATCH_COLORS = ['#d55e00', '#0072b2', '#009e73'];

/** `#rrggbb` as the API's sRGB `[r, g, b]` (0…1). */
export function rgbOf(hex) {
  return [1, 3, 5].map((i) => Math.round((parseInt(hex.slice(i, i + 2), 16) / 255) * 1000) / 1000);
}

/** The API's sRGB `[r, g, b]` (0…1) as `#rrggbb`. */
export function hexOf(rgb) {
  return `#${rgb.map((c) => Math.round(c * 255).toString(16).padStart(2, '0')).join('')}`;
}

/** Formats an RFC 3339 time without fractions: `2024-06-01 00:00 UTC`. */
export function formatTime(iso) {
  const date = new Date(iso);
  if (Number.isNaN(date.getTime())) return iso;
  return `${date.toISOString().slice(0, 16).replace('T', ' ')} UTC`;
}

/** The time at slider position `position` over the sorted `times` (ms), interpolated between steps. */
export function timeAt(times, position) {
  const i = Math.min(times.length - 1, Math.floor(position / SUBSTEPS));
  const u = position / SUBSTEPS - i;
  const t = i + 1 < times.length ? times[i] + (times[i + 1] - times[i]) * u : times[i];
  return new Date(t).toISOString().replace('.000Z', 'Z');
}

/** The slider position of `iso` over `times` (ms): the nearest sub-step. */
export function positionOf(times, iso) {
  const t = Date.parse(iso);
  if (Number.isNaN(t) || times.length < 2) return 0;
  for (let i = 0; i + 1 < times.length; i += 1) {
    if (t <= times[i + 1]) return Math.round((i + Math.max(0, (t - times[i]) / (times[i + 1] - times[i]))) * SUBSTEPS);
  }
  return (times.length - 1) * SUBSTEPS;
}

function element(tag, props = {}, ...children) {
  const node = Object.assign(document.createElement(tag), props);
  node.append(...children);
  return node;
}

/** The legend query of a mapping (colour map or hatch colour, range, reverse). */
export function legendQuery(mapping) {
  const query = new URLSearchParams();
  if (mapping?.target === 'hatch_color') {
    query.set('target', 'hatch_color');
    if (mapping.color) query.set('color', mapping.color.join(','));
  } else if (mapping?.colormap) query.set('colormap', mapping.colormap);
  if (mapping?.range) query.set('range', mapping.range.join(','));
  if (mapping?.reverse) query.set('reverse', 'true');
  return query.toString();
}

/**
 * The legend image URL of `layer` drawn with `mapping`; the layer's steps and value range are
 * part of it, so a new time step (a new range) is a new URL and never the browser's cached image.
 */
export function legendUrl(layer, mapping) {
  const query = legendQuery(mapping);
  const version = `v=${layer.steps.length}-${layer.min}-${layer.max}`;
  return `/api/layers/${encodeURIComponent(layer.id)}/legend.png?${query ? `${query}&` : ''}${version}`;
}

/**
 * The share (0…1) of the scene `extent` (`{min, max}`) a layer's `scene_extent`
 * (`[min_x, min_y, max_x, max_y]`) covers, and the covered part as `{min, max}` (null outside).
 */
export function coverage(sceneExtent, layerExtent) {
  if (!layerExtent) return { share: 1, part: sceneExtent };
  const min = [Math.max(sceneExtent.min[0], layerExtent[0]), Math.max(sceneExtent.min[1], layerExtent[1])];
  const max = [Math.min(sceneExtent.max[0], layerExtent[2]), Math.min(sceneExtent.max[1], layerExtent[3])];
  const area = (a, b) => Math.max(0, b[0] - a[0]) * Math.max(0, b[1] - a[1]);
  const inside = area(min, max);
  const share = inside / Math.max(1e-9, area(sceneExtent.min, sceneExtent.max));
  return { share, part: inside > 0 ? { min, max } : null };
}

/** Layers covering less than this share of the scene get a coverage note. */
const PARTIAL = 0.95;

export class DataPanel {
  /**
   * `options`: `targets` (mapping targets, empty when the server cannot map data),
   * `colormaps` (names), `timeSupported`, `extent` (the scene's), `onMappings(mappings)`,
   * `onTime(iso)`, `onDelete(layer)`, `onGoTo(part)` (show the covered part `{min, max}`).
   */
  constructor(options) {
    this.options = options;
    this.layers = [];
    this.mappings = [];
    this.time = null;
    this.playing = null;
    this.list = document.getElementById('layers');
    this.empty = document.getElementById('layers-empty');
    this.warnings = document.getElementById('mapping-warnings');
    this.slider = document.getElementById('time-slider');
    this.timeLabel = document.getElementById('time-label');
    this.play = document.getElementById('time-play');
    this.speed = document.getElementById('time-speed');
    this.slider.addEventListener('input', () => this.setPosition(Number(this.slider.value)));
    this.play.addEventListener('click', () => (this.playing ? this.pause() : this.start()));
  }

  /** Shows `layers` (the API's metadata) with the mappings `mappings` and time `time`. */
  show(layers, mappings, time) {
    this.layers = layers;
    const ids = new Set(layers.map((l) => l.id));
    this.mappings = mappings.filter((m) => ids.has(m.layer));
    this.time = time;
    this.list.replaceChildren(...layers.map((layer) => this.item(layer)));
    this.empty.hidden = layers.length > 0;
    this.updateTime();
  }

  mappingOf(id) {
    return this.mappings.find((m) => m.layer === id) ?? null;
  }

  item(layer) {
    const id = `layer-${layer.id}`;
    const mapping = this.mappingOf(layer.id);
    const li = element('li', { className: 'layer', id });
    li.dataset.layer = layer.id;
    const steps = layer.steps.filter((s) => s.time);
    const units = layer.units ? ` ${layer.units}` : '';
    const range = layer.kind === 'label'
      ? t('layer.classes', { n: layer.classes.length })
      : `${layer.min.toPrecision(4)}${units} … ${layer.max.toPrecision(4)}${units}`;
    const when = steps.length ? ` · ${t('layer.steps', { n: steps.length })}` : '';
    li.append(
      element('h3', { textContent: layer.name }),
      element('p', { className: 'summary', textContent: `${range}${when}` }),
      element('p', { className: 'meta planner-only', textContent: `${layer.kind} · ${layer.crs} · ${layer.source}` }),
    );
    if (this.options.extent) {
      const { share, part } = coverage(this.options.extent, layer.scene_extent);
      if (share < PARTIAL) {
        const note = element('p', {
          className: 'coverage',
          textContent: part ? t('layer.coverage', { pct: Math.max(1, Math.round(share * 100)) }) : t('layer.outside'),
        });
        li.append(note);
        if (part) {
          const go = element('button', { type: 'button', className: 'goto', textContent: t('layer.goto') });
          go.addEventListener('click', () => this.options.onGoTo(part));
          li.append(go);
        }
      }
    }
    if (this.options.targets.length) li.append(this.mappingControls(layer, mapping));
    const legend = element('img', {
      className: 'legend',
      alt: `${t('layer.legend', { name: layer.name })}${units ? ` (${layer.units})` : ''}`,
      src: legendUrl(layer, mapping),
      width: 320,
    });
    li.append(legend, element('p', { className: 'units', textContent: t('layer.units', { u: layer.units ?? t('layer.noUnits') }) }));
    const remove = element('button', { type: 'button', className: 'danger small planner-only', textContent: t('layer.delete') });
    remove.setAttribute('aria-label', `${t('layer.delete')} ${layer.name}`);
    remove.addEventListener('click', () => this.options.onDelete(layer));
    li.append(remove);
    return li;
  }

  mappingControls(layer, mapping) {
    const base = `map-${layer.id}`;
    const box = element('div', { className: 'mapping' });
    const target = element('select', { id: `${base}-target` });
    target.append(new Option(t('mapping.none'), ''));
    for (const name of this.options.targets) target.append(new Option(t(`mapping.${name}`), name));
    target.value = mapping?.target ?? '';
    const colormap = element('select', { id: `${base}-colormap` });
    colormap.append(new Option('default', ''));
    for (const c of this.options.colormaps) colormap.append(new Option(c, c));
    colormap.value = mapping?.colormap ?? '';
    const lo = element('input', { type: 'number', id: `${base}-min`, step: 'any', value: mapping?.range?.[0] ?? layer.min });
    const hi = element('input', { type: 'number', id: `${base}-max`, step: 'any', value: mapping?.range?.[1] ?? layer.max });
    const reverse = element('input', { type: 'checkbox', id: `${base}-reverse`, checked: Boolean(mapping?.reverse) });
    // The ink of a hatch colour (thesis Fig. 9.3): by default the first one no other layer uses.
    const used = this.mappings.filter((m) => m.layer !== layer.id && m.color).map((m) => hexOf(m.color));
    const ink = element('input', {
      type: 'color',
      id: `${base}-color`,
      value: mapping?.color ? hexOf(mapping.color) : HATCH_COLORS.find((c) => !used.includes(c)) ?? HATCH_COLORS[0],
    });
    const field = (label, control) => element('div', { className: 'field' }, element('label', { htmlFor: control.id, textContent: label }), control);
    const rangeRow = element('div', { className: 'row' },
      element('label', { htmlFor: lo.id, textContent: 'Range' }), lo,
      element('label', { htmlFor: hi.id, textContent: 'to' }), hi);
    const reverseRow = element('label', { className: 'check' }, reverse, 'Reverse');
    const colormapField = field('Colour map', colormap);
    const inkField = field('Hatch colour', ink);
    const showFields = () => {
      inkField.hidden = target.value !== 'hatch_color';
      colormapField.hidden = !inkField.hidden;
    };
    showFields();
    for (const node of [colormapField, inkField, rangeRow, reverseRow]) node.classList.add('planner-only');
    box.append(field(t('mapping.showAs'), target), colormapField, inkField, rangeRow, reverseRow);
    const changed = () => {
      showFields();
      const others = this.mappings.filter((m) => m.layer !== layer.id);
      if (target.value) {
        const m = { layer: layer.id, target: target.value };
        if (target.value === 'hatch_color') m.color = rgbOf(ink.value);
        else if (colormap.value) m.colormap = colormap.value;
        const ends = [Number(lo.value), Number(hi.value)];
        if (ends.every(Number.isFinite) && ends[0] !== ends[1] && (ends[0] !== layer.min || ends[1] !== layer.max)) m.range = ends;
        if (reverse.checked) m.reverse = true;
        others.push(m);
      }
      this.mappings = others;
      const img = box.parentElement?.querySelector('img.legend');
      if (img) img.src = legendUrl(layer, this.mappingOf(layer.id));
      this.updateTime();
      this.options.onMappings(this.mappings);
    };
    for (const control of [target, colormap, reverse, ink]) control.addEventListener('change', changed);
    for (const control of [lo, hi]) control.addEventListener('change', changed);
    return box;
  }

  /** Shows the server's warnings about the mappings (Table 9.1) and the time (clamped). */
  showWarnings(warnings) {
    this.warnings.replaceChildren(...warnings.map((text) => element('p', { className: 'warning', textContent: `⚠ ${text}` })));
  }

  /** The sorted time steps (ms) of the mapped layers. */
  times() {
    const mapped = new Set(this.mappings.map((m) => m.layer));
    const all = this.layers.filter((l) => mapped.has(l.id)).flatMap((l) => l.steps.map((s) => s.time).filter(Boolean));
    return [...new Set(all.map((t) => Date.parse(t)))].filter(Number.isFinite).sort((a, b) => a - b);
  }

  updateTime() {
    const times = this.times();
    const box = document.getElementById('time');
    box.hidden = times.length < 2 || !this.options.timeSupported;
    if (box.hidden) {
      this.pause();
      return;
    }
    this.slider.max = String((times.length - 1) * SUBSTEPS);
    const position = this.time ? positionOf(times, this.time) : 0;
    this.slider.value = String(position);
    this.timeLabel.textContent = formatTime(timeAt(times, position));
    this.slider.setAttribute('aria-valuetext', this.timeLabel.textContent);
  }

  /** Moves the time slider to `position` and reports the time. */
  setPosition(position) {
    const times = this.times();
    if (times.length < 2) return;
    this.slider.value = String(position);
    this.time = timeAt(times, position);
    this.timeLabel.textContent = formatTime(this.time);
    this.slider.setAttribute('aria-valuetext', this.timeLabel.textContent);
    this.options.onTime(this.time);
  }

  start() {
    this.play.textContent = 'Pause';
    this.play.setAttribute('aria-pressed', 'true');
    const tick = () => {
      const max = Number(this.slider.max);
      const next = Number(this.slider.value) + 1;
      this.setPosition(next > max ? 0 : next);
      this.playing = setTimeout(tick, 1000 / (Number(this.speed.value) * SUBSTEPS));
    };
    this.playing = setTimeout(tick, 0);
  }

  pause() {
    clearTimeout(this.playing);
    this.playing = null;
    this.play.textContent = 'Play';
    this.play.setAttribute('aria-pressed', 'false');
  }
}

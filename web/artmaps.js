// The "Art maps" panel (SPEC R11; README "Art maps over the API"): the renderer's tonal art
// maps (TAMs, the style's `hatch_map`) and silhouette art maps (SAMs, `silhouette_map`) with
// thumbnails; choosing one for the edited style; replacing or adding one from a PNG file;
// restoring a generated one; and painting strokes into one on a small canvas. Painted strokes
// go into the chosen tone level of a TAM and every darker level — the nesting of a TAM, darker
// levels holding the lighter levels' strokes (thesis 8.2.5, Praun et al.) — or into one
// stroke style (channel) of a SAM, and the edited map is sent as a PNG.

import { deleteArtMap, getBlob, getJSON, putArtMap } from './api.js';
import { decodePng, encodePng, Pixels } from './png.js';
import { t } from './i18n.js';

/** Per kind: its style field, its name in the panel and the label of choosing it (`web/i18n.js`). */
const KINDS = {
  tam: { field: 'hatch_map', name: 'TAM', use: 'art.useTam' },
  sam: { field: 'silhouette_map', name: 'SAM', use: 'art.useSam' },
};
/** A SAM's channels: one stroke style each (`art.sam0` … `art.sam3`). */
const SAM_CHANNELS = 4;
/** Pixels a keyboard step of the pen moves. */
const PEN_STEP = 8;

const $ = (id) => document.getElementById(id);

/** Shows `text` in a status line; `kind`: `busy`, `ok` or `error`. */
function status(node, kind, text) {
  node.dataset.kind = kind;
  node.textContent = text;
}

/** The message of a failed request, with the parameter the server named. */
function reason(error) {
  return `${error.message}${error.parameter ? ` (${error.parameter})` : ''}`;
}

/** `"tam:2"` → `['tam', 2]`. */
export function parseKey(key) {
  const [kind, index] = key.split(':');
  return [kind, Number(index)];
}

/**
 * Where pixel (x, y) of a painted `tile` (`{kind, width, height}`) is in the data of a map
 * `mapWidth` pixels wide: in a TAM (grey, tone levels side by side) the `layer`-th tone
 * image, in a SAM (RGBA) channel `layer`.
 */
export function tileOffset(tile, mapWidth, x, y, layer) {
  const { kind, width } = tile;
  return kind === 'tam' ? y * mapWidth + layer * width + x : (y * width + x) * 4 + layer;
}

/**
 * A map value with ink of `cover` (0…255) added: a TAM (`kind` `tam`) holds paper (255) and
 * gets paper × (1 − coverage), a SAM holds ink coverage and gets 1 − (1 − its own)(1 − coverage).
 */
export function inked(kind, value, cover) {
  const paper = kind === 'tam' ? value : 255 - value;
  const left = Math.round((paper * (255 - cover)) / 255);
  return kind === 'tam' ? left : 255 - left;
}

/**
 * The map `base` (`Pixels`: grey for a TAM, RGBA for a SAM) with strokes of ink coverage
 * `cover` (0…255 a pixel of `tile`, rows top to bottom) painted into a TAM's tone `layer` and
 * every darker level (a TAM's nesting), or into a SAM's channel `layer`. `base` is left as it is.
 */
export function paintStrokes(base, tile, layer, cover) {
  const { kind, width, height } = tile;
  const out = new Pixels(base.width, base.height, base.channels, base.data.slice());
  const layers = kind === 'tam' ? out.width / width : layer + 1;
  for (let l = layer; l < layers; l += 1) {
    for (let y = 0; y < height; y += 1) {
      for (let x = 0; x < width; x += 1) {
        const i = tileOffset(tile, out.width, x, y, l);
        out.data[i] = inked(kind, out.data[i], cover[y * width + x]);
      }
    }
  }
  return out;
}

/** Where strokes are painted: a coverage mask over one tone level of a TAM or one channel of a SAM. */
class Painter {
  constructor(canvas) {
    this.canvas = canvas;
    this.mask = document.createElement('canvas');
    this.ink = this.mask.getContext('2d', { willReadFrequently: true });
    this.base = null;
    this.tile = null;
    this.key = null;
    this.layer = 0;
    this.brush = 6;
    this.pen = null;
    this.strokes = 0;
    let last = null;
    const at = (e) => {
      const rect = canvas.getBoundingClientRect();
      return [(e.clientX - rect.left) * (canvas.width / rect.width), (e.clientY - rect.top) * (canvas.height / rect.height)];
    };
    canvas.addEventListener('pointerdown', (e) => {
      if (!this.base || e.button !== 0) return;
      canvas.setPointerCapture(e.pointerId);
      last = at(e);
      this.line(last, last);
    });
    canvas.addEventListener('pointermove', (e) => {
      if (!last) return;
      const point = at(e);
      this.line(last, point);
      last = point;
    });
    const end = () => {
      last = null;
    };
    canvas.addEventListener('pointerup', end);
    canvas.addEventListener('pointercancel', end);
    canvas.addEventListener('keydown', (e) => {
      const step = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] }[e.key];
      if (!this.base || !(step || e.key === 'Home')) return;
      e.preventDefault();
      const from = this.pen ?? [canvas.width / 2, canvas.height / 2];
      if (e.key === 'Home') {
        this.pen = [canvas.width / 2, canvas.height / 2];
        return;
      }
      const to = [
        Math.min(canvas.width, Math.max(0, from[0] + step[0] * PEN_STEP)),
        Math.min(canvas.height, Math.max(0, from[1] + step[1] * PEN_STEP)),
      ];
      this.line(from, to);
      this.pen = to;
    });
  }

  /** Starts painting on `base` (decoded `Pixels`) of map `key`; keeps the strokes when the map's shape stays. */
  load(key, base, tile) {
    const same = this.key === key && this.canvas.width === tile.width && this.canvas.height === tile.height;
    this.key = key;
    this.base = base.to(tile.kind === 'tam' ? 1 : 4);
    this.tile = tile;
    if (!same) {
      for (const c of [this.canvas, this.mask]) Object.assign(c, { width: tile.width, height: tile.height });
      this.clear();
    }
    this.draw();
  }

  /** Draws one stroke segment into the mask. */
  line(from, to) {
    const g = this.ink;
    Object.assign(g, { lineWidth: this.brush, lineCap: 'round', lineJoin: 'round', strokeStyle: '#000' });
    g.beginPath();
    g.moveTo(...from);
    g.lineTo(...to);
    g.stroke();
    this.strokes += 1;
    this.draw();
  }

  clear() {
    this.ink.clearRect(0, 0, this.mask.width, this.mask.height);
    this.strokes = 0;
    this.pen = null;
    this.draw();
  }

  /** Ink coverage of the strokes, 0…255 per pixel. */
  coverage() {
    const { width, height } = this.mask;
    const rgba = this.ink.getImageData(0, 0, width, height).data;
    const cover = new Uint8Array(width * height);
    for (let p = 0; p < cover.length; p += 1) cover[p] = rgba[p * 4 + 3];
    return cover;
  }

  /** Where pixel (x, y) of the painted tile is in the map's data (see `tileOffset`). */
  offset(x, y, layer = this.layer) {
    return tileOffset(this.tile, this.base.width, x, y, layer);
  }

  /** A map value with ink of `cover` (0…255) added (see `inked`). */
  inked(value, cover) {
    return inked(this.tile.kind, value, cover);
  }

  /** The map with the strokes (see `paintStrokes`). */
  result() {
    return paintStrokes(this.base, this.tile, this.layer, this.coverage());
  }

  /** Shows the painted tone level (or the SAM channel as ink on paper) with the strokes. */
  draw() {
    const g = this.canvas.getContext('2d');
    if (!this.base) {
      g.clearRect(0, 0, this.canvas.width, this.canvas.height);
      return;
    }
    const cover = this.coverage();
    const { kind, width, height } = this.tile;
    const image = g.createImageData(width, height);
    for (let y = 0; y < height; y += 1) {
      for (let x = 0; x < width; x += 1) {
        const value = this.inked(this.base.data[this.offset(x, y)], cover[y * width + x]);
        const v = kind === 'tam' ? value : 255 - value;
        const p = (y * width + x) * 4;
        image.data[p] = v;
        image.data[p + 1] = v;
        image.data[p + 2] = v;
        image.data[p + 3] = 255;
      }
    }
    g.putImageData(image, 0, 0);
  }
}

/** The panel. `chosen(field)` gives the edited style's value of a field, `onChoose(field, index)` sets it. */
export class ArtMapsPanel {
  constructor({ chosen, onChoose }) {
    this.chosen = chosen;
    this.onChoose = onChoose;
    this.list = null;
    this.version = 0;
    this.loading = 0;
    this.painter = new Painter($('art-canvas'));
    this.status = $('art-status');
    this.paintStatus = $('art-paint-status');
    const brush = $('art-brush');
    brush.addEventListener('input', () => {
      this.painter.brush = Number(brush.value);
      $('art-brush-value').textContent = t('art.px', { n: brush.value });
    });
    this.painter.brush = Number(brush.value);
    $('art-paint-map').addEventListener('change', () => this.loadPainter());
    for (const id of ['art-paint-level', 'art-paint-channel']) {
      $(id).addEventListener('change', (e) => {
        this.painter.layer = Number(e.target.value);
        this.painter.draw();
      });
    }
    $('art-clear').addEventListener('click', () => {
      this.painter.clear();
      status(this.paintStatus, 'ok', '');
    });
    $('art-apply').addEventListener('click', () => this.apply());
    $('art-upload').addEventListener('submit', (e) => {
      e.preventDefault();
      this.upload();
    });
  }

  /** Lists the maps again (after a change here or an `art_maps` message) and reloads the painted map. */
  async refresh() {
    const ticket = ++this.loading;
    let list;
    try {
      list = await getJSON('/api/artmaps');
    } catch (error) {
      status(this.status, 'error', t('art.listFailed', { reason: reason(error) }));
      return;
    }
    if (ticket !== this.loading) return;
    this.list = list;
    this.version += 1;
    for (const kind of Object.keys(KINDS)) this.showKind(kind, list[`${kind}s`]);
    const shape = list.tam_shape;
    $('art-shape').textContent = t('art.shape', {
      levels: shape.levels,
      size: shape.size,
      width: shape.width,
      height: shape.height,
      mib: Math.round(list.max_bytes / 2 ** 20),
    });
    this.fillTargets(list);
    this.showChosen();
    await this.loadPainter();
  }

  showKind(kind, maps) {
    const { field, name, use } = KINDS[kind];
    const ul = $(`art-${kind}s`);
    ul.replaceChildren();
    for (const map of maps) {
      const li = document.createElement('li');
      li.className = 'artmap';
      Object.assign(li.dataset, { kind, index: map.index, source: map.source });
      const label = `${name} ${map.index}`;
      const img = Object.assign(document.createElement('img'), {
        src: `${map.url}?v=${this.version}`,
        alt: kind === 'tam' ? t('art.altTam', { label, levels: map.levels }) : t('art.altSam', { label }),
        width: map.width,
        height: map.height,
      });
      const source = t(`art.source.${map.source}`);
      const meta = Object.assign(document.createElement('span'), { className: 'meta', textContent: `${label} · ${source}` });
      const row = document.createElement('div');
      row.className = 'row';
      const choose = Object.assign(document.createElement('button'), { type: 'button', className: 'small choose', textContent: t('art.use') });
      choose.setAttribute('aria-label', t(use, { label }));
      choose.addEventListener('click', () => {
        this.onChoose(field, map.index);
        this.showChosen();
      });
      const paint = Object.assign(document.createElement('button'), { type: 'button', className: 'small', textContent: t('art.paintButton') });
      paint.setAttribute('aria-label', t('art.paintLabel', { label }));
      paint.addEventListener('click', () => {
        $('art-paint-map').value = `${kind}:${map.index}`;
        this.loadPainter();
        $('art-canvas').focus();
      });
      row.append(meta, choose, paint);
      const last = map.index === maps.length - 1;
      if (map.has_default ? map.source === 'uploaded' : last) {
        const reset = Object.assign(document.createElement('button'), {
          type: 'button',
          className: 'small danger reset',
          textContent: t(map.has_default ? 'art.reset' : 'art.remove'),
        });
        reset.setAttribute('aria-label', t(map.has_default ? 'art.resetLabel' : 'art.removeLabel', { label }));
        reset.addEventListener('click', () => this.reset(kind, map, label));
        row.append(reset);
      }
      li.append(img, row);
      ul.append(li);
    }
    // A style naming a map that is gone (removed here or elsewhere) would be refused.
    if (this.chosen(field) >= maps.length) this.onChoose(field, 0);
  }

  /** Marks the maps the edited style uses. */
  showChosen() {
    for (const button of document.querySelectorAll('#pane-art .artmap .choose')) {
      const li = button.closest('.artmap');
      const on = this.chosen(KINDS[li.dataset.kind].field) === Number(li.dataset.index);
      button.setAttribute('aria-pressed', String(on));
      li.classList.toggle('chosen', on);
    }
  }

  /** The choices of the painter's map and the upload's target. */
  fillTargets(list) {
    const paintMap = $('art-paint-map');
    const target = $('art-upload-target');
    const painted = paintMap.value;
    const aimed = target.value;
    paintMap.replaceChildren();
    target.replaceChildren();
    for (const [kind, { name }] of Object.entries(KINDS)) {
      const maps = list[`${kind}s`];
      for (const map of maps) {
        paintMap.append(new Option(`${name} ${map.index}`, `${kind}:${map.index}`));
        target.append(new Option(t('art.replace', { label: `${name} ${map.index}` }), `${kind}:${map.index}`));
      }
      target.append(new Option(t('art.add', { label: `${name} ${maps.length}` }), `${kind}:${maps.length}`));
    }
    if ([...paintMap.options].some((o) => o.value === painted)) paintMap.value = painted;
    if ([...target.options].some((o) => o.value === aimed)) target.value = aimed;
    const levels = $('art-paint-level');
    const chosenLevel = levels.value;
    const last = list.tam_shape.levels - 1;
    levels.replaceChildren(...Array.from({ length: last + 1 }, (_, i) => {
      const key = i === 0 ? 'art.lightest' : i === last ? 'art.darkest' : null;
      return new Option(key ? t(key, { n: i + 1 }) : String(i + 1), String(i));
    }));
    if (chosenLevel) levels.value = chosenLevel;
    const channel = $('art-paint-channel');
    const chosenChannel = channel.value;
    channel.replaceChildren(...Array.from({ length: SAM_CHANNELS }, (_, i) => new Option(t(`art.sam${i}`), String(i))));
    if (chosenChannel) channel.value = chosenChannel;
  }

  /** Loads the map chosen for painting. */
  async loadPainter() {
    const key = $('art-paint-map').value;
    if (!key || !this.list) return;
    const [kind, index] = parseKey(key);
    const map = this.list[`${kind}s`][index];
    $('art-level-field').hidden = kind !== 'tam';
    $('art-channel-field').hidden = kind !== 'sam';
    const ticket = this.loading;
    try {
      const base = await decodePng(await (await getBlob(`${map.url}?v=${this.version}`)).arrayBuffer());
      if (ticket !== this.loading) return;
      const tile = kind === 'tam' ? { kind, width: map.height, height: map.height } : { kind, width: map.width, height: map.height };
      this.painter.layer = Number($(kind === 'tam' ? 'art-paint-level' : 'art-paint-channel').value);
      this.painter.load(key, base, tile);
      $('art-canvas').dataset.map = key;
      $('art-canvas').setAttribute('aria-label', t('art.canvasOn', { label: `${KINDS[kind].name} ${index}` }));
    } catch (error) {
      status(this.paintStatus, 'error', t('art.loadFailed', { label: `${KINDS[kind].name} ${index}`, reason: reason(error) }));
    }
  }

  /** Sends the painted map. */
  async apply() {
    const painter = this.painter;
    if (!painter.base) return;
    if (!painter.strokes) {
      status(this.paintStatus, 'error', t('art.nothing'));
      return;
    }
    const [kind, index] = parseKey(painter.key);
    const button = $('art-apply');
    button.disabled = true;
    status(this.paintStatus, 'busy', t('art.sending'));
    try {
      await putArtMap(kind, index, await encodePng(painter.result()));
      painter.clear();
      status(this.paintStatus, 'ok', t('art.updated', { label: `${KINDS[kind].name} ${index}` }));
      await this.refresh();
    } catch (error) {
      status(this.paintStatus, 'error', t('art.refused', { reason: reason(error) }));
    } finally {
      button.disabled = false;
    }
  }

  /** Uploads the chosen PNG file. */
  async upload() {
    const node = $('art-upload-status');
    const file = $('art-upload-file').files[0];
    if (!file) {
      status(node, 'error', t('art.chooseFile'));
      return;
    }
    const [kind, index] = parseKey($('art-upload-target').value);
    const submit = $('art-upload-submit');
    submit.disabled = true;
    status(node, 'busy', t('upload.busy'));
    try {
      const info = await putArtMap(kind, index, file);
      status(node, 'ok', t('art.stored', { label: `${KINDS[kind].name} ${info.index}` }));
      await this.refresh();
    } catch (error) {
      status(node, 'error', t('art.refused', { reason: reason(error) }));
    } finally {
      submit.disabled = false;
    }
  }

  /** Restores a generated map or removes an added one. */
  async reset(kind, map, label) {
    status(this.status, 'busy', t('art.resetting', { label }));
    try {
      await deleteArtMap(kind, map.index);
      status(this.status, 'ok', t(map.has_default ? 'art.resetDone' : 'art.removed', { label }));
      await this.refresh();
    } catch (error) {
      status(this.status, 'error', t('art.resetFailed', { label, reason: reason(error) }));
    }
  }
}

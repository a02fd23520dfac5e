// Style controls built from the server's style schema (`GET /api/scene` → `style_schema`:
// name, kind, default, min, max, doc per field): sliders for numbers, check boxes, selects for
// enumerations and art maps, colour pickers. The panel edits one style at a time — the view's
// (a preset and overrides) or one layer's (`layer_styles`: its own preset or fields over the
// view's style) — and `StyleModel` keeps those edits as the short overrides a link carries and
// shows the styles the server resolves from them (`POST /api/styles/resolve`).

import { t } from './i18n.js';
import { styleMessage } from './link.js';

/** Fields shown first, open: the style axes of issue #8 where the schema has them. */
const MAIN = [
  // with "Style of" set to a vegetation layer: show or hide that layer (existing / planned)
  'visible',
  'photorealism',
  'hlp_abstraction',
  'leaf_size',
  'leaf_shape',
  'contour_threshold',
  'contour_strength',
  'silhouette_map',
  'hatch_map',
  'hatch_brightness',
  'tone_contrast',
  'color',
  'color_saturation',
  'color_abstraction',
];

/** Group titles by the first word of a field name; other fields go to "More". */
const GROUPS = [
  ['contour', 'Contours'],
  ['isolated', 'Contours'],
  ['silhouette', 'Silhouettes'],
  ['hatch', 'Hatching'],
  ['image', 'Hatching'],
  ['tone', 'Tone and light'],
  ['ambient', 'Tone and light'],
  ['albedo', 'Tone and light'],
  ['normal', 'Tone and light'],
  ['gooch', 'Tone and light'],
  ['toon', 'Tone and light'],
  ['hlp', 'Abstraction'],
  ['leaf', 'Abstraction'],
  ['color', 'Colour'],
  ['sky', 'Paper, ink and sky'],
  ['ink', 'Paper, ink and sky'],
  ['paper', 'Paper, ink and sky'],
];

/** Ranges wider than this are mapped to their slider with a cubic curve (fine steps near the low end). */
const WIDE_RANGE = 50;
/** Integer ranges up to this many values get a slider, wider ones a number box. */
const SLIDER_INTEGERS = 32;
const SLIDER_STEPS = 400;

function groupOf(name) {
  if (MAIN.includes(name)) return 'Main';
  const first = name.split('_')[0];
  return GROUPS.find(([prefix]) => prefix === first)?.[1] ?? 'More';
}

/** A field's label: its plain words where `web/i18n.js` has them (`style.f.<name>`), else `snake_case` → "Snake case". */
export function labelOf(name) {
  const key = `style.f.${name}`;
  const plain = t(key);
  if (plain !== key) return plain;
  const words = name.replaceAll('_', ' ');
  return words[0].toUpperCase() + words.slice(1);
}

/** The values an enumeration's doc names in backticks (`hybrid` … `image`). */
function enumValues(field) {
  const values = [...field.doc.matchAll(/`([a-z0-9_]+)`/g)].map((m) => m[1]);
  if (!values.includes(field.default)) values.unshift(field.default);
  return [...new Set(values)];
}

/** sRGB 0…1 triple ↔ `#rrggbb`. */
export function toHex(rgb) {
  return `#${rgb.map((c) => Math.round(Math.min(1, Math.max(0, c)) * 255).toString(16).padStart(2, '0')).join('')}`;
}
export function fromHex(hex) {
  return [1, 3, 5].map((i) => Number((parseInt(hex.slice(i, i + 2), 16) / 255).toFixed(4)));
}

/** Slider position ↔ value; wide ranges use a cubic curve so that small values can be set. */
function scaleOf(field) {
  const { min, max } = field;
  if (field.kind === 'integer' || max - min <= WIDE_RANGE) {
    const step = field.kind === 'integer' ? 1 : (max - min) / SLIDER_STEPS;
    return { min, max, step, toSlider: (v) => v, fromSlider: (t) => t };
  }
  return {
    min: 0,
    max: 1,
    step: 1 / SLIDER_STEPS,
    toSlider: (v) => Math.cbrt((v - min) / (max - min)),
    fromSlider: (t) => min + (max - min) * t ** 3,
  };
}

/** Rounds a slider value to a short decimal: 3 significant digits, at least 2 decimals below 1. */
function tidy(value) {
  return Number(value.toPrecision(3));
}

export class StylePanel {
  /** `schema`: the style fields; `onChange(name, value)` on every edit. */
  constructor(container, schema, onChange) {
    this.container = container;
    this.controls = new Map();
    this.rows = new Map();
    this.onChange = onChange;
    const groups = new Map();
    for (const field of schema) {
      const group = groupOf(field.name);
      if (!groups.has(group)) groups.set(group, []);
      groups.get(group).push(field);
    }
    const order = ['Main', ...new Set(GROUPS.map(([, title]) => title)), 'More'];
    const advanced = document.createElement('details');
    advanced.className = 'group advanced';
    const advancedTitle = document.createElement('summary');
    advancedTitle.textContent = t('style.advanced');
    advanced.append(advancedTitle);
    for (const title of order) {
      const fields = groups.get(title);
      if (!fields) continue;
      const details = document.createElement('details');
      details.className = 'group';
      details.open = title === 'Main';
      const summary = document.createElement('summary');
      summary.textContent = title === 'Main' ? t('style.main') : title;
      details.append(summary);
      if (title === 'Main') fields.sort((a, b) => MAIN.indexOf(a.name) - MAIN.indexOf(b.name));
      for (const field of fields) details.append(this.control(field));
      if (title === 'Main') container.append(details);
      else advanced.append(details);
    }
    container.append(advanced);
  }

  /** The row of field `name` (to show or hide it). */
  rowOf(name) {
    return this.rows.get(name) ?? null;
  }

  /** One labelled control for `field`. */
  control(field) {
    const id = `style-${field.name}`;
    const row = document.createElement('div');
    row.className = 'field';
    this.rows.set(field.name, row);
    // The field's help, visible (touch screens show no tooltips).
    const help = document.createElement('p');
    help.className = 'doc';
    help.id = `${id}-doc`;
    help.textContent = field.doc;
    const label = document.createElement('label');
    label.htmlFor = id;
    label.textContent = labelOf(field.name);
    const box = document.createElement('div');
    box.className = 'control';
    const emit = (value) => this.onChange(field.name, value);
    let set;
    if (field.kind === 'boolean') {
      const input = Object.assign(document.createElement('input'), { type: 'checkbox', id });
      input.addEventListener('change', () => emit(input.checked));
      set = (v) => {
        input.checked = Boolean(v);
      };
      row.classList.replace('field', 'check');
      input.setAttribute('aria-describedby', help.id);
      row.append(input, label, help);
      this.controls.set(field.name, set);
      return row;
    }
    if (field.kind === 'color') {
      const input = Object.assign(document.createElement('input'), { type: 'color', id });
      input.addEventListener('input', () => emit(fromHex(input.value)));
      set = (v) => {
        input.value = toHex(v);
      };
      box.append(input);
    } else if (field.kind === 'string') {
      const select = Object.assign(document.createElement('select'), { id });
      for (const value of enumValues(field)) select.append(new Option(value, value));
      select.addEventListener('change', () => emit(select.value));
      set = (v) => {
        select.value = String(v);
      };
      box.append(select);
    } else if (field.min != null && field.max != null
      && (field.kind === 'number' || field.max - field.min <= SLIDER_INTEGERS)) {
      const scale = scaleOf(field);
      const slider = Object.assign(document.createElement('input'), {
        type: 'range', id, min: scale.min, max: scale.max, step: scale.step,
      });
      const number = Object.assign(document.createElement('input'), {
        type: 'number', min: field.min, max: field.max, step: field.kind === 'integer' ? 1 : 'any',
      });
      number.setAttribute('aria-label', `${labelOf(field.name)} value`);
      slider.addEventListener('input', () => {
        const raw = scale.fromSlider(Number(slider.value));
        const value = field.kind === 'integer' ? Math.round(raw) : tidy(raw);
        number.value = value;
        emit(value);
      });
      number.addEventListener('change', () => {
        const value = Math.min(field.max, Math.max(field.min, Number(number.value)));
        if (!Number.isFinite(value)) return;
        slider.value = scale.toSlider(value);
        emit(field.kind === 'integer' ? Math.round(value) : value);
      });
      set = (v) => {
        slider.value = scale.toSlider(v);
        number.value = v;
      };
      box.append(slider, number);
    } else {
      const number = Object.assign(document.createElement('input'), {
        type: 'number', id, step: field.kind === 'integer' ? 1 : 'any',
      });
      if (field.min != null) number.min = field.min;
      if (field.max != null) number.max = field.max;
      number.addEventListener('change', () => {
        if (number.value !== '' && Number.isFinite(Number(number.value))) emit(Number(number.value));
      });
      set = (v) => {
        number.value = v;
      };
      box.append(number);
    }
    this.controls.set(field.name, set);
    box.querySelector('input, select')?.setAttribute('aria-describedby', help.id);
    row.append(label, box, help);
    return row;
  }

  /** Shows `style` (every field's value) in the controls. */
  show(style) {
    for (const [name, set] of this.controls) if (name in style) set(style[name]);
  }
}

/**
 * The styles of a view: the edits (`view.preset`, `view.style`, `view.layerStyles`) and what the
 * server resolved from them — for the view and each layer its complete `style` and the `base`
 * its own fields merge over. The server owns the merge rules; the model only asks. `target` is
 * `''` for the view's style or a layer name.
 */
export class StyleModel {
  /** `resolve(styles)`: the server's resolution of `{preset, style, layer_styles}`. */
  constructor(resolve) {
    this.resolve = resolve;
    this.resolved = null;
    /** Edits so far, and the newest `refresh`: answers older than either are not shown. */
    this.edits = 0;
    this.asked = 0;
  }

  /** The preset of `target` in `view` (`''` for none). */
  presetOf(view, target) {
    return (target ? view.layerStyles[target]?.preset : view.preset) ?? '';
  }

  /** What the server resolved for `target` (`{base, style}`), `null` before its first answer. */
  resolvedOf(target) {
    return (target ? this.resolved?.layers[target] : this.resolved?.view) ?? null;
  }

  /** Every field's value for `target` as last resolved (nothing before the first answer). */
  styleOf(target) {
    return this.resolvedOf(target)?.style ?? {};
  }

  /**
   * Asks the server for the styles of `view` until an answer covers the latest edits; true
   * when it is shown, false when a newer `refresh` took over.
   */
  async refresh(view) {
    const ticket = ++this.asked;
    for (;;) {
      const edits = this.edits;
      const { type, replace, ...styles } = styleMessage(view);
      const resolved = await this.resolve(styles);
      if (ticket !== this.asked) return false;
      if (edits === this.edits) {
        this.resolved = resolved;
        return true;
      }
    }
  }

  /**
   * Sets one field of `target`; a value equal to what its fields merge over is dropped from the
   * overrides. The field shows the value at once.
   */
  set(view, target, name, value) {
    this.edits += 1;
    const shown = this.resolvedOf(target);
    const same = shown != null && JSON.stringify(value) === JSON.stringify(shown.base[name]);
    if (shown) shown.style[name] = value;
    if (!target) {
      if (same) delete view.style[name];
      else view.style[name] = value;
      return;
    }
    const layer = { ...(view.layerStyles[target] ?? {}) };
    if (same) delete layer[name];
    else layer[name] = value;
    this.store(view, target, layer);
  }

  /** Chooses the preset of `target` (`''`: none); its own fields start afresh. */
  setPreset(view, target, preset) {
    this.edits += 1;
    if (!target) {
      view.preset = preset;
      view.style = {};
    } else {
      this.store(view, target, preset ? { preset } : {});
    }
  }

  /** Drops the preset and fields of the view and of every layer. */
  resetAll(view) {
    this.edits += 1;
    view.preset = '';
    view.style = {};
    view.layerStyles = {};
  }

  store(view, target, layer) {
    const styles = { ...view.layerStyles };
    if (Object.keys(layer).length) styles[target] = layer;
    else delete styles[target];
    view.layerStyles = styles;
  }
}

// Unit tests of the orientation aids' geometry (web/orientation.js) and the UI's strings (web/i18n.js).
import assert from 'node:assert/strict';
import test from 'node:test';
import { STRINGS, initialLanguage, t } from '../../web/i18n.js';
import { fromMap, horizontalFov, niceLength, overview, toMap } from '../../web/orientation.js';

test('the mini map maps scene metres to pixels north up and back', () => {
  const map = overview({ min: [-1000, -500], max: [1000, 1500] });
  assert.deepEqual(map, { center: [0, 500], width: 2000 });
  assert.deepEqual(toMap(map, 160, [0, 500]), [80, 80]);
  assert.deepEqual(toMap(map, 160, [-1000, 1500]), [0, 0], 'north-west corner top left');
  assert.deepEqual(toMap(map, 160, [1000, -500]), [160, 160], 'south-east corner bottom right');
  for (const p of [[123, -45], [-999, 1499], [0, 0]]) {
    const back = fromMap(map, 160, toMap(map, 160, p));
    assert.ok(Math.abs(back[0] - p[0]) < 1e-9 && Math.abs(back[1] - p[1]) < 1e-9, `${p} → ${back}`);
  }
});

test('the horizontal field of view widens with the aspect ratio', () => {
  assert.ok(Math.abs(horizontalFov(60, 1) - 60) < 1e-9);
  assert.ok(Math.abs(horizontalFov(90, 2) - 2 * Math.atan(2) * (180 / Math.PI)) < 1e-9);
});

test('scale bars have round lengths no longer than asked', () => {
  assert.equal(niceLength(0.5), null);
  assert.equal(niceLength(1), 1);
  assert.equal(niceLength(7), 5);
  assert.equal(niceLength(240), 200);
  assert.equal(niceLength(1999), 1000);
});

test('every language has the keys it uses in English, with the same placeholders', () => {
  for (const [code, strings] of Object.entries(STRINGS)) {
    for (const [key, text] of Object.entries(strings)) {
      assert.ok(key in STRINGS.en, `${code}: ${key} is not an English key`);
      const names = (s) => [...s.matchAll(/\{(\w+)\}/g)].map((m) => m[1]).sort();
      assert.deepEqual(names(text), names(STRINGS.en[key]), `${code}: ${key} placeholders`);
    }
  }
  assert.equal(t('shot.saved', { w: 640, h: 480 }), 'Picture 640 × 480 pixels saved.');
  assert.equal(t('no.such.key'), 'no.such.key');
});

test('the language is the stored one, else the browser\'s if offered, else English', () => {
  assert.equal(initialLanguage('de', ['en-US']), 'de');
  assert.equal(initialLanguage(null, ['de-CH', 'en']), 'de');
  assert.equal(initialLanguage('xx', ['fr-FR']), 'en');
});

test('a report picture says what it shows: caption with or without the plan, eye height or width', async () => {
  const { reportText } = await import('../../web/report.js');
  const words = { caption: 'Place — view to the west', planCaption: 'Place — seen from above', plan: 'without the plan', width: 'Picture 900 m across', eye: 'Eye 1.7 m above the ground', credit: 'Drawn with landsketch' };
  assert.deepEqual(reportText({ plan: null }, words), { caption: 'Place — view to the west (without the plan)', note: 'Eye 1.7 m above the ground', credit: 'Drawn with landsketch' });
  assert.deepEqual(reportText({ plan: { width: 900 } }, { ...words, plan: null }), { caption: 'Place — seen from above', note: 'Picture 900 m across', credit: 'Drawn with landsketch' });
});

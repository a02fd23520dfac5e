// Unit tests of web/api.js: the server's JSON error bodies as `ApiError`s.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ApiError, errorOf, waitUntilReady } from '../../web/api.js';

test('errorOf reads the JSON error body', async () => {
  const body = { error: { code: 'invalid_parameter', message: 'yaw must be a number', parameter: 'yaw' } };
  const error = await errorOf(new Response(JSON.stringify(body), { status: 400, statusText: 'Bad Request' }));
  assert.ok(error instanceof ApiError && error instanceof Error);
  assert.deepEqual([error.name, error.status, error.code, error.message, error.parameter], ['ApiError', 400, 'invalid_parameter', 'yaw must be a number', 'yaw']);
});

test('errorOf without a parameter, and for bodies that are not the server\'s', async () => {
  const busy = await errorOf(new Response('{"error": {"code": "busy", "message": "the render queue is full"}}', { status: 503 }));
  assert.deepEqual([busy.status, busy.code, busy.parameter], [503, 'busy', null]);
  const proxy = await errorOf(new Response('<html>Bad gateway</html>', { status: 502, statusText: 'Bad Gateway' }));
  assert.deepEqual([proxy.status, proxy.code, proxy.message, proxy.parameter], [502, 'http', '502 Bad Gateway', null]);
  const bare = await errorOf(new Response('{}', { status: 500 }));
  assert.deepEqual([bare.code, bare.message], ['http', '500']);
});

test('waitUntilReady reports the loading stages until the scene is ready', async () => {
  const answers = [
    { status: 503, body: { status: 'loading' } },
    { status: 503, body: { status: 'loading', stage: 'placement', stage_label: 'placing the plants', percent: 35 } },
    { status: 503, body: { status: 'loading', stage: 'preprocessing', stage_label: 'preparing the plants for drawing', percent: 80 } },
    { status: 200, body: { status: 'ok', scene: 'valley' } },
  ];
  const fetchImpl = async (path) => {
    assert.equal(path, '/api/health');
    const { status, body } = answers.shift();
    return new Response(JSON.stringify(body), { status });
  };
  const seen = [];
  const health = await waitUntilReady((h) => seen.push(h.stage ?? null), { fetchImpl, wait: async () => {} });
  assert.equal(health.scene, 'valley');
  assert.deepEqual(seen, [null, 'placement', 'preprocessing']);
  // A server that answers neither `ok` nor `loading` (a proxy's error page) is an error.
  const broken = async () => new Response('<html>Bad gateway</html>', { status: 502, statusText: 'Bad Gateway' });
  await assert.rejects(waitUntilReady(() => {}, { fetchImpl: broken, wait: async () => {} }), /502 Bad Gateway/);
});

// Unit tests of web/api.js: the server's JSON error bodies as `ApiError`s.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ApiError, errorOf } from '../../web/api.js';

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

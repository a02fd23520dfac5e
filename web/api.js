// REST helpers: JSON requests and the server's error bodies
// (`{"error": {"code", "message", "parameter"}}`, README "Server" → "Errors").

/** An error answered by the server, with its code, message and the parameter it names. */
export class ApiError extends Error {
  constructor(status, code, message, parameter) {
    super(message);
    this.name = 'ApiError';
    this.status = status;
    this.code = code;
    this.parameter = parameter ?? null;
  }
}

/** Reads the error of a failed response: the JSON error body, or the status text. */
export async function errorOf(response) {
  let detail = null;
  try {
    detail = (await response.json()).error;
  } catch {
    // Not JSON (a proxy's error page): fall back to the status line.
  }
  const message = detail?.message ?? `${response.status} ${response.statusText}`.trim();
  return new ApiError(response.status, detail?.code ?? 'http', message, detail?.parameter);
}

/** The planner's admin token (null for a citizen), sent with every write. */
let adminToken = null;

/** Sets the admin token the writes send (`null`: none). */
export function setAdminToken(token) {
  adminToken = token || null;
}

/** `init` with the planner's `Authorization` header when a token is set. */
function authorized(init = {}) {
  if (!adminToken) return init;
  return { ...init, headers: { ...(init.headers ?? {}), Authorization: `Bearer ${adminToken}` } };
}

/** Asks the server whether `token` admits writes (`GET /api/auth`): its answer, or an `ApiError` (401/403). */
export async function checkAuth(token) {
  const headers = token ? { Authorization: `Bearer ${token}` } : {};
  return getJSON('/api/auth', { headers });
}

/** Fetches `path`; throws an `ApiError` for an error status. */
async function request(path, init) {
  const response = await fetch(path, init);
  if (!response.ok) throw await errorOf(response);
  return response;
}

/** Fetches `path` and returns its JSON; throws an `ApiError` for an error status. */
export async function getJSON(path, init) {
  return (await request(path, init)).json();
}

/**
 * Waits until the server has loaded its scene (`GET /api/health` says `ok`), calling
 * `onLoading(health)` with each answer while it loads (`stage`, `percent`); `wait(ms)` sleeps
 * between polls. Rejects when the server answers neither `ok` nor `loading`.
 */
export async function waitUntilReady(onLoading, { fetchImpl = fetch, wait = (ms) => new Promise((r) => setTimeout(r, ms)), intervalMs = 500 } = {}) {
  for (;;) {
    const response = await fetchImpl('/api/health');
    const health = await response.clone().json().catch(() => ({}));
    if (health.status === 'ok') return health;
    if (health.status !== 'loading') throw await errorOf(response);
    onLoading(health);
    await wait(intervalMs);
  }
}

/** Every comment, hidden and pending ones too (the planner's moderation list). */
export async function allComments() {
  return (await getJSON('/api/comments?status=all', authorized())).comments ?? [];
}

/** Moderates comment `id`: `approve` (visible), `hide`, or `delete` (gone for good). */
export async function moderateComment(id, action) {
  const init = action === 'delete' ? { method: 'DELETE' } : { method: 'POST' };
  await request(action === 'delete' ? `/api/comments/${id}` : `/api/comments/${id}/${action}`, authorized(init));
}

/** Stores the planner's viewpoint `name` (created or replaced) with `body`. */
export async function saveViewpoint(name, body) {
  const init = { method: 'PUT', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) };
  await request(`/api/viewpoints/${encodeURIComponent(name)}`, authorized(init));
}

/** Removes the planner's viewpoint `name` (one of the admin API's). */
export async function deleteViewpoint(name) {
  await request(`/api/viewpoints/${encodeURIComponent(name)}`, authorized({ method: 'DELETE' }));
}

/** Fetches `path` and returns the response as a Blob; throws an `ApiError` for an error status. */
export async function getBlob(path) {
  return (await request(path)).blob();
}

/** Uploads a data layer as a multipart form (`POST /api/layers`); returns the layer's metadata. */
export async function uploadLayer(form) {
  return getJSON('/api/layers', authorized({ method: 'POST', body: form }));
}

/** Deletes a data layer (`DELETE /api/layers/{id}`). */
export async function deleteLayer(id) {
  await request(`/api/layers/${encodeURIComponent(id)}`, authorized({ method: 'DELETE' }));
}

/** Replaces art map `index` of `kind` (`tam`/`sam`), or adds one at the count, from a PNG (`PUT /api/artmaps/{kind}/{index}`). */
export async function putArtMap(kind, index, png) {
  return getJSON(`/api/artmaps/${kind}/${index}`, authorized({ method: 'PUT', headers: { 'Content-Type': 'image/png' }, body: png }));
}

/** Restores a generated art map or removes the last added one (`DELETE /api/artmaps/{kind}/{index}`). */
export async function deleteArtMap(kind, index) {
  await request(`/api/artmaps/${kind}/${index}`, authorized({ method: 'DELETE' }));
}

/**
 * The styles of a view as the server resolves them (`POST /api/styles/resolve`): `styles` is
 * `{preset, style, layer_styles}`; the answer has, for the view and each layer, its complete
 * `style` and the `base` its own fields merge over.
 */
export async function resolveStyles(styles) {
  return getJSON('/api/styles/resolve', {
    method: 'POST',
    headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify(styles),
  });
}

// The planner's viewpoints (`GET /api/viewpoints`: the scene file's `[[viewpoints]]` and those
// added over the admin API) as places a citizen jumps to.

/**
 * The view fields (`x`, `y`, `z`, `eyeHeight`, `yaw`, `pitch`, `fov`, `plan`) of a viewpoint's
 * camera (the render body's `camera`); fields it leaves out keep those of `base`.
 */
export function viewpointCamera(camera, base) {
  if (camera.mode === 'plan') {
    const [x, y] = camera.center ?? [base.x, base.y];
    return { x, y, plan: { width: camera.width ?? base.planWidth }, yaw: 0, pitch: base.pitch, fov: base.fov };
  }
  const [x, y, z] = camera.position ?? [base.x, base.y];
  return {
    x,
    y,
    z: z ?? null,
    eyeHeight: camera.eye_height ?? base.eyeHeight,
    yaw: camera.yaw ?? base.yaw,
    pitch: camera.pitch ?? base.pitch,
    fov: camera.fov ?? base.fov,
    plan: null,
  };
}

/**
 * The body of `PUT /api/viewpoints/{name}` for the view `view` (the page's view fields) with
 * `caption`: its camera (`cameraMessage` of `link.js`, passed in as `camera`), and its look and
 * data layers when it has any.
 */
export function viewpointBody(view, camera, caption) {
  const { type, ...params } = camera;
  const body = { caption, camera: params };
  if (view.preset) body.preset = view.preset;
  if (Object.keys(view.style ?? {}).length) body.style = view.style;
  if (Object.keys(view.layerStyles ?? {}).length) body.layer_styles = view.layerStyles;
  if (view.mappings?.length) {
    body.mappings = view.mappings;
    if (view.time) body.time = view.time;
  }
  return body;
}

/**
 * Fills `list` with a button per viewpoint; `go(viewpoint)` is called on a click. With
 * `remove` (planner mode) the viewpoints of the admin API get a remove button calling
 * `remove(viewpoint)`, labelled by `removeLabel(viewpoint)`.
 */
export function showViewpoints(list, viewpoints, go, remove = null, removeLabel = null) {
  list.replaceChildren(
    ...viewpoints.map((viewpoint) => {
      const button = document.createElement('button');
      button.type = 'button';
      button.className = 'viewpoint';
      button.textContent = viewpoint.name;
      if (viewpoint.caption) button.title = viewpoint.caption;
      button.addEventListener('click', () => go(viewpoint));
      if (!remove || viewpoint.source !== 'admin') return button;
      const drop = document.createElement('button');
      drop.type = 'button';
      drop.className = 'small danger remove-viewpoint';
      drop.textContent = '×';
      drop.setAttribute('aria-label', removeLabel(viewpoint));
      drop.addEventListener('click', () => remove(viewpoint));
      const item = document.createElement('span');
      item.className = 'viewpoint-item';
      item.append(button, drop);
      return item;
    }),
  );
}

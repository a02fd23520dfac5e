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

/** Fills `list` with a button per viewpoint; `go(viewpoint)` is called on a click. */
export function showViewpoints(list, viewpoints, go) {
  list.replaceChildren(
    ...viewpoints.map((viewpoint) => {
      const button = document.createElement('button');
      button.type = 'button';
      button.className = 'viewpoint';
      button.textContent = viewpoint.name;
      if (viewpoint.caption) button.title = viewpoint.caption;
      button.addEventListener('click', () => go(viewpoint));
      return button;
    }),
  );
}

// The upload form: sends a data layer as `multipart/form-data` to `POST /api/layers` and shows
// the server's answer inline — its validation message when the upload is refused.

import { uploadLayer } from './api.js';
import { t } from './i18n.js';

/** Text fields sent only when filled in. */
const OPTIONAL = ['time', 'crs', 'units'];

/** Wires the upload form; `onUploaded(meta)` after a layer was stored. */
export function setupUpload(onUploaded) {
  const form = document.getElementById('upload');
  const status = document.getElementById('upload-status');
  const submit = document.getElementById('upload-submit');
  const fileInput = document.getElementById('upload-file');
  const nameInput = document.getElementById('upload-name');
  fileInput.addEventListener('change', () => {
    const file = fileInput.files[0];
    if (file && !nameInput.value) nameInput.value = file.name.replace(/\.[^.]+$/, '');
  });
  const say = (kind, text) => {
    status.dataset.kind = kind;
    status.textContent = text;
  };
  form.addEventListener('submit', async (event) => {
    event.preventDefault();
    const body = new FormData();
    body.set('name', nameInput.value.trim());
    body.set('kind', form.elements.kind.value);
    for (const name of OPTIONAL) {
      const value = form.elements[name].value.trim();
      if (value) body.set(name, value);
    }
    const file = fileInput.files[0];
    if (file) body.set('file', file, file.name);
    submit.disabled = true;
    say('busy', t('upload.busy'));
    try {
      const meta = await uploadLayer(body);
      say('ok', t(meta.steps.length === 1 ? 'upload.storedOne' : 'upload.stored', { name: meta.name, n: meta.steps.length }));
      onUploaded(meta);
    } catch (error) {
      const where = error.parameter ? ` (${error.parameter})` : '';
      say('error', t('upload.refused', { where, reason: error.message }));
    } finally {
      submit.disabled = false;
    }
  });
}

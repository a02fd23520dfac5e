// Comments pinned in the landscape (guide, "Participation"): a citizen points at a place in
// the view and says what they think of it; the server finds the point from the frame's depth,
// stores the comment and draws it as a numbered pin. Likes and reports take an anonymous
// author token the browser keeps (no personal data).

import { allComments, errorOf, moderateComment } from './api.js';

const AUTHOR_KEY = 'landsketch-author';

/** The browser's anonymous author token (random, kept in `localStorage`). */
export function authorToken(storage = window.localStorage, random = () => crypto.randomUUID()) {
  let token = storage.getItem(AUTHOR_KEY);
  if (!token || !/^[A-Za-z0-9_-]{16,128}$/.test(token)) {
    token = random();
    storage.setItem(AUTHOR_KEY, token);
  }
  return token;
}

/**
 * The pixel `[column, row]` of the frame under a pointer at `clientX`, `clientY`: the canvas
 * is stretched over its box, so its pixels scale with the box.
 */
export function framePixel(rect, frameWidth, frameHeight, clientX, clientY) {
  const x = Math.floor(((clientX - rect.left) / rect.width) * frameWidth);
  const y = Math.floor(((clientY - rect.top) / rect.height) * frameHeight);
  return [Math.min(frameWidth - 1, Math.max(0, x)), Math.min(frameHeight - 1, Math.max(0, y))];
}

/**
 * The view a comment was made in, as `POST /api/comments` takes it: the camera of the frame
 * shown (`camera` from the frame message) or the plan view, the frame's size and the styles
 * that decide what is drawn (a hidden plan is not pointed at).
 */
export function commentView(view, camera, width, height) {
  const cam = view.plan
    ? { mode: 'plan', center: [view.x, view.y], width: view.plan.width, yaw: 0 }
    : { position: camera.position, yaw: camera.yaw, pitch: camera.pitch, fov: camera.fov, roll: view.roll ?? 0 };
  const body = { camera: cam, width, height };
  if (view.preset) body.preset = view.preset;
  if (Object.keys(view.style).length) body.style = view.style;
  if (Object.keys(view.layerStyles).length) body.layer_styles = view.layerStyles;
  return body;
}

async function postJSON(path, body) {
  const response = await fetch(path, {
    method: 'POST',
    headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify(body),
  });
  if (!response.ok) throw await errorOf(response);
  return response.json();
}

/**
 * The Comments pane: add a comment at a place in the view, show the pins, read, like and
 * report; in planner mode (`app.mode`) every comment with its status and approve, hide and
 * delete. `app` gives the view, the frame camera and the WebSocket connection; `t` the words.
 */
export class CommentsPanel {
  constructor({ $, t, app }) {
    this.$ = $;
    this.t = t;
    this.app = app;
    this.author = authorToken();
    this.placing = false;
    this.pixel = null;
    this.shown = false;
    this.categories = [];
    $('comment-add').addEventListener('click', () => this.startPlacing());
    $('comment-cancel').addEventListener('click', () => this.closeForm());
    $('comment-form').addEventListener('submit', (e) => {
      e.preventDefault();
      this.send();
    });
    $('comments-show').addEventListener('click', () => this.show(!this.shown));
    $('viewer').addEventListener('click', (e) => this.pointed(e));
    app.connection.addEventListener('changed', (e) => {
      if (e.detail.what === 'comments') this.refresh();
    });
    // A reconnected session starts without pins: ask again.
    app.connection.addEventListener('hello', () => {
      if (this.shown) app.connection.send({ type: 'comments', show: true });
    });
  }

  /** Loads the categories and the comments. */
  async load() {
    try {
      const response = await fetch('/api/participation');
      if (response.ok) this.categories = (await response.json()).categories ?? [];
    } catch {
      this.categories = [];
    }
    const select = this.$('comment-category');
    select.replaceChildren(new Option(this.t('comments.noCategory'), ''));
    for (const name of this.categories) select.add(new Option(this.categoryLabel(name), name));
    await this.refresh();
  }

  categoryLabel(name) {
    const key = `comments.category.${name}`;
    const label = this.t(key);
    return label === key ? name : label;
  }

  say(text) {
    this.$('comment-message').textContent = text;
  }

  startPlacing() {
    this.placing = true;
    this.$('viewer').classList.add('placing');
    this.say(this.t('comments.pointAt'));
    this.$('viewer').focus();
  }

  pointed(event) {
    if (!this.placing) return;
    const canvas = this.$('frame');
    this.pixel = framePixel(canvas.getBoundingClientRect(), canvas.width, canvas.height, event.clientX, event.clientY);
    this.placing = false;
    this.$('viewer').classList.remove('placing');
    this.$('comment-form').hidden = false;
    this.say(this.t('comments.write'));
    this.$('comment-text').focus();
  }

  closeForm() {
    this.placing = false;
    this.pixel = null;
    this.$('viewer').classList.remove('placing');
    this.$('comment-form').hidden = true;
    this.$('comment-text').value = '';
    this.say('');
    this.$('viewer').focus();
  }

  async send() {
    const canvas = this.$('frame');
    const camera = this.app.frameCamera;
    if (!this.pixel || (!camera && !this.app.view.plan)) return;
    const body = {
      view: commentView(this.app.view, camera, canvas.width, canvas.height),
      pixel: this.pixel,
      text: this.$('comment-text').value,
      author: this.author,
    };
    const category = this.$('comment-category').value;
    if (category) body.category = category;
    try {
      const comment = await postJSON('/api/comments', body);
      this.closeForm();
      this.say(this.t(comment.status === 'visible' ? 'comments.thanks' : 'comments.pending', { n: comment.number }));
      this.show(true);
      await this.refresh();
    } catch (error) {
      this.say(error.status === 400 || error.parameter === 'pixel' ? this.t('comments.sky') : error.message);
    }
  }

  /** Shows or hides the pins in the view. */
  show(on) {
    this.shown = on;
    this.$('comments-show').setAttribute('aria-pressed', String(on));
    this.app.connection.send({ type: 'comments', show: on });
  }

  async refresh() {
    let comments = [];
    try {
      if (this.app.mode === 'planner') {
        comments = await allComments();
      } else {
        const response = await fetch('/api/comments');
        if (response.ok) comments = (await response.json()).comments ?? [];
      }
    } catch {
      return;
    }
    const list = this.$('comment-list');
    list.replaceChildren(...comments.map((c) => this.item(c)));
    this.$('comment-empty').hidden = comments.length > 0;
  }

  item(comment) {
    const li = document.createElement('li');
    li.dataset.id = String(comment.id);
    const head = document.createElement('p');
    head.className = 'comment-head';
    head.textContent = `${comment.number}. ${comment.category ? this.categoryLabel(comment.category) : ''}`.trim();
    const text = document.createElement('p');
    text.className = 'comment-text';
    text.textContent = comment.text;
    const like = document.createElement('button');
    like.type = 'button';
    like.textContent = this.t('comments.like', { n: comment.likes ?? 0 });
    like.addEventListener('click', () => this.act(comment.id, 'like'));
    const report = document.createElement('button');
    report.type = 'button';
    report.textContent = this.t('comments.report');
    report.addEventListener('click', () => this.act(comment.id, 'report'));
    li.append(head, text, like, report);
    if (this.app.mode === 'planner') li.append(...this.moderation(comment));
    li.dataset.status = comment.status ?? 'visible';
    return li;
  }

  /** The planner's status line and buttons of `comment`. */
  moderation(comment) {
    const status = comment.status ?? 'visible';
    const label = Object.assign(document.createElement('p'), {
      className: 'comment-status',
      textContent: this.t(`comments.status.${status}`),
    });
    const actions = status === 'visible' ? ['hide', 'delete'] : ['approve', 'delete'];
    const buttons = actions.map((action) => {
      const button = Object.assign(document.createElement('button'), {
        type: 'button',
        className: action === 'delete' ? 'danger' : '',
        textContent: this.t(`comments.${action}`),
      });
      button.dataset.action = action;
      button.addEventListener('click', () => this.moderate(comment.id, action));
      return button;
    });
    return [label, ...buttons];
  }

  async moderate(id, action) {
    try {
      await moderateComment(id, action);
      const done = { approve: 'comments.approved', hide: 'comments.hiddenNow', delete: 'comments.deleted' };
      this.say(this.t(done[action]));
      await this.refresh();
    } catch (error) {
      this.say(error.message);
    }
  }

  async act(id, action) {
    try {
      await postJSON(`/api/comments/${id}/${action}`, { author: this.author });
      this.say(this.t(action === 'like' ? 'comments.liked' : 'comments.reported'));
      await this.refresh();
    } catch (error) {
      this.say(error.status === 403 ? this.t('comments.ownLike') : error.message);
    }
  }
}

// Camera navigation on the canvas: orbit (left drag, around the target), pan (right or shift drag),
// dolly (wheel, towards the target; orthographic cameras change their view height), and flight keys:
// W/S forward/back along the view direction projected on the horizontal plane (world y is up),
// Q/E down/up, Shift for 5x speed. `horizon()` looks at the horizon, 2 degrees down.

import { vec3 } from './camera.js';

const ORBIT_SPEED = 0.006; // radians per CSS pixel
const MAX_PITCH = (89 * Math.PI) / 180;
const HORIZON_PITCH = (-2 * Math.PI) / 180;
const Y = [0, 1, 0];

function horizontalForward(camera) {
  const f = vec3.sub(camera.target, camera.eye);
  let h = [f[0], 0, f[2]];
  if (vec3.length(h) < 1e-9 * vec3.length(f)) {
    // looking straight down or up: use the camera's up vector projected instead
    h = [camera.up[0], 0, camera.up[2]];
    if (vec3.length(h) < 1e-9) h = [0, 0, -1];
  }
  return vec3.normalize(h);
}

export class Navigation {
  /**
   * element: the canvas. get(): the camera now shown (a copy is edited); set(camera): make it the
   * user's camera. enabled: set false to ignore input (fixed view).
   */
  constructor(element, { get, set }) {
    this.element = element;
    this.get = get;
    this.set = set;
    this.enabled = true;
    this.keys = new Set();
    this.drag = null;
    element.addEventListener('contextmenu', (e) => e.preventDefault());
    element.addEventListener('pointerdown', (e) => this.pointerDown(e));
    element.addEventListener('pointermove', (e) => this.pointerMove(e));
    element.addEventListener('pointerup', (e) => this.pointerUp(e));
    element.addEventListener('pointercancel', (e) => this.pointerUp(e));
    element.addEventListener('wheel', (e) => this.wheel(e), { passive: false });
    window.addEventListener('keydown', (e) => this.key(e, true));
    window.addEventListener('keyup', (e) => this.key(e, false));
    window.addEventListener('blur', () => this.keys.clear());
  }

  pointerDown(e) {
    if (!this.enabled) return;
    const pan = e.button === 2 || e.shiftKey;
    if (e.button !== 0 && e.button !== 2) return;
    this.drag = { x: e.clientX, y: e.clientY, pan, id: e.pointerId };
    this.element.setPointerCapture(e.pointerId);
    e.preventDefault();
  }

  pointerMove(e) {
    if (!this.drag || e.pointerId !== this.drag.id) return;
    const dx = e.clientX - this.drag.x;
    const dy = e.clientY - this.drag.y;
    this.drag.x = e.clientX;
    this.drag.y = e.clientY;
    if (dx || dy) (this.drag.pan ? this.pan : this.orbit).call(this, dx, dy);
  }

  pointerUp(e) {
    if (this.drag && e.pointerId === this.drag.id) {
      this.element.releasePointerCapture(e.pointerId);
      this.drag = null;
    }
  }

  orbit(dx, dy) {
    const c = this.get();
    const offset = vec3.sub(c.eye, c.target);
    const r = vec3.length(offset);
    let yaw = Math.atan2(offset[0], offset[2]);
    let pitch = Math.asin(Math.max(-1, Math.min(1, offset[1] / r)));
    yaw -= dx * ORBIT_SPEED;
    pitch = Math.max(-MAX_PITCH, Math.min(MAX_PITCH, pitch + dy * ORBIT_SPEED));
    const dir = [Math.cos(pitch) * Math.sin(yaw), Math.sin(pitch), Math.cos(pitch) * Math.cos(yaw)];
    this.set({ ...c, eye: vec3.add(c.target, vec3.scale(dir, r)) });
  }

  pan(dx, dy) {
    const c = this.get();
    const forward = vec3.normalize(vec3.sub(c.target, c.eye));
    const right = vec3.normalize(vec3.cross(forward, c.up));
    const up = vec3.cross(right, forward);
    const height = this.element.getBoundingClientRect().height || 1;
    const r = vec3.length(vec3.sub(c.target, c.eye));
    const viewHeight = c.projection === 'orthographic' ? c.height : 2 * r * Math.tan((c.fov * Math.PI) / 360);
    const s = viewHeight / height;
    const move = vec3.add(vec3.scale(right, -dx * s), vec3.scale(up, dy * s));
    this.set({ ...c, eye: vec3.add(c.eye, move), target: vec3.add(c.target, move) });
  }

  wheel(e) {
    if (!this.enabled) return;
    e.preventDefault();
    const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
    const factor = Math.exp(e.deltaY * unit * 0.0015);
    const c = this.get();
    if (c.projection === 'orthographic') {
      this.set({ ...c, height: c.height * factor });
      return;
    }
    const offset = vec3.sub(c.eye, c.target);
    const r = vec3.length(offset);
    const next = Math.max(c.near * 2, r * factor);
    this.set({ ...c, eye: vec3.add(c.target, vec3.scale(offset, next / r)) });
  }

  key(e, down) {
    const k = (e.key || '').toLowerCase();
    this.fast = e.shiftKey;
    if (k.length !== 1 || !'wsqe'.includes(k)) return;
    const t = e.target;
    if (t && (t.tagName === 'SELECT' || (t.tagName === 'INPUT' && !['range', 'checkbox', 'color'].includes(t.type)))) return;
    if (down) this.keys.add(k);
    else this.keys.delete(k);
  }

  /** Apply held flight keys for dt seconds; true if the camera moved. */
  update(dt) {
    if (!this.enabled || !this.keys.size || !(dt > 0)) return false;
    const c = this.get();
    const r = vec3.length(vec3.sub(c.target, c.eye));
    const speed = Math.max(Math.abs(c.eye[1]), 0.05 * r, 0.01) * (this.fast ? 5 : 1) * Math.min(dt, 0.1);
    let move = [0, 0, 0];
    const f = horizontalForward(c);
    if (this.keys.has('w')) move = vec3.add(move, vec3.scale(f, speed));
    if (this.keys.has('s')) move = vec3.add(move, vec3.scale(f, -speed));
    if (this.keys.has('e')) move = vec3.add(move, vec3.scale(Y, speed));
    if (this.keys.has('q')) move = vec3.add(move, vec3.scale(Y, -speed));
    if (!vec3.length(move)) return false;
    this.set({ ...c, eye: vec3.add(c.eye, move), target: vec3.add(c.target, move) });
    return true;
  }

  /** Look at the horizon from the current eye (pitch -2 degrees), keeping the orbit distance. */
  horizon() {
    const c = this.get();
    const r = vec3.length(vec3.sub(c.target, c.eye));
    const f = horizontalForward(c);
    const dir = vec3.add(vec3.scale(f, Math.cos(HORIZON_PITCH)), vec3.scale(Y, Math.sin(HORIZON_PITCH)));
    this.set({ ...c, target: vec3.add(c.eye, vec3.scale(dir, r)) });
  }
}

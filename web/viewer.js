// prefilter viewer: wires the WebGL2 context, the bundle loader, the scene renderer, the screen passes,
// navigation and the panel; runs the frame loop; exposes window.prefilterViewer for tests.
// URL: ?scene=NAME&mode=MODE&modeB=MODE&split=0..1&t=0..1&size=WxH&fixed=1
//      &continuous=0|1: redraw every frame (default: yes, but scenes slower than SLOW_FRAME_MS per frame
//      are then redrawn on change only; with fixed=1 the default is no: a fixed view is drawn once per change)
//      (debug: &disable=EXT_a,EXT_b treats those extensions as missing, to exercise the fallbacks)

import { fetchJson, loadBundle } from './bundle.js';
import { detectExtensions } from './gl-resources.js';
import { Navigation } from './navigation.js';
import { Passes } from './passes.js';
import { SceneRenderer } from './renderer.js';
import { FrameTimer } from './timing.js';
import { Panel } from './ui.js';

const REFERENCE = 'reference';
const REFERENCE_SAMPLES = 1024; // as `prefilter render --mode reference` (default --spp); 64 for running means
const REFERENCE_PASSES_PER_FRAME = 2;
const PLAY_SECONDS = 8; // one sweep of t from 0 to 1
const SLOW_FRAME_MS = 250; // slower frames are redrawn on change only (unless redrawing is forced)
const KIND_LABELS = { base: 'base', filtered: 'filtered', diagnostic: 'diagnostic', reference: 'progressive supersampling' };
const R2 = [0.7548776662466927, 0.5698402909980532]; // Roberts' R2 low-discrepancy sequence

// -- URL parameters ---------------------------------------------------------------------------------

const query = new URLSearchParams(location.search);
const fixed = query.get('fixed') === '1';
const clamp01 = (v) => Math.min(1, Math.max(0, v));
const numberParam = (name, fallback) => {
  const v = Number.parseFloat(query.get(name));
  return Number.isFinite(v) ? clamp01(v) : fallback;
};
function sizeParam() {
  const m = /^(\d+)x(\d+)$/.exec(query.get('size') || '');
  if (!m) return null;
  const size = [Number(m[1]), Number(m[2])];
  return size.every((v) => v >= 1 && v <= 8192) ? size : null;
}
const disabled = (query.get('disable') || '').split(',').filter(Boolean);
const continuousParam = query.get('continuous');

// -- state ------------------------------------------------------------------------------------------

let readyResolve, readyReject;
const renderedOnce = new Promise((resolve, reject) => {
  readyResolve = resolve;
  readyReject = reject;
});
renderedOnce.catch(() => {}); // awaiting tests see the rejection; the page itself stays quiet

const api = {
  ready: false,
  error: null,
  webgl2: false,
  extensions: {},
  scene: null,
  mode: null,
  modeB: null,
  modes: [], // names, as setMode takes them ('reference' last: the progressive pseudo-mode)
  modeKinds: {}, // name -> base | filtered | diagnostic | reference
  frames: 0,
  frameMs: NaN,
  frameTimeSource: null,
  samples: 0,
  setMode,
  setScene,
  renderedOnce,
};
window.prefilterViewer = api;

const state = {
  gl: null,
  caps: null,
  canvas: null,
  passes: null,
  timer: null,
  nav: null,
  renderer: null,
  loading: true,
  loadToken: 0,
  modes: [], // [{name, kind}] of the scene shown
  modeA: null,
  modeB: null,
  split: numberParam('split', 0.5),
  t: numberParam('t', 0),
  playing: false,
  userCamera: null, // set once the user moves the camera; null follows the scene's camera (flight)
  paramVersion: 0,
  referenceKey: '',
  jitterShift: [0, 0],
  lastTime: null,
  continuous: continuousParam === null ? !fixed : continuousParam === '1',
  forceContinuous: continuousParam === '1', // the user asked for it: no throttling of slow scenes
  throttled: false, // continuous, but frames are too slow: redraw on change only
  drawnKey: '', // what the canvas shows; a frame is drawn when it changes (or every frame if continuous)
  waiters: [], // resolved after the next drawn frame
  checkGL: false,
  notes: [],
};
const panel = new Panel();

function fail(message) {
  const text = message instanceof Error ? message.message : String(message);
  api.error = text;
  console.error(`prefilter viewer: ${text}`);
  panel.showError(text);
}

function nextFrame() {
  return new Promise((resolve) => state.waiters.push(resolve));
}

/** After a scene or mode change: draw the next frame, check it for GL errors, time it afresh. */
function invalidate() {
  state.drawnKey = '';
  state.checkGL = true;
  state.throttled = false;
  state.timer?.reset();
}

// -- modes ------------------------------------------------------------------------------------------

function sceneModes(scene) {
  const modes = scene.modes.map((m) => ({ name: m.name, kind: m.kind }));
  if (modes.some((m) => m.name === 'point')) modes.push({ name: REFERENCE, kind: 'reference' });
  return modes;
}

function modeItems(modes) {
  return modes.map((m) => ({ value: m.name, label: `${m.name} (${KIND_LABELS[m.kind] || m.kind})` }));
}

async function prepareMode(mode) {
  if (mode === null) return;
  await state.renderer.prepare(mode === REFERENCE ? 'point' : mode);
}

function checkMode(name, modes) {
  if (!modes.some((m) => m.name === name)) {
    throw new Error(`${name} is not a mode of ${api.scene} (modes: ${modes.map((m) => m.name).join(', ')})`);
  }
}

/** Show `name` as mode A; resolves after the next frame is drawn with it. */
async function setMode(name) {
  try {
    checkMode(name, state.modes);
    await prepareMode(name);
  } catch (err) {
    fail(err);
    throw err;
  }
  state.modeA = api.mode = name;
  panel.mode.value = name;
  invalidate();
  updateUrl();
  return nextFrame();
}

async function setModeB(name) {
  try {
    if (name !== null) {
      checkMode(name, state.modes);
      await prepareMode(name);
    }
  } catch (err) {
    fail(err);
    throw err;
  }
  state.modeB = api.modeB = name;
  panel.modeB.value = name ?? '';
  panel.showSplit(name !== null);
  invalidate();
  updateUrl();
  return nextFrame();
}

// -- scenes -----------------------------------------------------------------------------------------

function defaultMode(modes) {
  return (modes.find((m) => m.kind === 'filtered') || modes[0]).name;
}

/** Load a preset's bundle and show it; resolves after its first frame. */
async function setScene(name, wanted = {}) {
  const token = ++state.loadToken;
  state.loading = true;
  state.timer?.pause();
  panel.scene.value = name;
  panel.setStatus(`Loading ${name}… (the first load of a preset bakes its tables and may take tens of seconds)`);
  try {
    const bundle = await loadBundle(`bundles/${encodeURIComponent(name)}`, {
      onStep: (done, total) => {
        if (token === state.loadToken) panel.setStatus(`Loading ${name}: ${done}/${total} files`);
      },
    });
    if (token !== state.loadToken) return nextFrame();
    const modes = sceneModes(bundle.scene);
    const pick = (m) => (m && modes.some((x) => x.name === m) ? m : null);
    let modeA = pick(wanted.mode) ?? pick(state.modeA) ?? defaultMode(modes);
    const modeB = wanted.modeB !== undefined ? pick(wanted.modeB) : pick(state.modeB);
    const invalid = [wanted.mode, wanted.modeB].filter((m) => m && !pick(m));
    if (state.renderer) state.renderer.release();
    state.renderer = null;
    const renderer = new SceneRenderer(state.gl, state.caps, bundle);
    state.renderer = renderer;
    api.scene = name;
    state.modes = modes;
    api.modes = modes.map((m) => m.name);
    api.modeKinds = Object.fromEntries(modes.map((m) => [m.name, m.kind]));
    for (const m of [modeA, modeB]) await prepareMode(m);
    if (token !== state.loadToken) return nextFrame();
    const size = sizeParam() || bundle.scene.scene.size;
    state.canvas.width = size[0];
    state.canvas.height = size[1];
    state.passes.resize(size[0], size[1]);
    fitCanvas();
    state.userCamera = null;
    state.referenceKey = '';
    state.modeA = api.mode = modeA;
    state.modeB = api.modeB = modeB;
    panel.fill(panel.mode, modeItems(modes), modeA);
    panel.fill(panel.modeB, [{ value: '', label: '(none)' }, ...modeItems(modes)], modeB ?? '');
    panel.showSplit(modeB !== null);
    panel.description.textContent = bundle.scene.scene.description || '';
    panel.showTime(renderer.animated() && !fixed);
    panel.setTime(state.t);
    buildParameters();
    api.error = null;
    panel.showError('');
    if (invalid.length) fail(`mode ${invalid.join(', ')} is not a mode of ${name} (modes: ${modes.map((m) => m.name).join(', ')})`);
    panel.setStatus('');
    state.loading = false;
    invalidate();
    updateUrl();
    return nextFrame();
  } catch (err) {
    if (token === state.loadToken) {
      panel.setStatus('');
      fail(`cannot show ${name}: ${err.message}`);
      if (!api.ready) readyReject(err);
    }
    throw err;
  }
}

function buildParameters() {
  const r = state.renderer;
  const initial = (obj, uniform) => [...(obj.json.uniforms?.[uniform]?.value || [])];
  panel.buildParameters(
    r.objects.map((obj) => ({
      name: obj.json.name,
      parameters: obj.json.parameters || [],
      value: (u) => r.materialValue(obj, u, 0) || [],
    })),
    (index, uniform, values) => {
      r.objects[index].overrides[uniform] = values;
      state.paramVersion++;
    },
  );
  panel.paramReset.onclick = () => {
    for (const obj of r.objects) obj.overrides = {};
    panel.resetParameters((index, uniform) => initial(r.objects[index], uniform));
    state.paramVersion++;
  };
}

function updateUrl() {
  if (!api.scene) return;
  const q = new URLSearchParams(location.search);
  q.set('scene', api.scene);
  if (state.modeA) q.set('mode', state.modeA);
  if (state.modeB) q.set('modeB', state.modeB);
  else q.delete('modeB');
  history.replaceState(null, '', `${location.pathname}?${q}`);
}

// -- camera -----------------------------------------------------------------------------------------

function currentCamera() {
  if (!fixed && state.userCamera) return state.userCamera;
  return state.renderer.sceneCamera(state.t);
}

function fitCanvas() {
  const c = state.canvas;
  if (fixed) {
    const dpr = window.devicePixelRatio || 1;
    c.style.width = `${c.width / dpr}px`;
    c.style.height = `${c.height / dpr}px`;
    return;
  }
  const stage = c.parentElement.getBoundingClientRect();
  const scale = Math.min(stage.width / c.width, stage.height / c.height);
  if (!(scale > 0)) return;
  c.style.width = `${Math.floor(c.width * scale)}px`;
  c.style.height = `${Math.floor(c.height * scale)}px`;
}

// -- frames -----------------------------------------------------------------------------------------

function referenceSamples() {
  return Math.min(REFERENCE_SAMPLES, state.passes.maxSamples);
}

function nextJitter(n) {
  const frac = (x) => x - Math.floor(x);
  return [frac(state.jitterShift[0] + n * R2[0]) - 0.5, frac(state.jitterShift[1] + n * R2[1]) - 0.5];
}

function drawFrame(camera) {
  const { renderer, passes } = state;
  const width = passes.colour.width;
  const view = { camera, t: state.t, jitter: [0, 0] };
  const { modeA, modeB } = state;
  const refA = modeA === REFERENCE;
  const refB = modeB === REFERENCE;
  const split = modeB === null ? width : Math.round(state.split * width);
  if (refA || refB) {
    const key = JSON.stringify([camera.eye, camera.target, camera.height, state.t, state.paramVersion, width]);
    if (key !== state.referenceKey) {
      state.referenceKey = key;
      state.jitterShift = [Math.random(), Math.random()];
      passes.resetAccumulation();
    }
    for (let k = 0; k < REFERENCE_PASSES_PER_FRAME && passes.samples < referenceSamples(); k++) {
      renderer.draw(passes.colour, 'point', { ...view, jitter: nextJitter(passes.samples) });
      passes.accumulate();
    }
  }
  if (!refA) renderer.draw(passes.colour, modeA, view);
  if (modeB !== null && !refB && modeB !== modeA) {
    renderer.draw(passes.colour, modeB, view, refA ? null : split);
  }
  const left = passes.source(refA);
  const right = modeB === null ? left : passes.source(refB);
  passes.display(left, right, split, modeB !== null && !fixed, state.renderer.scene.scene.background);
}

/** Everything a drawn frame depends on, but the reference's sample count. */
function viewKey(camera) {
  const { passes } = state;
  return JSON.stringify([
    state.loadToken, state.modeA, state.modeB, state.modeB === null ? 1 : state.split, state.t, state.paramVersion,
    camera.eye, camera.target, camera.fov, camera.height, passes.colour.width, passes.colour.height,
  ]);
}

function frame(now) {
  requestAnimationFrame(frame);
  if (state.loading || !state.renderer || !state.renderer.has(state.modeA === REFERENCE ? 'point' : state.modeA)) {
    state.timer?.pause();
    state.lastTime = null;
    return;
  }
  const dt = state.lastTime === null ? 0 : (now - state.lastTime) / 1000;
  state.lastTime = now;
  state.nav.update(dt);
  if (state.playing) {
    state.t = (state.t + dt / PLAY_SECONDS) % 1;
    panel.setTime(state.t);
  }
  const camera = currentCamera();
  const key = viewKey(camera);
  const refining = (state.modeA === REFERENCE || state.modeB === REFERENCE) && state.passes.samples < referenceSamples();
  state.throttled = state.continuous && !state.forceContinuous && state.timer.value.ms > SLOW_FRAME_MS;
  if ((!state.continuous || state.throttled) && !refining && key === state.drawnKey) {
    state.timer.idle();
    updateTiming();
    return;
  }
  try {
    state.timer.begin(now);
    drawFrame(camera);
    state.timer.end();
    state.drawnKey = key;
    if (state.checkGL) {
      state.checkGL = false;
      const err = state.gl.getError();
      if (err !== state.gl.NO_ERROR) fail(`WebGL error 0x${err.toString(16)} while drawing ${api.scene} / ${state.modeA}`);
    }
  } catch (err) {
    state.timer.end();
    fail(err);
    state.loading = true; // stop drawing until the next scene or mode change
    return;
  }
  api.frames++;
  updateTiming();
  api.samples = state.modeA === REFERENCE || state.modeB === REFERENCE ? state.passes.samples : 0;
  if (!api.ready) {
    api.ready = true;
    readyResolve();
  }
  const waiters = state.waiters.splice(0);
  for (const resolve of waiters) resolve();
  if (api.frames % 10 === 1 || !state.continuous || state.throttled) showStats();
}

function updateTiming() {
  const timing = state.timer.value;
  if (timing.ms === api.frameMs && timing.source === api.frameTimeSource) return;
  api.frameMs = timing.ms;
  api.frameTimeSource = timing.source;
  if (!state.continuous || state.throttled) showStats();
}

function showStats() {
  const { passes, renderer } = state;
  const lines = [
    [`frame (${api.frameTimeSource})`, Number.isFinite(api.frameMs) ? `${api.frameMs.toFixed(2)} ms` : '…'],
    ['size', `${passes.colour.width}×${passes.colour.height}`],
    ['target', passes.format],
  ];
  if (api.samples) {
    const how = passes.accumMode === 'mean' ? `${passes.accumFormat} running mean` : `${passes.accumFormat} sum`;
    lines.push(['reference', `${api.samples} / ${referenceSamples()} samples (${how})`]);
  }
  const refining = api.samples > 0 && api.samples < referenceSamples();
  if (state.throttled && !refining) lines.push(['redraw', `on change only (frames > ${SLOW_FRAME_MS} ms)`]);
  panel.setStats(lines);
  panel.setNotices([...state.notes, ...renderer.notes]);
}

// -- start ------------------------------------------------------------------------------------------

function wirePanel() {
  panel.scene.addEventListener('change', () => setScene(panel.scene.value).catch(() => {}));
  panel.mode.addEventListener('change', () => setMode(panel.mode.value).catch(() => {}));
  panel.modeB.addEventListener('change', () => setModeB(panel.modeB.value || null).catch(() => {}));
  panel.split.value = state.split;
  panel.split.addEventListener('input', () => {
    state.split = Number(panel.split.value);
  });
  panel.time.addEventListener('input', () => {
    state.t = Number(panel.time.value);
    panel.setTime(state.t);
  });
  panel.play.addEventListener('click', () => {
    state.playing = !state.playing;
    panel.play.textContent = state.playing ? 'Pause' : 'Play';
  });
  panel.continuous.checked = state.continuous;
  panel.continuous.addEventListener('change', () => {
    state.continuous = state.forceContinuous = panel.continuous.checked;
  });
  panel.horizon.addEventListener('click', () => state.nav.horizon());
  panel.resetView.addEventListener('click', () => {
    state.userCamera = null;
  });
  new ResizeObserver(() => state.passes?.colour && fitCanvas()).observe(state.canvas.parentElement);
}

async function main() {
  document.body.classList.toggle('fixed', fixed);
  const canvas = document.getElementById('view');
  state.canvas = canvas;
  const gl = canvas.getContext('webgl2', {
    alpha: false, depth: false, stencil: false, antialias: false, premultipliedAlpha: false,
    preserveDrawingBuffer: true,
  });
  if (!gl) {
    document.getElementById('no-webgl2').hidden = false;
    canvas.hidden = true;
    fail('WebGL2 is not available in this browser: the viewer needs it.');
    readyReject(new Error(api.error));
    return;
  }
  api.webgl2 = true;
  state.gl = gl;
  canvas.addEventListener('webglcontextlost', (e) => {
    e.preventDefault();
    fail('the WebGL context was lost; reload the page');
    state.loading = true;
  });
  state.caps = detectExtensions(gl, disabled);
  api.extensions = { ...state.caps.summary, target: state.caps.target };
  if (state.caps.target === 'RGBA8') {
    state.notes.push('low-precision fallback: no float colour buffers (EXT_color_buffer_float / _half_float), the scene is drawn into RGBA8');
  } else if (state.caps.target === 'RGBA16F') {
    state.notes.push('scene target RGBA16F: RGBA32F needs EXT_color_buffer_float and EXT_float_blend');
  }
  if (!state.caps.ext.textureFloatLinear) state.notes.push('no OES_texture_float_linear: linearly filtered tables are uploaded as 16-bit floats');
  panel.setNotices(state.notes);
  state.passes = new Passes(gl, state.caps);
  state.timer = new FrameTimer(gl, state.caps.ext.timerQuery);
  state.nav = new Navigation(canvas, {
    get: () => ({ ...currentCamera() }),
    set: (camera) => {
      state.userCamera = camera;
    },
  });
  state.nav.enabled = !fixed;
  wirePanel();
  requestAnimationFrame(frame);

  let presets = [];
  try {
    presets = await fetchJson('presets.json');
  } catch (err) {
    fail(err);
  }
  panel.fill(panel.scene, presets.map((p) => ({ value: p.name, label: p.name })));
  for (const option of panel.scene.options) {
    const p = presets.find((x) => x.name === option.value);
    if (p) option.title = [p.description, (p.tags || []).join(', ')].filter(Boolean).join(' — ');
  }
  const name = query.get('scene') || presets.find((p) => p.name === 'marble-cube')?.name || presets[0]?.name;
  if (!name) {
    fail('no presets to show (presets.json is empty or missing)');
    readyReject(new Error(api.error));
    return;
  }
  if (!presets.some((p) => p.name === name)) {
    panel.scene.append(Object.assign(document.createElement('option'), { value: name, textContent: name }));
  }
  await setScene(name, { mode: query.get('mode'), modeB: query.get('modeB') }).catch(() => {});
}

main().catch((err) => {
  fail(err);
  readyReject(err);
});

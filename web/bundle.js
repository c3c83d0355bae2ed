// Fetching an export bundle (docs/export.md): scene.json, meshes (.bin), tables (JSON + EXR levels)
// and, on demand, the es300 shader sources. Paths in the bundle are relative to its root URL.

import { decodeExr } from './exr.js';

export const FORMAT = 'prefilter-export/1';

async function fetchOk(url, signal) {
  let response;
  try {
    response = await fetch(url, { signal });
  } catch (err) {
    if (err.name === 'AbortError') throw err;
    throw new Error(`${url}: ${err.message}`);
  }
  if (!response.ok) {
    // The server answers a failed export with {"error": "..."}; anything else: its first line.
    let text = (await response.text().catch(() => '')).trim();
    try {
      text = JSON.parse(text).error ?? text;
    } catch {
      // not JSON
    }
    text = String(text).split('\n')[0].slice(0, 500);
    throw new Error(`${url}: HTTP ${response.status} ${response.statusText}${text ? ` (${text})` : ''}`);
  }
  return response;
}

export async function fetchJson(url, signal) {
  const response = await fetchOk(url, signal);
  try {
    return await response.json();
  } catch (err) {
    throw new Error(`${url}: not valid JSON (${err.message})`);
  }
}

export async function fetchBytes(url, signal) {
  return (await fetchOk(url, signal)).arrayBuffer();
}

export async function fetchText(url, signal) {
  return (await fetchOk(url, signal)).text();
}

function resolve(base, path) {
  return base.replace(/\/?$/, '/') + path;
}

async function loadTable(base, path, signal) {
  const meta = await fetchJson(resolve(base, path), signal);
  const dir = path.replace(/[^/]*$/, '');
  const levels = await Promise.all(
    meta.levels.map(async (lv) => {
      const url = resolve(base, dir + lv.file);
      try {
        return decodeExr(await fetchBytes(url, signal));
      } catch (err) {
        if (err.name === 'AbortError') throw err;
        throw new Error(err.message.startsWith(url) ? err.message : `${url}: ${err.message}`);
      }
    }),
  );
  return { meta, levels };
}

/**
 * Everything but the shaders: {base, scene, objects: [{json, vertices, indices, tables: {sampler: {meta, levels}}}]}.
 * onStep(done, total) reports progress over the files fetched.
 */
export async function loadBundle(base, { signal, onStep } = {}) {
  const scene = await fetchJson(resolve(base, 'scene.json'), signal);
  if (scene.format !== FORMAT) {
    throw new Error(`${resolve(base, 'scene.json')}: format ${JSON.stringify(scene.format)}, expected ${FORMAT}`);
  }
  let done = 0;
  const total = scene.objects.reduce((n, o) => n + 2 + Object.keys(o.samplers || {}).length, 0);
  const step = (value) => {
    done++;
    if (onStep) onStep(done, total);
    return value;
  };
  const objects = await Promise.all(
    scene.objects.map(async (json) => {
      const [vertices, indices, tables] = await Promise.all([
        fetchBytes(resolve(base, json.mesh.vertices), signal).then(step),
        fetchBytes(resolve(base, json.mesh.indices), signal).then(step),
        Promise.all(
          Object.entries(json.samplers || {}).map(async ([name, path]) => [name, step(await loadTable(base, path, signal))]),
        ),
      ]);
      return { json, vertices, indices, tables: Object.fromEntries(tables) };
    }),
  );
  return { base, scene, objects };
}

/** The es300 {vertex, fragment} sources of an object in a mode, or null if the bundle has none. */
export async function loadShaders(bundle, object, mode) {
  const entry = object.json.shaders?.[mode]?.es300;
  if (!entry) return null;
  const [vertex, fragment] = await Promise.all([
    fetchText(resolve(bundle.base, entry.vertex)),
    fetchText(resolve(bundle.base, entry.fragment)),
  ]);
  return { vertex, fragment, paths: entry };
}

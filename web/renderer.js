// Drawing a loaded bundle exactly as prefilter.gl.render.Renderer.draw: clear to (0, 0, 0, 0) and
// depth 1, depth test LESS, opaque objects first then "over" objects in file order (premultiplied
// blend ONE, ONE_MINUS_SRC_ALPHA, no depth writes), back faces culled unless double_sided. Programs
// are compiled per (object, mode) on first use; per-frame uniforms are computed as frame_uniforms.

import { loadShaders } from './bundle.js';
import {
  cameraAt, fromRows, inverse, lightAt, multiply, normalMatrix, projectionMatrix, toGL, transform, vec3, viewMatrix,
} from './camera.js';
import {
  compileProgram, createMesh, createTable, createVertexArray, programUniforms, setUniform,
} from './gl-resources.js';

export const MAX_LIGHTS = 4; // SH_MAX_LIGHTS in glsl/common/shading.glsl

/** The renderer's per-frame uniforms of one object (render.py frame_uniforms), as flat number lists. */
export function frameUniforms(scene, object, clipFromWorld, camera, t, jitter) {
  const world = object.world;
  const objectFromWorld = inverse(world);
  let eye;
  if (camera.projection === 'orthographic') {
    eye = [...transform(objectFromWorld, [...vec3.sub(camera.target, camera.eye), 0]).slice(0, 3), 0];
  } else {
    eye = transform(objectFromWorld, [...camera.eye, 1]);
  }
  const lights = scene.lights.slice(0, MAX_LIGHTS).map((l) => lightAt(l, t));
  while (lights.length < MAX_LIGHTS) lights.push({ direction: [0, 0, 0], colour: [0, 0, 0] });
  return {
    u_clipFromObject: toGL(multiply(clipFromWorld, world)),
    u_worldNormalFromObject: normalMatrix(world),
    u_jitter: jitter,
    u_eyeObject: eye,
    u_objectFromWorld: toGL(objectFromWorld),
    sh_lit: [object.json.lit ? 1 : 0],
    sh_ambient: [scene.lights.length ? scene.scene.ambient : 1],
    sh_lightCount: [scene.lights.length],
    sh_lightDirection: lights.flatMap((l) => l.direction),
    sh_lightColour: lights.flatMap((l) => l.colour),
  };
}

/** clipFromWorld of a camera pose for a target of size [w, h]. */
export function clipFromWorld(camera, size) {
  return multiply(projectionMatrix(camera, size[0] / size[1]), viewMatrix(camera));
}

const SAMPLER_TARGETS = {
  SAMPLER_3D: 'TEXTURE_3D', INT_SAMPLER_3D: 'TEXTURE_3D', UNSIGNED_INT_SAMPLER_3D: 'TEXTURE_3D',
  SAMPLER_2D_ARRAY: 'TEXTURE_2D_ARRAY', INT_SAMPLER_2D_ARRAY: 'TEXTURE_2D_ARRAY',
  UNSIGNED_INT_SAMPLER_2D_ARRAY: 'TEXTURE_2D_ARRAY', SAMPLER_2D_ARRAY_SHADOW: 'TEXTURE_2D_ARRAY',
  SAMPLER_CUBE: 'TEXTURE_CUBE_MAP', SAMPLER_CUBE_SHADOW: 'TEXTURE_CUBE_MAP',
};

export class SceneRenderer {
  /** bundle: loadBundle's result. Creates meshes and tables now; programs on prepare(mode). */
  constructor(gl, caps, bundle) {
    this.gl = gl;
    this.bundle = bundle;
    this.scene = bundle.scene;
    this.notes = []; // non-fatal remarks for the page (half-float tables, missing shaders, ...)
    const halfFloat = [];
    this.objects = bundle.objects.map((o) => {
      const textures = {};
      for (const [name, table] of Object.entries(o.tables)) {
        textures[name] = createTable(gl, caps, table.meta, table.levels);
        if (textures[name].halfFloat) halfFloat.push(`${o.json.name}.${name}`);
      }
      return {
        json: o.json,
        world: fromRows(o.json.world_from_object),
        mesh: createMesh(gl, o.json.mesh, o.vertices, o.indices),
        textures,
        programs: new Map(), // mode -> {program, uniforms, samplers, vao}
        overrides: {}, // uniform -> flat values set by the parameters panel
      };
    });
    if (halfFloat.length) this.notes.push(`tables uploaded as 16F: ${halfFloat.join(', ')}`);
    // Opaque first, then "over" objects in file order (a stable sort keeps file order).
    this.drawOrder = [...this.objects].sort((a, b) => (a.json.blend !== 'opaque') - (b.json.blend !== 'opaque'));
    this.samplerTargets = new Map(
      Object.entries(SAMPLER_TARGETS).map(([type, target]) => [gl[type], gl[target]]),
    );
  }

  /** Fetch and compile every object's program of `mode` (throws with the driver's log on failure). */
  async prepare(mode) {
    const gl = this.gl;
    await Promise.all(
      this.objects.map(async (obj) => {
        if (obj.programs.has(mode)) return;
        let sourceMode = mode;
        let src = await loadShaders(this.bundle, obj, mode);
        if (!src && mode !== 'point') {
          sourceMode = 'point';
          src = await loadShaders(this.bundle, obj, 'point');
          this.notes.push(`${obj.json.name}: no ${mode} shader in the bundle, drawn with point`);
        }
        if (!src) throw new Error(`${obj.json.name}: the bundle has no es300 shader for mode ${mode}`);
        if (obj.programs.has(mode)) return;
        const label = `${obj.json.name} / ${sourceMode} (${src.paths.vertex}, ${src.paths.fragment})`;
        const program = compileProgram(gl, src.vertex, src.fragment, label);
        const { uniforms, samplers } = programUniforms(gl, program);
        for (const name of samplers.keys()) {
          if (!obj.textures[name]) this.notes.push(`${obj.json.name}: sampler ${name} has no table in the bundle`);
        }
        const vao = createVertexArray(gl, program, obj.mesh);
        obj.programs.set(mode, { program, uniforms, samplers, vao });
      }),
    );
  }

  has(mode) {
    return this.objects.every((o) => o.programs.has(mode));
  }

  /** Material uniform values at time t: overrides, else value + t (end - value). */
  materialValue(obj, name, t) {
    if (obj.overrides[name]) return obj.overrides[name];
    const u = obj.json.uniforms?.[name];
    if (!u) return null;
    if (!u.end || t === 0) return u.value;
    return u.value.map((v, i) => v + t * (u.end[i] - v));
  }

  /** Any animation in the scene (camera flight, moving lights, uniforms with `end`)? */
  animated() {
    const s = this.scene;
    return !!(
      s.camera.eye_end || s.camera.target_end ||
      s.lights.some((l) => l.direction_end) ||
      s.objects.some((o) => Object.values(o.uniforms || {}).some((u) => u.end))
    );
  }

  /** The scene's own camera at time t. */
  sceneCamera(t) {
    return cameraAt(this.scene.camera, t);
  }

  /**
   * Draw `mode` into target (a createRenderTarget result). view: {camera, t, jitter: [px, py]}.
   * scissorX: if given, only pixels with x >= scissorX are cleared and drawn (split screen).
   */
  draw(target, mode, view, scissorX = null) {
    const gl = this.gl;
    const size = [target.width, target.height];
    gl.bindFramebuffer(gl.FRAMEBUFFER, target.framebuffer);
    gl.viewport(0, 0, size[0], size[1]);
    if (scissorX !== null) {
      gl.enable(gl.SCISSOR_TEST);
      gl.scissor(scissorX, 0, Math.max(0, size[0] - scissorX), size[1]);
    } else gl.disable(gl.SCISSOR_TEST);
    gl.colorMask(true, true, true, true);
    gl.depthMask(true);
    gl.clearColor(0, 0, 0, 0);
    gl.clearDepth(1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.frontFace(gl.CCW);
    gl.cullFace(gl.BACK);
    const clip = clipFromWorld(view.camera, size);
    const jitter = [(2 * view.jitter[0]) / size[0], (2 * view.jitter[1]) / size[1]];
    for (const obj of this.drawOrder) {
      const p = obj.programs.get(mode);
      if (!p) continue;
      gl.useProgram(p.program);
      const frame = frameUniforms(this.scene, obj, clip, view.camera, view.t, jitter);
      for (const [name, u] of p.uniforms) {
        // Python sets the frame uniforms, then the material's bind: the material wins on a clash.
        const value = this.materialValue(obj, name, view.t) ?? frame[name];
        if (value) setUniform(u, value);
      }
      for (const [name, s] of p.samplers) {
        gl.activeTexture(gl.TEXTURE0 + s.unit);
        const tex = obj.textures[name];
        if (tex) gl.bindTexture(tex.target, tex.texture);
        else gl.bindTexture(this.samplerTargets.get(s.type) ?? gl.TEXTURE_2D, null);
      }
      if (obj.json.double_sided) gl.disable(gl.CULL_FACE);
      else gl.enable(gl.CULL_FACE);
      if (obj.json.blend === 'over') {
        gl.enable(gl.BLEND);
        gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
        gl.depthMask(false);
      } else {
        gl.disable(gl.BLEND);
        gl.depthMask(true);
      }
      gl.bindVertexArray(p.vao);
      gl.drawElements(gl.TRIANGLES, obj.mesh.count, gl.UNSIGNED_INT, 0);
    }
    gl.bindVertexArray(null);
    gl.depthMask(true);
    gl.disable(gl.BLEND);
    gl.disable(gl.CULL_FACE);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.SCISSOR_TEST);
    gl.activeTexture(gl.TEXTURE0);
  }

  release() {
    const gl = this.gl;
    for (const obj of this.objects) {
      for (const p of obj.programs.values()) {
        gl.deleteVertexArray(p.vao);
        gl.deleteProgram(p.program);
      }
      for (const tex of Object.values(obj.textures)) gl.deleteTexture(tex.texture);
      gl.deleteBuffer(obj.mesh.vbo);
      gl.deleteBuffer(obj.mesh.ibo);
    }
    this.objects = [];
    this.drawOrder = [];
  }
}

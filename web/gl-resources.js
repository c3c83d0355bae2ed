// WebGL2 resources of an export bundle: extension detection with fallbacks, tables (textures from
// decoded EXR levels), meshes (interleaved float32 vertices + uint32 indices), programs with error
// reports, generic uniform setting through gl.getActiveUniform, and float render targets.

/** Extensions the viewer uses; names in `disabled` (debug: ?disable=a,b) are treated as missing. */
export function detectExtensions(gl, disabled = []) {
  const get = (name) => (disabled.includes(name) ? null : gl.getExtension(name));
  const ext = {
    colorBufferFloat: get('EXT_color_buffer_float'),
    colorBufferHalfFloat: get('EXT_color_buffer_half_float'),
    floatBlend: get('EXT_float_blend'),
    textureFloatLinear: get('OES_texture_float_linear'),
    anisotropic: get('EXT_texture_filter_anisotropic'),
    timerQuery: get('EXT_disjoint_timer_query_webgl2'),
  };
  const summary = {
    EXT_color_buffer_float: !!ext.colorBufferFloat,
    EXT_color_buffer_half_float: !!ext.colorBufferHalfFloat,
    EXT_float_blend: !!ext.floatBlend,
    OES_texture_float_linear: !!ext.textureFloatLinear,
    EXT_texture_filter_anisotropic: !!ext.anisotropic,
    EXT_disjoint_timer_query_webgl2: !!ext.timerQuery,
  };
  // Scene target: RGBA32F needs float blending too ("over" objects, reference accumulation);
  // RGBA16F is blendable wherever it is renderable; RGBA8 is the last resort.
  let target = 'RGBA8';
  if (ext.colorBufferFloat && ext.floatBlend) target = 'RGBA32F';
  else if (ext.colorBufferFloat || ext.colorBufferHalfFloat) target = 'RGBA16F';
  return { ext, summary, target };
}

// -- float16 ------------------------------------------------------------------------------------

const f32 = new Float32Array(1);
const u32 = new Uint32Array(f32.buffer);

/** IEEE binary16 bits of x, rounded to nearest even; overflow -> inf, NaN kept. */
export function toHalf(x) {
  f32[0] = x;
  const bits = u32[0];
  const sign = (bits >>> 16) & 0x8000;
  const exp = (bits >>> 23) & 0xff;
  let mant = bits & 0x7fffff;
  if (exp === 0xff) return sign | 0x7c00 | (mant ? 0x200 : 0);
  let e = exp - 127 + 15;
  if (e >= 0x1f) return sign | 0x7c00;
  if (e <= 0) {
    if (e < -10) return sign;
    mant |= 0x800000;
    const shift = 14 - e;
    let half = mant >>> shift;
    const rest = mant & ((1 << shift) - 1);
    const mid = 1 << (shift - 1);
    if (rest > mid || (rest === mid && half & 1)) half++;
    return sign | half;
  }
  let half = (e << 10) | (mant >>> 13);
  const rest = mant & 0x1fff;
  if (rest > 0x1000 || (rest === 0x1000 && half & 1)) half++; // may carry into the exponent: correct
  return sign | half;
}

export function toHalfArray(data) {
  const out = new Uint16Array(data.length);
  for (let i = 0; i < data.length; i++) out[i] = toHalf(data[i]);
  return out;
}

// -- tables -------------------------------------------------------------------------------------

const FORMATS = ['RED', 'RG', 'RGB', 'RGBA'];
const INTERNAL32 = ['R32F', 'RG32F', 'RGB32F', 'RGBA32F'];
const INTERNAL16 = ['R16F', 'RG16F', 'RGB16F', 'RGBA16F'];
const TARGETS = { '2d': 'TEXTURE_2D', '2d_array': 'TEXTURE_2D_ARRAY', '3d': 'TEXTURE_3D' };

function glEnum(gl, name, what) {
  const value = gl[name];
  if (typeof value !== 'number') throw new Error(`unknown GL ${what} ${JSON.stringify(name)}`);
  return value;
}

/** Throws, naming the table and the limit, when this device cannot hold the table. */
function checkLimits(gl, meta) {
  const limits =
    meta.kind === '3d'
      ? [['width, height and depth', [meta.width, meta.height, meta.depth], 'MAX_3D_TEXTURE_SIZE']]
      : [['width and height', [meta.width, meta.height], 'MAX_TEXTURE_SIZE']];
  if (meta.kind === '2d_array') limits.push(['layers', [meta.depth], 'MAX_ARRAY_TEXTURE_LAYERS']);
  for (const [what, values, name] of limits) {
    const limit = gl.getParameter(gl[name]);
    if (Math.max(...values) > limit) {
      throw new Error(`table ${meta.sampler}: ${what} ${values.join('x')} exceed this device's ${name} = ${limit}`);
    }
  }
}

/**
 * A texture from a table's JSON and its decoded EXR levels (decodeExr results, level 0 first).
 * Returns {texture, target, halfFloat} — halfFloat when a LINEAR* table had to be uploaded as 16F
 * because OES_texture_float_linear is missing.
 */
export function createTable(gl, caps, meta, levels) {
  const targetName = TARGETS[meta.kind];
  if (!targetName) throw new Error(`table ${meta.sampler}: unknown kind ${JSON.stringify(meta.kind)}`);
  const target = gl[targetName];
  const c = meta.components;
  if (!(c >= 1 && c <= 4)) throw new Error(`table ${meta.sampler}: components must be 1..4, got ${c}`);
  checkLimits(gl, meta);
  const linear = [meta.filter.min, meta.filter.mag].some((f) => f.startsWith('LINEAR') || f.endsWith('MIPMAP_LINEAR'));
  const halfFloat = linear && !caps.ext.textureFloatLinear;
  const internal = gl[(halfFloat ? INTERNAL16 : INTERNAL32)[c - 1]];
  const format = gl[FORMATS[c - 1]];
  const type = halfFloat ? gl.HALF_FLOAT : gl.FLOAT;
  const texture = gl.createTexture();
  gl.bindTexture(target, texture);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  meta.levels.forEach((lv, k) => {
    const img = levels[k];
    const depth = meta.kind === '2d' ? 1 : lv.depth;
    if (img.channels.length !== c) {
      throw new Error(`table ${meta.sampler} level ${k}: EXR has channels ${img.channels.join('')}, expected ${c}`);
    }
    if (img.width !== lv.width || img.height !== lv.height * depth) {
      throw new Error(
        `table ${meta.sampler} level ${k}: EXR is ${img.width}x${img.height}, expected ${lv.width}x${lv.height * depth}`,
      );
    }
    const data = halfFloat ? toHalfArray(img.data) : img.data;
    if (meta.kind === '2d') gl.texImage2D(target, k, internal, lv.width, lv.height, 0, format, type, data);
    else gl.texImage3D(target, k, internal, lv.width, lv.height, depth, 0, format, type, data);
  });
  gl.texParameteri(target, gl.TEXTURE_BASE_LEVEL, 0);
  gl.texParameteri(target, gl.TEXTURE_MAX_LEVEL, meta.levels.length - 1);
  gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, glEnum(gl, meta.filter.min, 'filter'));
  gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, glEnum(gl, meta.filter.mag, 'filter'));
  const wraps = { s: gl.TEXTURE_WRAP_S, t: gl.TEXTURE_WRAP_T, r: gl.TEXTURE_WRAP_R };
  for (const [axis, name] of Object.entries(meta.wrap || {})) {
    if (wraps[axis]) gl.texParameteri(target, wraps[axis], glEnum(gl, name, 'wrap'));
  }
  const aniso = caps.ext.anisotropic;
  if (aniso && meta.anisotropy > 1) {
    const max = gl.getParameter(aniso.MAX_TEXTURE_MAX_ANISOTROPY_EXT);
    gl.texParameterf(target, aniso.TEXTURE_MAX_ANISOTROPY_EXT, Math.min(meta.anisotropy, max));
  }
  gl.bindTexture(target, null);
  return { texture, target, halfFloat };
}

// -- meshes -------------------------------------------------------------------------------------

export function createMesh(gl, meta, vertexBytes, indexBytes) {
  const expectV = meta.vertex_count * meta.stride;
  const expectI = meta.index_count * 4;
  if (vertexBytes.byteLength !== expectV || indexBytes.byteLength !== expectI) {
    throw new Error(
      `mesh ${meta.vertices}: ${vertexBytes.byteLength} + ${indexBytes.byteLength} bytes, expected ${expectV} + ${expectI}`,
    );
  }
  const vbo = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(vertexBytes), gl.STATIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, null);
  gl.bindVertexArray(null);
  const ibo = gl.createBuffer();
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array(indexBytes), gl.STATIC_DRAW);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
  return { meta, vbo, ibo, count: meta.index_count };
}

/** A VAO binding the mesh's attributes by name (names the program does not use are skipped). */
export function createVertexArray(gl, program, mesh) {
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  gl.bindBuffer(gl.ARRAY_BUFFER, mesh.vbo);
  for (const a of mesh.meta.attributes) {
    const loc = gl.getAttribLocation(program, a.name);
    if (loc < 0) continue;
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, a.size, gl.FLOAT, false, mesh.meta.stride, a.offset);
  }
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, mesh.ibo);
  gl.bindVertexArray(null);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
  gl.bindBuffer(gl.ARRAY_BUFFER, null);
  return vao;
}

// -- programs -----------------------------------------------------------------------------------

/**
 * Exported shaders use `#line L N` with a file table comment `// source files: 1=a.frag, 2=b.glsl`;
 * rewrite the driver's `N:L` locations into `a.frag:L`.
 */
function nameSourceFiles(log, source) {
  const table = /^\/\/ source files: (.*)$/m.exec(source);
  if (!table) return log;
  const files = Object.fromEntries(table[1].split(', ').map((e) => e.split('=')));
  return log.replace(/\b(\d+):(\d+):/g, (m, id, line) => (files[id] ? `${files[id]}:${line}:` : m));
}

/** Compile and link; a failure throws an Error whose message carries the driver's log. */
export function compileProgram(gl, vertexSource, fragmentSource, label) {
  const shaders = [];
  const stage = (type, source, name) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    shaders.push(s);
    return [s, name];
  };
  const program = gl.createProgram();
  const stages = [stage(gl.VERTEX_SHADER, vertexSource, 'vertex'), stage(gl.FRAGMENT_SHADER, fragmentSource, 'fragment')];
  for (const [s] of stages) gl.attachShader(program, s);
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
    // Compile status is only queried on failure (KHR_parallel_shader_compile friendly).
    const logs = stages
      .filter(([s]) => !gl.getShaderParameter(s, gl.COMPILE_STATUS))
      .map(([s, name]) => {
        const source = name === 'vertex' ? vertexSource : fragmentSource;
        return `${name} shader: ${nameSourceFiles((gl.getShaderInfoLog(s) || '').trim(), source)}`;
      });
    if (!logs.length) logs.push(`link: ${(gl.getProgramInfoLog(program) || '').trim()}`);
    for (const s of shaders) gl.deleteShader(s);
    gl.deleteProgram(program);
    throw new Error(`${label}: ${logs.join('\n')}`);
  }
  for (const s of shaders) gl.deleteShader(s);
  return program;
}

// -- uniforms -----------------------------------------------------------------------------------

function uniformKinds(gl) {
  const f = (n, fn) => ({ n, set: (loc, v) => gl[fn](loc, v) });
  const m = (n, fn) => ({ n, set: (loc, v) => gl[fn](loc, false, v) });
  const kinds = {
    [gl.FLOAT]: f(1, 'uniform1fv'), [gl.FLOAT_VEC2]: f(2, 'uniform2fv'),
    [gl.FLOAT_VEC3]: f(3, 'uniform3fv'), [gl.FLOAT_VEC4]: f(4, 'uniform4fv'),
    [gl.INT]: f(1, 'uniform1iv'), [gl.INT_VEC2]: f(2, 'uniform2iv'),
    [gl.INT_VEC3]: f(3, 'uniform3iv'), [gl.INT_VEC4]: f(4, 'uniform4iv'),
    [gl.BOOL]: f(1, 'uniform1iv'), [gl.BOOL_VEC2]: f(2, 'uniform2iv'),
    [gl.BOOL_VEC3]: f(3, 'uniform3iv'), [gl.BOOL_VEC4]: f(4, 'uniform4iv'),
    [gl.UNSIGNED_INT]: f(1, 'uniform1uiv'), [gl.UNSIGNED_INT_VEC2]: f(2, 'uniform2uiv'),
    [gl.UNSIGNED_INT_VEC3]: f(3, 'uniform3uiv'), [gl.UNSIGNED_INT_VEC4]: f(4, 'uniform4uiv'),
    [gl.FLOAT_MAT2]: m(4, 'uniformMatrix2fv'), [gl.FLOAT_MAT3]: m(9, 'uniformMatrix3fv'),
    [gl.FLOAT_MAT4]: m(16, 'uniformMatrix4fv'), [gl.FLOAT_MAT2x3]: m(6, 'uniformMatrix2x3fv'),
    [gl.FLOAT_MAT2x4]: m(8, 'uniformMatrix2x4fv'), [gl.FLOAT_MAT3x2]: m(6, 'uniformMatrix3x2fv'),
    [gl.FLOAT_MAT3x4]: m(12, 'uniformMatrix3x4fv'), [gl.FLOAT_MAT4x2]: m(8, 'uniformMatrix4x2fv'),
    [gl.FLOAT_MAT4x3]: m(12, 'uniformMatrix4x3fv'),
  };
  const ints = new Set([gl.INT, gl.INT_VEC2, gl.INT_VEC3, gl.INT_VEC4, gl.BOOL, gl.BOOL_VEC2, gl.BOOL_VEC3, gl.BOOL_VEC4]);
  const uints = new Set([gl.UNSIGNED_INT, gl.UNSIGNED_INT_VEC2, gl.UNSIGNED_INT_VEC3, gl.UNSIGNED_INT_VEC4]);
  for (const [type, k] of Object.entries(kinds)) {
    k.array = ints.has(+type) ? Int32Array : uints.has(+type) ? Uint32Array : Float32Array;
  }
  return kinds;
}

const SAMPLER_TYPES = [
  'SAMPLER_2D', 'SAMPLER_3D', 'SAMPLER_CUBE', 'SAMPLER_2D_SHADOW', 'SAMPLER_2D_ARRAY',
  'SAMPLER_2D_ARRAY_SHADOW', 'SAMPLER_CUBE_SHADOW', 'INT_SAMPLER_2D', 'INT_SAMPLER_3D',
  'INT_SAMPLER_CUBE', 'INT_SAMPLER_2D_ARRAY', 'UNSIGNED_INT_SAMPLER_2D', 'UNSIGNED_INT_SAMPLER_3D',
  'UNSIGNED_INT_SAMPLER_CUBE', 'UNSIGNED_INT_SAMPLER_2D_ARRAY',
];

/**
 * The program's active uniforms by name (array names without "[0]"): {location, type, size, n, set}.
 * Samplers are listed apart, each with its own texture unit (set once here).
 */
export function programUniforms(gl, program) {
  const kinds = uniformKinds(gl);
  const samplerTypes = new Set(SAMPLER_TYPES.map((n) => gl[n]));
  const count = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
  const indices = Array.from({ length: count }, (_, i) => i);
  const blocks = count ? gl.getActiveUniforms(program, indices, gl.UNIFORM_BLOCK_INDEX) : [];
  const uniforms = new Map();
  const samplers = new Map();
  gl.useProgram(program);
  for (const i of indices) {
    if (blocks[i] !== -1) continue;
    const info = gl.getActiveUniform(program, i);
    const name = info.name.replace(/\[0\]$/, '');
    const location = gl.getUniformLocation(program, info.name);
    if (!location) continue;
    if (samplerTypes.has(info.type)) {
      const unit = samplers.size;
      gl.uniform1i(location, unit);
      samplers.set(name, { location, type: info.type, unit });
      continue;
    }
    const kind = kinds[info.type];
    if (!kind) continue;
    uniforms.set(name, { location, type: info.type, size: info.size, ...kind });
  }
  gl.useProgram(null);
  return { uniforms, samplers };
}

/** Set one uniform from a flat list of numbers, truncated to the active size. */
export function setUniform(u, values) {
  const length = Math.min(values.length, u.n * u.size);
  const whole = length - (length % u.n);
  if (whole <= 0) return;
  const data = new u.array(whole);
  for (let i = 0; i < whole; i++) data[i] = u.array === Float32Array ? values[i] : Math.round(values[i]);
  u.set(u.location, data);
}

// -- render targets -----------------------------------------------------------------------------

/** A colour texture (format 'RGBA32F' | 'RGBA16F' | 'RGBA8') + optional depth renderbuffer + FBO. */
export function createRenderTarget(gl, format, width, height, withDepth) {
  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  const type = { RGBA32F: gl.FLOAT, RGBA16F: gl.HALF_FLOAT, RGBA8: gl.UNSIGNED_BYTE }[format];
  gl.texImage2D(gl.TEXTURE_2D, 0, gl[format], width, height, 0, gl.RGBA, type, null);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.bindTexture(gl.TEXTURE_2D, null);
  const framebuffer = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, texture, 0);
  let depth = null;
  if (withDepth) {
    depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    gl.bindRenderbuffer(gl.RENDERBUFFER, null);
  }
  const status = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  if (status !== gl.FRAMEBUFFER_COMPLETE) {
    gl.deleteFramebuffer(framebuffer);
    gl.deleteTexture(texture);
    if (depth) gl.deleteRenderbuffer(depth);
    throw new Error(`${format} framebuffer incomplete (status 0x${status.toString(16)})`);
  }
  return {
    format, width, height, texture, framebuffer, depth,
    release() {
      gl.deleteFramebuffer(framebuffer);
      gl.deleteTexture(texture);
      if (depth) gl.deleteRenderbuffer(depth);
    },
  };
}

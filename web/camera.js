// Camera and matrix maths, identical to prefilter.scene.Camera (view_matrix, projection_matrix, at)
// and prefilter.scene.Light.at. Matrices are 4x4 Float64Array in column-major order (element (row r,
// column c) at [c * 4 + r]); `toGL` gives the Float32Array that gl.uniformMatrix4fv takes untransposed.

export const vec3 = {
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  scale: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  length: (a) => Math.hypot(a[0], a[1], a[2]),
  normalize: (a) => vec3.scale(a, 1 / Math.hypot(a[0], a[1], a[2])),
  lerp: (a, b, t) => [(1 - t) * a[0] + t * b[0], (1 - t) * a[1] + t * b[1], (1 - t) * a[2] + t * b[2]],
};

export function identity() {
  const m = new Float64Array(16);
  m[0] = m[5] = m[10] = m[15] = 1;
  return m;
}

/** A matrix from a list of 4 rows (the row-major nesting of scene.json's world_from_object). */
export function fromRows(rows) {
  const m = new Float64Array(16);
  for (let r = 0; r < 4; r++) for (let c = 0; c < 4; c++) m[c * 4 + r] = rows[r][c];
  return m;
}

export function get(m, r, c) {
  return m[c * 4 + r];
}

/** a · b */
export function multiply(a, b) {
  const out = new Float64Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      out[c * 4 + r] = s;
    }
  }
  return out;
}

/** General 4x4 inverse (cofactor expansion); throws on a singular matrix. */
export function inverse(m) {
  // aCR: column C, row R (the column-major storage order)
  const [a00, a01, a02, a03, a10, a11, a12, a13, a20, a21, a22, a23, a30, a31, a32, a33] = m;
  const b00 = a00 * a11 - a01 * a10, b01 = a00 * a12 - a02 * a10, b02 = a00 * a13 - a03 * a10;
  const b03 = a01 * a12 - a02 * a11, b04 = a01 * a13 - a03 * a11, b05 = a02 * a13 - a03 * a12;
  const b06 = a20 * a31 - a21 * a30, b07 = a20 * a32 - a22 * a30, b08 = a20 * a33 - a23 * a30;
  const b09 = a21 * a32 - a22 * a31, b10 = a21 * a33 - a23 * a31, b11 = a22 * a33 - a23 * a32;
  const det = b00 * b11 - b01 * b10 + b02 * b09 + b03 * b08 - b04 * b07 + b05 * b06;
  if (!det) throw new Error('matrix is singular');
  const d = 1 / det;
  return Float64Array.from([
    (a11 * b11 - a12 * b10 + a13 * b09) * d, (a02 * b10 - a01 * b11 - a03 * b09) * d,
    (a31 * b05 - a32 * b04 + a33 * b03) * d, (a22 * b04 - a21 * b05 - a23 * b03) * d,
    (a12 * b08 - a10 * b11 - a13 * b07) * d, (a00 * b11 - a02 * b08 + a03 * b07) * d,
    (a32 * b02 - a30 * b05 - a33 * b01) * d, (a20 * b05 - a22 * b02 + a23 * b01) * d,
    (a10 * b10 - a11 * b08 + a13 * b06) * d, (a01 * b08 - a00 * b10 - a03 * b06) * d,
    (a30 * b04 - a31 * b02 + a33 * b00) * d, (a21 * b02 - a20 * b04 - a23 * b00) * d,
    (a11 * b07 - a10 * b09 - a12 * b06) * d, (a00 * b09 - a01 * b07 + a02 * b06) * d,
    (a31 * b01 - a30 * b03 - a32 * b00) * d, (a20 * b03 - a21 * b01 + a22 * b00) * d,
  ]);
}

/** m · (x, y, z, w) */
export function transform(m, v) {
  const out = [0, 0, 0, 0];
  for (let r = 0; r < 4; r++) {
    out[r] = m[r] * v[0] + m[4 + r] * v[1] + m[8 + r] * v[2] + m[12 + r] * v[3];
  }
  return out;
}

/** Column-major float32 for gl.uniformMatrix4fv(loc, false, ...). */
export function toGL(m) {
  return Float32Array.from(m);
}

/**
 * u_worldNormalFromObject: inverse(world_from_object[0:3, 0:3]) written row by row, as the Python
 * renderer uploads it; GL reads it column-major, i.e. as the inverse-transpose.
 */
export function normalMatrix(world) {
  const a = (r, c) => world[c * 4 + r];
  const det =
    a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
    a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
    a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
  if (!det) throw new Error('world_from_object is singular');
  const inv = new Float32Array(9); // row-major inverse
  for (let r = 0; r < 3; r++) {
    for (let c = 0; c < 3; c++) {
      // inverse[r][c] = cofactor[c][r] / det
      const rows = [0, 1, 2].filter((i) => i !== c);
      const cols = [0, 1, 2].filter((i) => i !== r);
      const minor = a(rows[0], cols[0]) * a(rows[1], cols[1]) - a(rows[0], cols[1]) * a(rows[1], cols[0]);
      inv[r * 3 + c] = ((r + c) % 2 ? -minor : minor) / det;
    }
  }
  return inv;
}

/** Camera pose at animation time t (Camera.at): eye and target move linearly to their _end values. */
export function cameraAt(camera, t) {
  return {
    ...camera,
    eye: camera.eye_end ? vec3.lerp(camera.eye, camera.eye_end, t) : [...camera.eye],
    target: camera.target_end ? vec3.lerp(camera.target, camera.target_end, t) : [...camera.target],
  };
}

/** Light at time t (Light.at): direction interpolated and renormalised. */
export function lightAt(light, t) {
  if (!light.direction_end) return { direction: light.direction, colour: light.colour };
  return { direction: vec3.normalize(vec3.lerp(light.direction, light.direction_end, t)), colour: light.colour };
}

/** cameraFromWorld: right-handed look-at, camera looks down -z (Camera.view_matrix). */
export function viewMatrix(camera) {
  const forward = vec3.normalize(vec3.sub(camera.target, camera.eye));
  const right = vec3.normalize(vec3.cross(forward, camera.up));
  const up = vec3.cross(right, forward);
  const rows = [right, up, vec3.scale(forward, -1)];
  const m = identity();
  for (let r = 0; r < 3; r++) {
    for (let c = 0; c < 3; c++) m[c * 4 + r] = rows[r][c];
    m[12 + r] = -vec3.dot(rows[r], camera.eye);
  }
  return m;
}

/** clipFromCamera with OpenGL conventions (Camera.projection_matrix). */
export function projectionMatrix(camera, aspect) {
  const n = camera.near, f = camera.far;
  const m = new Float64Array(16);
  const set = (r, c, v) => { m[c * 4 + r] = v; };
  if (camera.projection === 'orthographic') {
    const h = camera.height / 2;
    set(0, 0, 1 / (h * aspect));
    set(1, 1, 1 / h);
    set(2, 2, -2 / (f - n));
    set(2, 3, -(f + n) / (f - n));
    set(3, 3, 1);
    return m;
  }
  const t = 1 / Math.tan((camera.fov * Math.PI) / 180 / 2);
  set(0, 0, t / aspect);
  set(1, 1, t);
  set(2, 2, -(f + n) / (f - n));
  set(2, 3, (-2 * f * n) / (f - n));
  set(3, 2, -1);
  return m;
}

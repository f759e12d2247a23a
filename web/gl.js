// SPDX-License-Identifier: MIT
// WebGL 1 helpers: the shared GLSL ES 1.00 shaders of src/shaders (served
// at /shaders/NAME.glsl), #include expansion, programs, matrices.

const shaderCache = new Map();

async function fetchShader(name) {
  if (!shaderCache.has(name)) {
    shaderCache.set(name, fetch(`/shaders/${name}.glsl`).then((response) => {
      if (!response.ok) throw new Error(`shader ${name}: HTTP ${response.status}`);
      return response.text();
    }));
  }
  return shaderCache.get(name);
}

/**
 * The shader text with every line `#include "NAME"` (at the start of a line)
 * replaced by that file, the rest of the directive's line dropped: the rule
 * of lk__gl_program in src/gl/context.c (one level deep).
 */
export async function loadShaderSource(name) {
  const text = await fetchShader(name);
  const directive = '#include "';
  let out = '';
  let rest = 0;
  let search = 0;
  for (;;) {
    const found = text.indexOf(directive, search);
    if (found < 0) break;
    if (found !== 0 && text[found - 1] !== '\n') {
      search = found + 1;
      continue;
    }
    const nameStart = found + directive.length;
    const nameEnd = text.indexOf('"', nameStart);
    if (nameEnd < 0) throw new Error(`shader ${name}: malformed #include`);
    const included = text.slice(nameStart, nameEnd).replace(/\.glsl$/, '');
    out += text.slice(rest, found) + (await fetchShader(included));
    const lineEnd = text.indexOf('\n', nameEnd);
    rest = search = lineEnd >= 0 ? lineEnd + 1 : nameEnd + 1;
  }
  return out + text.slice(rest);
}

function compile(gl, type, name, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
    const log = gl.getShaderInfoLog(shader);
    gl.deleteShader(shader);
    throw new Error(`compiling shader ${name} failed: ${log}`);
  }
  return shader;
}

/**
 * Links vertex + fragment shader (names without .glsl, e.g. 'mesh.vert')
 * with `attributes` bound to locations 0, 1, ... as the C renderer does.
 * Returns { program, uniform(name) }.
 */
export async function createProgram(gl, vertexName, fragmentName, attributes) {
  const [vertexSource, fragmentSource] = await Promise.all([loadShaderSource(vertexName), loadShaderSource(fragmentName)]);
  const vertex = compile(gl, gl.VERTEX_SHADER, vertexName, vertexSource);
  const fragment = compile(gl, gl.FRAGMENT_SHADER, fragmentName, fragmentSource);
  const program = gl.createProgram();
  gl.attachShader(program, vertex);
  gl.attachShader(program, fragment);
  attributes.forEach((attribute, location) => gl.bindAttribLocation(program, location, attribute));
  gl.linkProgram(program);
  gl.deleteShader(vertex);
  gl.deleteShader(fragment);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS))
    throw new Error(`linking ${vertexName} + ${fragmentName} failed: ${gl.getProgramInfoLog(program)}`);
  const locations = new Map();
  return {
    program,
    uniform(uniformName) {
      if (!locations.has(uniformName)) locations.set(uniformName, gl.getUniformLocation(program, uniformName));
      return locations.get(uniformName);
    },
  };
}

/** The key light of the C renderer (LK__KEY_LIGHT_DIRECTION, eye space). */
export const KEY_LIGHT_DIRECTION = new Float32Array([-0.4444, 0.6667, 0.5981]);

/** Default surface colour of lk_render_options_default (light grey-blue). */
export const SURFACE_COLOR = [0.7, 0.76, 0.86];

/** Column-major perspective projection. */
export function perspective(fovYDegrees, aspect, near, far) {
  const f = 1 / Math.tan((fovYDegrees * Math.PI) / 360);
  const m = new Float32Array(16);
  m[0] = f / aspect;
  m[5] = f;
  m[10] = (far + near) / (near - far);
  m[11] = -1;
  m[14] = (2 * far * near) / (near - far);
  return m;
}

/** View matrix (column-major) from an eye and the camera's right, up, back axes. */
export function viewFromAxes(eye, right, up, back) {
  const m = new Float32Array(16);
  const axes = [right, up, back];
  for (let row = 0; row < 3; row++) {
    const axis = axes[row];
    for (let col = 0; col < 3; col++) m[col * 4 + row] = axis[col];
    m[12 + row] = -(axis[0] * eye[0] + axis[1] * eye[1] + axis[2] * eye[2]);
  }
  m[15] = 1;
  return m;
}

/** The rotation part of a view matrix (3x3 column-major): normals to eye space. */
export function normalMatrix(view) {
  return new Float32Array([view[0], view[1], view[2], view[4], view[5], view[6], view[8], view[9], view[10]]);
}

export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const normalize = (a) => {
  const length = Math.hypot(a[0], a[1], a[2]) || 1;
  return [a[0] / length, a[1] / length, a[2] / length];
};

/** Bounding box of packed xyz positions. */
export function bounds(positions, count = positions.length / 3) {
  const min = [Infinity, Infinity, Infinity];
  const max = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < count; i++)
    for (let a = 0; a < 3; a++) {
      const value = positions[3 * i + a];
      if (value < min[a]) min[a] = value;
      if (value > max[a]) max[a] = value;
    }
  if (count === 0) return { min: [0, 0, 0], max: [0, 0, 0] };
  return { min, max };
}

/**
 * Per-vertex normals: the sum of the area-weighted face normals around each
 * vertex (as face_averaged_normals in src/gl/mesh_draw.c). `triangles` is a
 * callback visiting (a, b, c) for every drawn triangle.
 */
export function faceAveragedNormals(positions, vertexCount, forEachTriangle) {
  const normals = new Float32Array(3 * vertexCount);
  const p = positions;
  forEachTriangle((a, b, c) => {
    const ux = p[3 * b] - p[3 * a], uy = p[3 * b + 1] - p[3 * a + 1], uz = p[3 * b + 2] - p[3 * a + 2];
    const vx = p[3 * c] - p[3 * a], vy = p[3 * c + 1] - p[3 * a + 1], vz = p[3 * c + 2] - p[3 * a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    normals[3 * a] += nx; normals[3 * a + 1] += ny; normals[3 * a + 2] += nz;
    normals[3 * b] += nx; normals[3 * b + 1] += ny; normals[3 * b + 2] += nz;
    normals[3 * c] += nx; normals[3 * c + 1] += ny; normals[3 * c + 2] += nz;
  });
  for (let v = 0; v < vertexCount; v++) {
    const length = Math.hypot(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
    if (length > 0 && Number.isFinite(length)) {
      normals[3 * v] /= length; normals[3 * v + 1] /= length; normals[3 * v + 2] /= length;
    } else {
      normals[3 * v] = 0; normals[3 * v + 1] = 1; normals[3 * v + 2] = 0;
    }
  }
  return normals;
}

/**
 * Element indices for WebGL 1: 16-bit when every vertex fits, else 32-bit
 * with OES_element_index_uint. Returns { array, type } or throws.
 */
export function elementArray(gl, indices, length, vertexCount) {
  if (vertexCount <= 65536) {
    const array = new Uint16Array(length);
    for (let i = 0; i < length; i++) array[i] = indices[i];
    return { array, type: gl.UNSIGNED_SHORT };
  }
  if (!gl.getExtension('OES_element_index_uint'))
    throw new Error(`${vertexCount} vertices need 32-bit indices (OES_element_index_uint), which this WebGL lacks`);
  return { array: indices.subarray ? indices.subarray(0, length) : new Uint32Array(indices.slice(0, length)), type: gl.UNSIGNED_INT };
}

/** LKMB buffer: the mesh / point-set format of lodkit serve (docs/server.md). */
export function parseLkmb(buffer) {
  const bytes = new Uint8Array(buffer);
  if (bytes.length < 24 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'LKMB') throw new Error('not an LKMB buffer');
  const view = new DataView(buffer);
  const version = view.getUint32(4, true);
  if (version !== 1) throw new Error(`LKMB version ${version} is not supported`);
  const vertexCount = view.getUint32(8, true);
  const triangleCount = view.getUint32(12, true);
  const flags = view.getUint32(16, true);
  let offset = 24;
  const need = 24 + vertexCount * (12 + (flags & 1 ? 12 : 0) + (flags & 2 ? 4 : 0) + (flags & 4 ? 4 : 0) + (flags & 8 ? 4 : 0)) +
    12 * triangleCount;
  if (bytes.length < need) throw new Error(`LKMB buffer of ${bytes.length} bytes is shorter than its counts say (${need})`);
  // Copies (not views): the float arrays need 4-byte alignment.
  const floats = (count) => {
    const array = new Float32Array(buffer.slice(offset, offset + 4 * count));
    offset += 4 * count;
    return array;
  };
  const positions = floats(3 * vertexCount);
  const normals = flags & 1 ? floats(3 * vertexCount) : null;
  let colors = null;
  if (flags & 2) {
    colors = new Uint8Array(buffer.slice(offset, offset + 4 * vertexCount));
    offset += 4 * vertexCount;
  }
  const radii = flags & 4 ? floats(vertexCount) : null;
  // Clip lines of border splats: direction and offset in radii, signed bytes / 127.
  let clips = null;
  if (flags & 8) {
    clips = new Int8Array(buffer.slice(offset, offset + 4 * vertexCount));
    offset += 4 * vertexCount;
  }
  const indices = new Uint32Array(buffer.slice(offset, offset + 12 * triangleCount));
  return { vertexCount, triangleCount, flags, positions, normals, colors, radii, clips, indices };
}

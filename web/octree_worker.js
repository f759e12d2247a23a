// SPDX-License-Identifier: MIT
// Worker of the octree view (web/octree_view.js): fetches one node of a
// point octree by an HTTP Range request on its data file, checks its
// length and CRC-32 (the index's), and decodes it (docs/formats.md, "Point
// octree") into one interleaved vertex array, 36 bytes a point:
//   x y z (float32, relative to the cloud's offset), nx ny nz (float32),
//   radius (float32, as stored: version 2's are the points' own, which
//   the vertex shader floors), r g b a (uint8), clip line (4 x int8, as stored;
//   zeros when the octree has none: nothing cut)
// so the page's thread only uploads. Messages in:
//   { id, url, offset, length, points, stride, scale: [sx, sy, sz],
//     layout: { rgb, normal, radius, clip } (byte offsets in a record or -1), crc32 }
//   { abort: id }
// out: { id, vertices (ArrayBuffer, transferred), points, clipped (points
// with a clip line), status, bytes } or { id, error }.

import { crc32 } from './stream.js';

const VERTEX_BYTES = 36; // web/octree_view.js binds the same layout
const controllers = new Map();

function decode(bytes, job) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = new ArrayBuffer(job.points * VERTEX_BYTES);
  const floats = new Float32Array(out);
  const colours = new Uint8Array(out);
  const [sx, sy, sz] = job.scale;
  const { rgb, normal, radius, clip } = job.layout;
  let clipped = 0;
  for (let i = 0; i < job.points; i++) {
    const record = i * job.stride;
    const f = i * 9;
    floats[f] = view.getInt32(record, true) * sx;
    floats[f + 1] = view.getInt32(record + 4, true) * sy;
    floats[f + 2] = view.getInt32(record + 8, true) * sz;
    if (normal >= 0) {
      // octahedral, as lk__octree_oct_decode
      let x = (view.getUint16(record + normal, true) / 65535) * 2 - 1;
      let y = (view.getUint16(record + normal + 2, true) / 65535) * 2 - 1;
      const z = 1 - Math.abs(x) - Math.abs(y);
      if (z < 0) {
        const fx = (1 - Math.abs(y)) * (x >= 0 ? 1 : -1);
        const fy = (1 - Math.abs(x)) * (y >= 0 ? 1 : -1);
        x = fx;
        y = fy;
      }
      const length = Math.hypot(x, y, z) || 1;
      floats[f + 3] = x / length;
      floats[f + 4] = y / length;
      floats[f + 5] = z / length;
    } else {
      floats[f + 5] = 1;
    }
    floats[f + 6] = radius >= 0 ? view.getFloat32(record + radius, true) : job.spacing;
    const c = f * 4 + 28;
    if (rgb >= 0) {
      colours[c] = bytes[record + rgb];
      colours[c + 1] = bytes[record + rgb + 1];
      colours[c + 2] = bytes[record + rgb + 2];
    } else {
      colours[c] = 179; // SURFACE_COLOR of web/gl.js, 0.7 0.76 0.86
      colours[c + 1] = 194;
      colours[c + 2] = 219;
    }
    colours[c + 3] = 255;
    if (clip >= 0) {
      colours[c + 4] = bytes[record + clip];
      colours[c + 5] = bytes[record + clip + 1];
      colours[c + 6] = bytes[record + clip + 2];
      colours[c + 7] = bytes[record + clip + 3];
      if (colours[c + 4] || colours[c + 5] || colours[c + 6]) clipped++;
    }
  }
  return { vertices: out, clipped };
}

async function load(job) {
  const controller = new AbortController();
  controllers.set(job.id, controller);
  try {
    const last = job.offset + job.length - 1;
    const response = await fetch(job.url, { headers: { Range: `bytes=${job.offset}-${last}` }, signal: controller.signal });
    if (response.status !== 206 && response.status !== 200) throw new Error(`${job.url}: HTTP ${response.status}`);
    let bytes = new Uint8Array(await response.arrayBuffer());
    // A server without Range support sends the whole file (200): cut the node out.
    if (response.status === 200) bytes = bytes.subarray(job.offset, job.offset + job.length);
    if (bytes.length !== job.length)
      throw new Error(`${job.url}: node ${job.name}: ${bytes.length} bytes instead of ${job.length}`);
    if (crc32(bytes) !== job.crc32) throw new Error(`${job.url}: node ${job.name}: CRC-32 mismatch (corrupt data)`);
    const { vertices, clipped } = decode(bytes, job);
    postMessage({ id: job.id, vertices, points: job.points, clipped, status: response.status, bytes: bytes.length },
      [vertices]);
  } catch (error) {
    postMessage({ id: job.id, error: String(error && error.message ? error.message : error), aborted: controller.signal.aborted });
  } finally {
    controllers.delete(job.id);
  }
}

self.onmessage = (event) => {
  const message = event.data;
  if (message.abort !== undefined) {
    const controller = controllers.get(message.abort);
    if (controller) controller.abort();
    return;
  }
  load(message);
};

// SPDX-License-Identifier: MIT
// The viewer's version-2 stream decoders (web/stream.js + web/stream2.js,
// and with STREAM2_WASM the C decoder built as WebAssembly through
// web/stream2_wasm.js) in node, against the C decoder (`lodkit unpack`),
// run by tests/cli/test_web_stream2.sh:
//   node stream2.test.mjs LODKIT SAMPLES_DIR WORK_DIR [STREAM2_WASM]
// For the bunny, the cow, the fandisk, assimp's spider (its normals and
// texture coordinates travel in the stream) and a made-up non-manifold mesh
// (sheets with borders, welded at a bowtie vertex and three on an edge: open
// and unordered fans, fans whose triangles share a `prev`, restored
// triangles named one by one, none of which the closed meshes have): a v2 stream written by `lodkit
// progressive --stream-version 2`, decoded in pieces; positions (float bits)
// and triangles equal unpack's PLY at the full level, at level 0 and at a
// level inside a chunk (rebuilt from the split log). A chunk changed after
// encoding, its CRCs re-sealed, is refused with C's own message (chunk and
// byte named), the level of the chunk before is kept, and the decoder's
// mesh, fed the true chunk afterwards, decodes on to the same full mesh (so
// the take-back restored every corner list). Prints one line per check and
// exits 1 when any fails. Needs no browser and no node_modules.

import { execFileSync, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { StreamDecoder, crc32 } from '../../web/stream.js';
import { Stream2State } from '../../web/stream2.js';
import { loadStream2Wasm, Stream2Wasm } from '../../web/stream2_wasm.js';

const [lodkit, samples, work, wasmFile] = process.argv.slice(2);
if (!lodkit || !samples || !work) {
  console.error('usage: node stream2.test.mjs LODKIT SAMPLES_DIR WORK_DIR [STREAM2_WASM]');
  process.exit(2);
}
// The decoders under test: web/stream2.js, and the C decoder built for the
// browser (stream2.wasm, web/stream2_wasm.js) when its path is given.
const kinds = [['JS', null]];
if (wasmFile) {
  const wasm = await loadStream2Wasm(fs.readFileSync(wasmFile));
  kinds.push(['wasm', (info, headerBytes) => new Stream2Wasm(wasm, info, headerBytes)]);
}
let checks = 0;
let failures = 0;
function check(description, condition, detail = '') {
  checks++;
  if (!condition) failures++;
  console.log(`${condition ? 'ok' : 'not ok'} - ${description}${detail ? ` (${detail})` : ''}`);
  return condition;
}

/* A binary little-endian PLY as lodkit writes it: float x y z, uchar-int triangle lists. */
function readPly(file) {
  const bytes = fs.readFileSync(file);
  const end = bytes.indexOf('end_header\n') + 'end_header\n'.length;
  const header = bytes.subarray(0, end).toString();
  if (!/format binary_little_endian 1.0/.test(header) || !/property list uchar int vertex_indices/.test(header))
    throw new Error(`${file}: not the PLY layout this test reads`);
  const vertexCount = Number(/element vertex (\d+)/.exec(header)[1]);
  const faceCount = Number(/element face (\d+)/.exec(header)[1]);
  // x y z first, then any attributes (normals, texture coordinates: floats; colours: uchar)
  const vertexPart = header.slice(header.indexOf('element vertex'), header.indexOf('element face'));
  const properties = [...vertexPart.matchAll(/property (float|uchar) (\w+)/g)].map((m) => m[1]);
  const stride = properties.reduce((sum, type) => sum + (type === 'float' ? 4 : 1), 0);
  const positions = new Float32Array(3 * vertexCount);
  let at = end;
  for (let v = 0; v < vertexCount; v++, at += stride)
    for (let a = 0; a < 3; a++) positions[3 * v + a] = bytes.readFloatLE(at + 4 * a);
  const triangles = new Uint32Array(3 * faceCount);
  for (let f = 0; f < faceCount; f++) {
    if (bytes[at++] !== 3) throw new Error(`${file}: face ${f} is not a triangle`);
    for (let k = 0; k < 3; k++, at += 4) triangles[3 * f + k] = bytes.readInt32LE(at);
  }
  return { vertexCount, positions, triangles };
}

/* Same vertex count, same float bits of every coordinate, same triangles in the same order. */
function sameMesh(geometry, expected) {
  if (geometry.vertexCount !== expected.vertexCount) return `${geometry.vertexCount} vertices, C has ${expected.vertexCount}`;
  if (geometry.triangles.length !== expected.triangles.length)
    return `${geometry.triangles.length / 3} triangles, C has ${expected.triangles.length / 3}`;
  const a = new Uint32Array(geometry.positions.buffer, geometry.positions.byteOffset, geometry.positions.length);
  const b = new Uint32Array(expected.positions.buffer, expected.positions.byteOffset, expected.positions.length);
  for (let i = 0; i < a.length; i++) if (a[i] !== b[i]) return `coordinate ${i} differs: ${geometry.positions[i]} vs ${expected.positions[i]}`;
  for (let i = 0; i < geometry.triangles.length; i++)
    if (geometry.triangles[i] !== expected.triangles[i]) return `triangle corner ${i} differs`;
  return '';
}

const unpack = (stream, out, level) =>
  execFileSync(lodkit, ['unpack', '-q', ...(level === undefined ? [] : [`--level=${level}`]), stream, out]);

/* A copy of the stream with one byte of chunk `index`'s payload changed and every CRC re-sealed. */
function corrupted(file, chunks, index, byteInPayload) {
  const bytes = Buffer.from(file);
  const chunk = chunks[index];
  bytes[chunk.offset + 8 + byteInPayload] ^= 0x10;
  const crc = crc32(bytes.subarray(chunk.offset + 8, chunk.offset + chunk.size));
  bytes.writeUInt32LE(crc, chunk.offset + 4);
  bytes.writeUInt32LE(crc, 96 + 32 * index + 28);
  bytes.writeUInt32LE(crc32(bytes.subarray(96, 96 + 32 * chunks.length)), 96 + 32 * chunks.length);
  return bytes;
}

/* Bumpy sheets with borders welded at one vertex (a bowtie) and along two
 * edges (three sheets on an edge), as an OBJ. */
function nonManifoldObj(file) {
  const lines = [], faces = [], index = new Map();
  const vertex = (p) => {
    const key = p.map((x) => (x + 0).toFixed(9)).join(' ');
    if (!index.has(key)) {
      index.set(key, index.size + 1);
      lines.push(`v ${key}`);
    }
    return index.get(key);
  };
  const sheet = (n, place) => {
    const id = (i, j) => vertex(place(i / n, j / n));
    for (let j = 0; j < n; j++)
      for (let i = 0; i < n; i++) {
        const a = id(i, j), b = id(i + 1, j), c = id(i, j + 1), d = id(i + 1, j + 1);
        faces.push(`f ${a} ${b} ${d}`, `f ${a} ${d} ${c}`);
      }
  };
  const bump = (x, y) => 0.05 * Math.sin(7 * x) * Math.cos(5 * y);
  sheet(16, (x, y) => [x, y, bump(x, y)]);
  sheet(16, (x, y) => [-x, -y, bump(x, y)]); // the bowtie at (0, 0, 0)
  sheet(16, (x, y) => [x, 0, bump(x, 0) + 0.6 * y]); // a fin on the edge y = 0
  sheet(16, (x, y) => [1 + 0.7 * x, y, bump(1, y) + 0.3 * x * y]); // a third sheet on the edge x = 1
  fs.writeFileSync(file, `${lines.join('\n')}\n${faces.join('\n')}\n`);
  return file;
}

// Which fan shapes (and pairwise orderings) the decoder met, per stream.
const met = { shapes: [0, 0, 0], pairwise: 0 };
const orderFan = Stream2State.prototype.orderFan;
Stream2State.prototype.orderFan = function (k) {
  const shape = orderFan.call(this, k);
  met.shapes[shape]++;
  return shape;
};
const orderFanPairwise = Stream2State.prototype.orderFanPairwise;
Stream2State.prototype.orderFanPairwise = function (k) {
  met.pairwise++;
  return orderFanPairwise.call(this, k);
};

// A model, or [name, null, stream] for a stream kept in tests/data: spider-v2-axes.lks was written by lodkit
// before split positions moved to their ring's frame (header flag 8; lodkit progressive at 11 bits, commit
// 198732f5), and must still decode.
const models = [['bunny', path.join(samples, 'bunny.obj')], ['cow', path.join(samples, 'cow.off')],
  ['fandisk', path.join(samples, 'fandisk.off')], ['non-manifold sheets', nonManifoldObj(path.join(work, 'sheets.obj'))],
  ['spider (normals, texture coordinates)', path.join(samples, 'assimp', 'OBJ', 'spider.obj')],
  ['spider (normals, texture coordinates), positions axis by axis', null,
    path.join(path.dirname(fileURLToPath(import.meta.url)), '..', 'data', 'stream', 'spider-v2-axes.lks')]];
for (const [model, source, storedStream] of models)
for (const [kind, createStream2] of kinds) {
  const name = `${kind}: ${model}`;
  const slug = `${kind}-${model}`.replace(/[ (),:]+/g, '-');
  const stream = path.join(work, `${slug}.lks`);
  if (storedStream) fs.copyFileSync(storedStream, stream);
  else execFileSync(lodkit, ['progressive', '-q', '--stream-version=2', source, stream]);
  const file = fs.readFileSync(stream);

  // the whole stream, fed in 777-byte pieces
  met.shapes = [0, 0, 0];
  met.pairwise = 0;
  const decoder = new StreamDecoder({ createStream2 });
  const started = performance.now();
  try {
    for (let offset = 0; offset < file.length; offset += 777) await decoder.feed(file.subarray(offset, offset + 777));
  } catch (error) {
    check(`${name}: the stream decodes`, false, error.message);
    continue;
  }
  const milliseconds = performance.now() - started;
  const info = decoder.info;
  if (model.startsWith('spider'))
    check(`${name}: the stream carries normals and texture coordinates`, (decoder.info.flags & 7) === 3, `flags ${decoder.info.flags}`);
  check(`${name}: split positions are coded ${storedStream ? 'axis by axis' : 'in their ring\'s frame'}`,
    (decoder.info.flags & 8) === (storedStream ? 0 : 8), `flags ${decoder.info.flags}`);
  check(`${name}: a version-2 stream decodes to its full level`, decoder.done && decoder.version === 2 &&
    decoder.level === info.splitCount, `${info.chunkCount} chunks, ${file.length} bytes, ${milliseconds.toFixed(0)} ms in node`);
  if (model === 'non-manifold sheets' && kind === 'JS')
    check(`${name}: open and unordered fans, and fans ordered pairwise, were decoded`,
      met.shapes[0] > 0 && met.shapes[1] > 0 && met.pairwise > 0,
      `${met.shapes[0]} unordered, ${met.shapes[1]} open, ${met.shapes[2]} closed, ${met.pairwise} pairwise`);
  const full = decoder.levelGeometry(decoder.level);
  const file2 = (suffix) => path.join(work, `${slug}${suffix}`);
  unpack(stream, file2('.ply'));
  const fullDifference = sameMesh(full, readPly(file2('.ply')));
  check(`${name}: positions and triangles equal lodkit unpack's exactly`, !fullDifference && full.triangles.length / 3 === info.triangleCount,
    fullDifference || `${full.vertexCount} vertices, ${full.triangles.length / 3} triangles`);

  // lower levels rebuilt from the split log: 0 and one inside a chunk
  const inside = decoder.chunks[Math.min(3, info.chunkCount - 1)];
  for (const level of [0, inside.firstSplit + (inside.splitCount >> 1) + 1, info.splitCount - 1]) {
    unpack(stream, file2(`-${level}.ply`), level);
    const difference = sameMesh(decoder.levelGeometry(level), readPly(file2(`-${level}.ply`)));
    check(`${name}: level ${level} from the split log equals lodkit unpack --level=${level}`, !difference, difference);
  }
  check(`${name}: the full level is unchanged by the lower levels' rebuilds`, !sameMesh(decoder.levelGeometry(decoder.level), full));

  // a corrupt chunk with matching CRCs: refused as C refuses it, taken back whole
  const index = Math.min(model === 'bunny' ? 5 : 2, info.chunkCount - 1);
  const chunk = decoder.chunks[index];
  const bad = corrupted(file, decoder.chunks, index, chunk.size >> 2);
  const badPath = file2('-bad.lks');
  fs.writeFileSync(badPath, bad);
  const broken = new StreamDecoder({ createStream2 });
  let message = '';
  try {
    await broken.feed(bad);
  } catch (error) {
    message = error.message;
  }
  const c = spawnSync(lodkit, ['unpack', '-q', badPath, file2('-bad.ply')], { encoding: 'utf8' });
  const cMessage = (/^lodkit: [^:]*: (chunk .*)$/m.exec(c.stderr) || [])[1] || '';
  check(`${name}: a corrupt chunk ${index} (CRCs re-sealed) is refused, naming the chunk, with C's message`,
    new RegExp(`^chunk ${index} at byte ${chunk.offset}: `).test(message) && !/CRC/.test(message) && message === cMessage &&
      c.status === 1, `${kind} "${message}", C "${cMessage}"`);
  const kept = broken.level === chunk.firstSplit;
  const keptDifference = sameMesh(broken.levelGeometry(broken.level), readPly(file2('-bad.ply')));
  check(`${name}: the level of chunk ${index - 1} is kept, equal to what C kept`, kept && !keptDifference,
    `level ${broken.level}, chunk ${index} starts at ${chunk.firstSplit}${keptDifference ? '; ' + keptDifference : ''}`);
  let againDifference = 'not run';
  try {
    // the true chunks from there on, straight into the decoder's mesh
    for (let i = index; i < info.chunkCount; i++) {
      const c2 = decoder.chunks[i];
      broken.state.applyChunk(file.subarray(c2.offset + 8, c2.offset + c2.size), c2);
    }
    againDifference = sameMesh(broken.levelGeometry(broken.level), full);
  } catch (error) {
    againDifference = error.message;
  }
  check(`${name}: after the take-back, the true chunks decode on to the same full mesh`, !againDifference, againDifference);
  decoder.dispose(); // the module's memory back, for the next model
  broken.dispose();
}

console.log(`${checks} checks, ${failures} failed`);
process.exit(failures ? 1 : 0);

// SPDX-License-Identifier: MIT
// Decoder of version-2 progressive stream payloads (.lks v2), written from
// docs/stream-format.md, section "Version 2", and checked bit for bit
// against the C decoder (src/stream2_decode.c, src/stream2_mesh.c) by
// tests/browser/stream2.test.mjs. The container (header, chunk table, CRCs,
// buffering) is web/stream.js's: it hands each chunk's payload to
// Stream2State.decodeBase or Stream2State.applyChunk.
//
// The mesh: quantised positions (Int32Array, 3 per vertex) and triangles
// (Uint32Array, 3 corners per triangle, growing as splits restore them),
// and per vertex a linked list of its corners (head / nextCorner), so a
// split touches only the triangles around one vertex. Every split is
// logged (p, p's old position, the triangles moved to q, the triangle
// count before): a chunk that fails half-way is taken back from the log,
// and levelGeometry(level) rebuilds any lower level from it.
//
// Integers: positions are below 2^24 and every sum and dot product the
// format asks for stays below 2^53, so Numbers hold them exactly; the
// range coder's 32-bit registers are kept unsigned with >>> 0.

const NONE = 0xffffffff;
const PROB_INIT = 2048; // P(bit = 0) in 1/4096
const TOP = 1 << 24;
const LENGTH_BITS = 6;
const MAX_ESCAPED = 8; // restored triangles named one by one, at most
const MAX_TRIANGLES_PER_SPLIT = 8;
const SYMBOLS_PER_BYTE = 64; // no base vertex, triangle or split costs less than 1/64 byte

/* A split chunk or base chunk payload that cannot be decoded. */
export class PayloadError extends Error {
  constructor(message) {
    super(message);
    this.name = 'PayloadError';
  }
}

// ---- models: one Uint16Array of probabilities, reset at every chunk -------

// An unsigned-integer model set: a 6-bit length tree, then per length a
// 2-bit tree (4 probabilities, index 0 unused) for the bits under the lead.
const UINT_MODEL = (1 << LENGTH_BITS) + 33 * 4;
const SPLIT_CONTEXTS = 11; // "is v a split vertex": one per triangle count, the last for that or more
const M_SPLIT = 0;
const M_BATCH = M_SPLIT + SPLIT_CONTEXTS;
const M_ESCAPE = M_BATCH + UINT_MODEL;
const M_RESIDUAL = M_ESCAPE + UINT_MODEL; // 3 of them, one per axis
const M_CORNER = M_RESIDUAL + 3 * UINT_MODEL; // 3, one per corner of a base triangle
const M_MOVE = M_CORNER + 3 * UINT_MODEL; // 96 bits
const M_PREDICTED_OK = M_MOVE + 96; // 2
const M_ORIENTATION = M_PREDICTED_OK + 2; // 1
const M_KIND = M_ORIENTATION + 1; // a 2-bit tree: 4
const M_ATTRIBUTE = M_KIND + 4; // 8, one per attribute component
const MODEL_COUNT = M_ATTRIBUTE + 8 * UINT_MODEL;

// Header flags of the attributes each vertex carries after its position.
const FLAG_NORMALS = 1, FLAG_TEXCOORDS = 2, FLAG_COLORS = 4;
// Header flag: split positions are coded in their ring's frame (readInFrame).
const FLAG_RING_FRAME = 8;

/* The adaptive binary range decoder (LZMA's, docs: "Range decoder"). */
class RangeDecoder {
  constructor(data, probs) {
    this.data = data;
    this.size = data.length;
    this.position = 0;
    this.overrun = false; // read past the end: the payload is corrupt or cut
    this.probs = probs;
    this.range = 0xffffffff;
    this.code = 0;
    for (let i = 0; i < 4; i++) this.code = ((this.code << 8) | this.byte()) >>> 0;
  }

  byte() {
    if (this.position < this.size) return this.data[this.position++];
    this.overrun = true;
    return 0;
  }

  /* A bit with the model at probs[index]. */
  bit(index) {
    const probs = this.probs;
    const prob = probs[index];
    const bound = (this.range >>> 12) * prob; // below 2^32: exact
    let bit;
    if (this.code < bound) {
      this.range = bound;
      probs[index] = prob + ((4096 - prob) >> 5);
      bit = 0;
    } else {
      this.code -= bound;
      this.range -= bound;
      probs[index] = prob - (prob >> 5);
      bit = 1;
    }
    while (this.range < TOP) {
      this.range = (this.range << 8) >>> 0;
      this.code = ((this.code << 8) | this.byte()) >>> 0;
    }
    return bit;
  }

  /* `bits` bits of even odds, most significant first (up to 32). */
  direct(bits) {
    let value = 0;
    while (bits-- > 0) {
      this.range >>>= 1;
      let bit = 0;
      if (this.code >= this.range) {
        this.code -= this.range;
        bit = 1;
      }
      value = value * 2 + bit;
      while (this.range < TOP) {
        this.range = (this.range << 8) >>> 0;
        this.code = ((this.code << 8) | this.byte()) >>> 0;
      }
    }
    return value;
  }

  /* A tree of `bits` bits whose node models start at probs[offset] (node 1 first at offset + 1). */
  tree(offset, bits) {
    let node = 1;
    for (let i = 0; i < bits; i++) node = 2 * node + this.bit(offset + node);
    return node - (1 << bits);
  }

  /* An unsigned integer (0 .. 2^32 - 1) with the model set at `offset`; -1 for a length above 32. */
  uint(offset) {
    const length = this.tree(offset, LENGTH_BITS);
    if (length > 32) return -1;
    if (length <= 1) return length;
    const below = length - 1;
    const modelled = below < 2 ? below : 2;
    let value = (1 << modelled) | this.tree(offset + (1 << LENGTH_BITS) + 4 * length, modelled);
    if (below > modelled) value = value * 2 ** (below - modelled) + this.direct(below - modelled);
    return value;
  }

  /* A zigzag-coded signed integer (int32), or null for a corrupt length. */
  signed(offset) {
    const u = this.uint(offset);
    if (u < 0) return null;
    return (u >>> 1) ^ -(u & 1);
  }
}


/**
 * Float32 positions of the first `n` vertices of `quantised` (3 per
 * vertex) in the box of `info` (web/stream.js's header): min + q * step in
 * double, rounded once, as the C decoder computes them.
 */
export function dequantisedPositions(quantised, n, info) {
  const positions = new Float32Array(3 * n);
  const min = info.quantisationMin, step = info.quantisationStep;
  for (let v = 0; v < n; v++)
    for (let a = 0; a < 3; a++) positions[3 * v + a] = Math.fround(min[a] + quantised[3 * v + a] * step[a]);
  return positions;
}

const bitLength = (value) => (value === 0 ? 0 : 32 - Math.clz32(value));

/* floor(numerator / denominator) for non-negative integers below 2^53. */
function floorDiv(numerator, denominator) {
  let quotient = Math.floor(numerator / denominator);
  if (quotient * denominator > numerator) quotient--;
  else if ((quotient + 1) * denominator <= numerator) quotient++;
  return quotient;
}

const UNORDERED = 0;
const OPEN = 1;
const CLOSED = 2;

/* A growable typed array's storage: at least `needed` elements, old ones
 * kept. It grows 4 times at a time but not past `limit` (what the header
 * says the whole stream needs) unless `needed` is more: fresh memory is
 * what growing costs (a page fault per 4 KiB as it is first written), and
 * doubling every array to the bunny's full level allocated 10.4 MB in 132
 * arrays, 29-58 ms of a 250-350 ms decode in node. Never more than 4 times
 * what the chunks that arrived need, so a header that lies costs no large
 * allocation. */
function grown(array, needed, limit = Infinity) {
  if (needed <= array.length) return array;
  const bigger = new array.constructor(Math.max(needed, Math.min(4 * array.length, limit), 16));
  bigger.set(array);
  return bigger;
}

/**
 * The decoder's mesh and split log. `header` is web/stream.js's parsed
 * header (baseVertexCount, baseTriangleCount, triangleCount, positionBits,
 * quantisedMax, quantisationMin, quantisationStep).
 */
export class Stream2State {
  constructor(header) {
    this.info = header;
    this.base = header.baseVertexCount;
    this.max = header.quantisedMax;
    this.hintShift = header.positionBits > 12 ? header.positionBits - 12 : 0;
    this.hasBase = false;
    this.vertexCount = 0;
    this.triangleCount = 0;
    // What the C decoder has reserved (its checks depend on it): the base
    // chunk's counts, then per split chunk its vertices and at most 8
    // triangles per split, never more triangles than the header's.
    this.triangleCapacity = 0;
    this.quantised = new Int32Array(0);
    this.head = new Uint32Array(0);
    this.valence = new Uint32Array(0); // per vertex: its triangle count (the split bits' context)
    this.stamp = new Uint32Array(0); // per vertex: the batch that excluded it
    this.serial = 0;
    // per vertex, for ordering fans: marks of the fan being ordered (epoch)
    this.afterMark = new Uint32Array(0);
    this.beforeMark = new Uint32Array(0);
    this.beforeIndex = new Uint32Array(0);
    this.epoch = 0;
    this.corners = new Uint32Array(0); // 3 per triangle, drawing order
    this.nextCorner = new Uint32Array(0);
    // the split log: split k created vertex base + k
    this.logP = new Uint32Array(0);
    this.logOld = new Int32Array(0); // 3 per split: p's position before it
    this.logTrianglesBefore = new Uint32Array(0);
    this.logMovedStart = new Uint32Array(1); // split k moved logMoved[logMovedStart[k] .. logMovedStart[k+1])
    this.logMoved = new Uint32Array(0);
    this.models = new Uint16Array(MODEL_COUNT); // the base chunk's
    // the split chunks', carried from one to the next (docs: "Models")
    this.splitModels = new Uint16Array(MODEL_COUNT).fill(PROB_INIT);
    // scratch for one split's fan
    this.fan = new Uint32Array(64);
    this.fanNext = new Uint32Array(32);
    this.fanPrevious = new Uint32Array(32);
    this.placed = new Uint8Array(32);
    this.moved = new Uint8Array(32);
    this.hint = new Uint8Array(32);
    // per fan triangle: its two corners' offsets from p, summed (doubles: products with the centroid pass 2^31)
    this.offsets = new Float64Array(3 * 32);
    this.spokes = new Float64Array(32); // per fan triangle: its two spokes' squared lengths, summed
    this.restored = new Uint32Array(3 * 32);
    this.batch = new Uint32Array(16);
    this.position = new Int32Array(3);
    this.predicted = new Int32Array(3);
    this.frameNormal = new Float64Array(3);
    this.merged = new Int32Array(3);
    // Attributes (docs/stream-format.md, "Base chunk"): their layout comes
    // from the flags, their bits and box from the base chunk.
    this.flags = header.flags || 0;
    this.attributeCount = (this.flags & FLAG_NORMALS ? 2 : 0) + (this.flags & FLAG_TEXCOORDS ? 2 : 0) +
      (this.flags & FLAG_COLORS ? 4 : 0);
    this.ringFrame = (this.flags & FLAG_RING_FRAME) !== 0;
    this.attributeTop = new Int32Array(8);
    this.normalBits = 0;
    this.texcoordBits = 0;
    this.texcoordMin = [0, 0];
    this.texcoordStep = [0, 0];
    this.attributes = new Int32Array(0); // attributeCount per vertex
    this.logOldAttributes = new Int32Array(0); // attributeCount per split: p's before it
    this.mergedAttributes = new Int32Array(8);
    this.predictedAttributes = new Int32Array(8);
  }

  /* How the attributes are quantised, at the start of the base chunk; false when out of range. */
  readAttributeParameters(coder) {
    let c = 0;
    if (this.flags & FLAG_NORMALS) {
      this.normalBits = coder.direct(5);
      if (this.normalBits < 4 || this.normalBits > 16) return false;
      this.attributeTop[c++] = 2 ** this.normalBits - 1;
      this.attributeTop[c++] = 2 ** this.normalBits - 1;
    }
    if (this.flags & FLAG_TEXCOORDS) {
      this.texcoordBits = coder.direct(5);
      if (this.texcoordBits < 4 || this.texcoordBits > 24) return false;
      const view = new DataView(new ArrayBuffer(4));
      for (let axis = 0; axis < 2; axis++) {
        view.setUint32(0, coder.direct(32));
        const min = view.getFloat32(0);
        view.setUint32(0, coder.direct(32));
        const step = view.getFloat32(0);
        const top = min + (2 ** this.texcoordBits - 1) * step;
        if (!Number.isFinite(min) || !(step >= 0) || !(Math.abs(top) <= 3.4028234663852886e38)) return false;
        this.texcoordMin[axis] = min;
        this.texcoordStep[axis] = step;
      }
      this.attributeTop[c++] = 2 ** this.texcoordBits - 1;
      this.attributeTop[c++] = 2 ** this.texcoordBits - 1;
    }
    if (this.flags & FLAG_COLORS) for (let i = 0; i < 4; i++) this.attributeTop[c++] = 255;
    return true;
  }

  /* Attribute residuals against `predicted` into vertex v's attributes; false when out of range. */
  readAttributes(coder, predicted, v) {
    const count = this.attributeCount, out = this.attributes;
    for (let c = 0; c < count; c++) {
      const delta = coder.signed(M_ATTRIBUTE + c * UINT_MODEL);
      if (delta === null) return false;
      const value = predicted[c] + delta;
      if (value < 0 || value > this.attributeTop[c]) return false;
      out[count * v + c] = value;
    }
    return true;
  }

  /* The ring mean of v's attributes (as predict() for positions), or `fallback`. */
  predictAttributes(v, fallback, out) {
    const count = this.attributeCount, corners = this.corners, next = this.nextCorner, values = this.attributes;
    const sum = [0, 0, 0, 0, 0, 0, 0, 0];
    let corners_seen = 0;
    for (let corner = this.head[v]; corner !== NONE; corner = next[corner]) {
      const base = corner - (corner % 3);
      for (let k = base; k < base + 3; k++) {
        const other = corners[k];
        if (other === v) continue;
        for (let c = 0; c < count; c++) sum[c] += values[count * other + c];
        corners_seen++;
      }
    }
    for (let c = 0; c < count; c++)
      out[c] = corners_seen ? floorDiv(2 * sum[c] + corners_seen, 2 * corners_seen) : fallback[c];
  }

  /* A new position for v, then its attributes (write_vertex/read_vertex in C). */
  readVertex(coder, v, merged) {
    const position = this.position, prediction = this.predicted;
    this.predict(v, merged, prediction);
    if (!(this.ringFrame ? this.readInFrame(coder, v, prediction, position) : this.readResidual(coder, prediction, position)))
      return false;
    this.quantised.set(position, 3 * v);
    if (!this.attributeCount) return true;
    this.predictAttributes(v, this.mergedAttributes, this.predictedAttributes);
    return this.readAttributes(coder, this.predictedAttributes, v);
  }

  get level() {
    return this.hasBase ? this.vertexCount - this.base : 0;
  }

  /* Room for `vertices` vertices and `triangles` triangles (reserve_for in C). */
  reserve(vertices, triangles) {
    if (triangles > this.info.triangleCount) triangles = this.info.triangleCount;
    this.triangleCapacity = Math.max(this.triangleCapacity, triangles || 1);
    vertices = vertices || 1;
    const allVertices = this.info.vertexCount, allTriangles = this.info.triangleCount;
    if (3 * vertices > this.quantised.length) {
      this.quantised = grown(this.quantised, 3 * vertices, 3 * allVertices);
      this.head = grown(this.head, vertices, allVertices);
      this.valence = grown(this.valence, vertices, allVertices);
      this.stamp = grown(this.stamp, vertices, allVertices);
      this.afterMark = grown(this.afterMark, vertices, allVertices);
      this.beforeMark = grown(this.beforeMark, vertices, allVertices);
      this.beforeIndex = grown(this.beforeIndex, vertices, allVertices);
    }
    if (this.attributeCount * vertices > this.attributes.length)
      this.attributes = grown(this.attributes, this.attributeCount * vertices, this.attributeCount * allVertices);
    if (3 * this.triangleCapacity > this.corners.length) {
      this.corners = grown(this.corners, 3 * this.triangleCapacity, 3 * allTriangles);
      this.nextCorner = grown(this.nextCorner, 3 * this.triangleCapacity, 3 * allTriangles);
    }
  }

  addVertex(x, y, z, like = NONE) {
    const v = this.vertexCount++;
    this.quantised[3 * v] = x;
    this.quantised[3 * v + 1] = y;
    this.quantised[3 * v + 2] = z;
    this.head[v] = NONE;
    this.valence[v] = 0;
    const count = this.attributeCount;
    if (count) {
      if (like !== NONE) this.attributes.copyWithin(count * v, count * like, count * like + count);
      else this.attributes.fill(0, count * v, count * v + count);
    }
    return v;
  }

  addTriangle(a, b, c) {
    const corner = 3 * this.triangleCount++;
    const corners = this.corners, next = this.nextCorner, head = this.head, valence = this.valence;
    valence[a]++;
    valence[b]++;
    valence[c]++;
    corners[corner] = a;
    next[corner] = head[a];
    head[a] = corner;
    corners[corner + 1] = b;
    next[corner + 1] = head[b];
    head[b] = corner + 1;
    corners[corner + 2] = c;
    next[corner + 2] = head[c];
    head[c] = corner + 2;
  }

  /* Gives triangle t's corner at v to vertex `to` (moved to the front of to's list). */
  moveCorner(t, v, to) {
    const next = this.nextCorner;
    let previous = NONE;
    let corner = this.head[v];
    while (corner !== NONE && ((corner / 3) | 0) !== t) {
      previous = corner;
      corner = next[corner];
    }
    if (corner === NONE) return;
    this.valence[v]--;
    this.valence[to]++;
    if (previous === NONE) this.head[v] = next[corner];
    else next[previous] = next[corner];
    this.corners[corner] = to;
    next[corner] = this.head[to];
    this.head[to] = corner;
  }

  /* Unlinks corner `corner` from its vertex's list. */
  unlinkCorner(corner) {
    const next = this.nextCorner;
    const v = this.corners[corner];
    this.valence[v]--;
    if (this.head[v] === corner) {
      this.head[v] = next[corner];
      return;
    }
    let at = this.head[v];
    while (next[at] !== corner) at = next[at];
    next[at] = next[corner];
  }

  /* The mean of the corners other than v of v's triangles (rounded half
   * up), or `fallback` (3 values) when v has no triangle. */
  predict(v, fallback, out) {
    const corners = this.corners, q = this.quantised, next = this.nextCorner;
    let s0 = 0, s1 = 0, s2 = 0, count = 0;
    for (let corner = this.head[v]; corner !== NONE; corner = next[corner]) {
      const base = corner - (corner % 3);
      for (let k = base; k < base + 3; k++) {
        const other = corners[k];
        if (other === v) continue;
        s0 += q[3 * other];
        s1 += q[3 * other + 1];
        s2 += q[3 * other + 2];
        count++;
      }
    }
    if (count) {
      out[0] = floorDiv(2 * s0 + count, 2 * count);
      out[1] = floorDiv(2 * s1 + count, 2 * count);
      out[2] = floorDiv(2 * s2 + count, 2 * count);
    } else {
      out[0] = fallback[0];
      out[1] = fallback[1];
      out[2] = fallback[2];
    }
  }

  /* Reads a position: predicted + residual per axis, within the grid; false when outside. */
  readResidual(coder, predicted, out) {
    for (let a = 0; a < 3; a++) {
      const delta = coder.signed(M_RESIDUAL + a * UINT_MODEL);
      if (delta === null) return false;
      const value = predicted[a] + delta;
      if (value < 0 || value > this.max) return false;
      out[a] = value;
    }
    return true;
  }

  /* Reads a split position coded in its ring's frame (header flag 8; C: lk__lks2_predict_frame and read_in_frame):
   * the two components across the ring's normal, then the one along it, less the offset that puts the vertex in
   * the plane through the prediction. Every product below stays under 2^47, every sum under 2^53 (fans of fewer
   * than 2^28 triangles), so doubles compute what C's 64-bit integers do. False when outside the grid. */
  readInFrame(coder, v, predicted, out) {
    const corners = this.corners, q = this.quantised, next = this.nextCorner, shift = this.hintShift;
    const cx = predicted[0] >> shift, cy = predicted[1] >> shift, cz = predicted[2] >> shift;
    let n0 = 0, n1 = 0, n2 = 0;
    for (let corner = this.head[v]; corner !== NONE; corner = next[corner]) {
      const base = corner - (corner % 3), k = corner - base;
      const a = 3 * corners[base + ((k + 1) % 3)], b = 3 * corners[base + ((k + 2) % 3)];
      const ax = (q[a] >> shift) - cx, ay = (q[a + 1] >> shift) - cy, az = (q[a + 2] >> shift) - cz;
      const bx = (q[b] >> shift) - cx, by = (q[b + 1] >> shift) - cy, bz = (q[b + 2] >> shift) - cz;
      n0 += ay * bz - az * by;
      n1 += az * bx - ax * bz;
      n2 += ax * by - ay * bx;
    }
    // the axis closest to the normal (the lowest on ties); the normal scaled below 2^15 there, truncating
    let w = 0, largest = Math.abs(n0);
    if (Math.abs(n1) > largest) (w = 1), (largest = Math.abs(n1));
    if (Math.abs(n2) > largest) (w = 2), (largest = Math.abs(n2));
    let divisor = 1;
    while (largest / divisor >= 32768) divisor *= 2;
    const n = this.frameNormal;
    n[0] = Math.trunc(n0 / divisor);
    n[1] = Math.trunc(n1 / divisor);
    n[2] = Math.trunc(n2 / divisor);
    const u = (w + 1) % 3, t = (w + 2) % 3;
    const first = coder.signed(M_RESIDUAL);
    if (first === null) return false;
    const second = coder.signed(M_RESIDUAL + UINT_MODEL);
    if (second === null) return false;
    const along = coder.signed(M_RESIDUAL + 2 * UINT_MODEL);
    if (along === null) return false;
    let offset = 0;
    if (n[w] !== 0) {
      const across = n[u] * first + n[t] * second;
      const denominator = Math.abs(n[w]);
      offset = Math.floor((2 * (n[w] > 0 ? -across : across) + denominator) / (2 * denominator));
    }
    const vu = predicted[u] + first, vt = predicted[t] + second, vw = predicted[w] + offset + along;
    if (vu < 0 || vu > this.max || vt < 0 || vt > this.max || vw < 0 || vw > this.max) return false;
    out[u] = vu;
    out[t] = vt;
    out[w] = vw;
    return true;
  }

  /** Decodes the base chunk's payload (Uint8Array). Throws PayloadError. */
  decodeBase(payload, chunk) {
    const info = this.info;
    const base = info.baseVertexCount;
    const triangles = info.baseTriangleCount;
    const size = payload.length;
    if (base > SYMBOLS_PER_BYTE * size || triangles > SYMBOLS_PER_BYTE * size)
      throw new PayloadError(`${size} bytes cannot hold ${base} base vertices and ${triangles} triangles`);
    this.reserve(base, triangles);
    this.models.fill(PROB_INIT);
    const coder = new RangeDecoder(payload, this.models);
    if (!this.readAttributeParameters(coder)) throw new PayloadError('attribute quantisation out of range');
    const corners = new Uint32Array(3 * triangles);
    let nextNew = 0;
    for (let t = 0; t < triangles; t++) {
      for (let c = 0; c < 3; c++) {
        const back = coder.uint(M_CORNER + c * UINT_MODEL);
        if (back < 0 || back > nextNew || (back === 0 && nextNew >= base))
          throw new PayloadError(`base triangle ${t}: corner ${c} names no vertex`);
        corners[3 * t + c] = back ? nextNew - back : nextNew++;
      }
      const a = corners[3 * t], b = corners[3 * t + 1], c = corners[3 * t + 2];
      if (a === b || b === c || a === c) throw new PayloadError(`base triangle ${t} repeats a vertex`);
    }
    const previous = new Int32Array(3);
    const position = this.position;
    this.vertexCount = 0;
    const previousAttributes = new Int32Array(8), count = this.attributeCount;
    for (let v = 0; v < base; v++) {
      if (!this.readResidual(coder, previous, position))
        throw new PayloadError(`base vertex ${v}: position outside the quantisation grid`);
      previous.set(position);
      this.addVertex(position[0], position[1], position[2]);
      if (count) {
        if (!this.readAttributes(coder, previousAttributes, v))
          throw new PayloadError(`base vertex ${v}: attribute out of range`);
        previousAttributes.set(this.attributes.subarray(count * v, count * v + count));
      }
    }
    this.triangleCount = 0;
    for (let t = 0; t < triangles; t++) this.addTriangle(corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]);
    try {
      this.payloadEnd(coder);
      if (this.triangleCount !== chunk.triangleCount)
        throw new PayloadError(`the base chunk holds ${this.triangleCount} triangles, the table says ${chunk.triangleCount}`);
    } catch (error) {
      this.vertexCount = 0;
      this.triangleCount = 0;
      throw error;
    }
    this.hasBase = true;
  }

  payloadEnd(coder) {
    if (coder.overrun) throw new PayloadError('the payload ends before its last symbol');
    if (coder.position !== coder.size)
      throw new PayloadError(`${coder.size - coder.position} bytes left over after the last symbol`);
  }

  /* Marks v and its neighbours with the batch's serial. */
  exclude(v, serial) {
    const stamp = this.stamp, corners = this.corners, next = this.nextCorner;
    stamp[v] = serial;
    for (let corner = this.head[v]; corner !== NONE; corner = next[corner]) {
      const base = corner - (corner % 3);
      stamp[corners[base]] = serial;
      stamp[corners[base + 1]] = serial;
      stamp[corners[base + 2]] = serial;
    }
  }

  /* Context of "is v a split vertex of the batch": its triangle count, up
   * to SPLIT_CONTEXTS - 1. */
  splitContext(v) {
    const count = this.valence[v];
    return count < SPLIT_CONTEXTS - 1 ? count : SPLIT_CONTEXTS - 1;
  }

  /* Loads p's fan into this.fan[0 .. k), ordered (docs: "Order p's fan");
   * returns k and sets this.shape, this.hint. */
  loadFan(p) {
    const corners = this.corners, next = this.nextCorner;
    let fan = this.fan, after = this.fanNext, before = this.fanPrevious;
    let k = 0;
    for (let corner = this.head[p]; corner !== NONE; corner = next[corner]) {
      if (k === after.length) {
        this.growFan(2 * k);
        fan = this.fan, after = this.fanNext, before = this.fanPrevious;
      }
      const base = corner - (corner % 3);
      const at = corner - base;
      fan[k] = base / 3;
      after[k] = corners[at === 2 ? base : corner + 1];
      before[k] = corners[at === 0 ? base + 2 : corner - 1];
      k++;
    }
    this.placed.fill(0, 0, k);
    this.shape = this.orderFan(k);

    // Hints: does triangle i lie towards the ring's centroid (1), are its
    // spokes longer than the fan's mean (+ 2)? On positions without their
    // bits above 12, so every product stays below 2^53. A triangle's dot
    // product is that of the sum of its two corners' offsets.
    const shift = this.hintShift, q = this.quantised, hint = this.hint, offsets = this.offsets;
    const px = q[3 * p] >> shift, py = q[3 * p + 1] >> shift, pz = q[3 * p + 2] >> shift;
    let cx = 0, cy = 0, cz = 0;
    const spokes = this.spokes;
    let spokeTotal = 0;
    for (let i = 0; i < k; i++) {
      const base = 3 * fan[i];
      let sx = 0, sy = 0, sz = 0, spoke = 0;
      for (let c = base; c < base + 3; c++) {
        const w = corners[c];
        if (w === p) continue;
        const dx = (q[3 * w] >> shift) - px, dy = (q[3 * w + 1] >> shift) - py, dz = (q[3 * w + 2] >> shift) - pz;
        sx += dx;
        sy += dy;
        sz += dz;
        spoke += dx * dx + dy * dy + dz * dz;
      }
      offsets[3 * i] = sx;
      offsets[3 * i + 1] = sy;
      offsets[3 * i + 2] = sz;
      spokes[i] = spoke;
      spokeTotal += spoke;
      cx += sx;
      cy += sy;
      cz += sz;
    }
    for (let i = 0; i < k; i++)
      hint[i] =
        (offsets[3 * i] * cx + offsets[3 * i + 1] * cy + offsets[3 * i + 2] * cz > 0 ? 1 : 0) +
        (k * spokes[i] > spokeTotal ? 2 : 0);
    return k;
  }

  /* Room for fans of `room` triangles. */
  growFan(room) {
    const fan = new Uint32Array(2 * room);
    fan.set(this.fan.subarray(0, this.fanNext.length));
    this.fan = fan;
    this.fanNext = grown(this.fanNext, room, room);
    this.fanPrevious = grown(this.fanPrevious, room, room);
    this.placed = new Uint8Array(room);
    this.moved = new Uint8Array(room);
    this.hint = new Uint8Array(room);
    this.offsets = new Float64Array(3 * room);
    this.spokes = new Float64Array(room);
  }

  /* Orders this.fan[0 .. k) in place (docs: "Order p's fan"); returns the
   * shape. Triangles have three different corners, so a triangle never
   * leads itself. When no two triangles share a `prev`, each step of the
   * chain has at most one way on, found through per-vertex marks in O(k);
   * otherwise every pair is compared, as the C decoder does. */
  orderFan(k) {
    const fan = this.fan, after = this.fanNext, before = this.fanPrevious, placed = this.placed;
    const epoch = ++this.epoch;
    const afterMark = this.afterMark, beforeMark = this.beforeMark, beforeIndex = this.beforeIndex;
    let distinct = true;
    for (let i = 0; i < k; i++) {
      afterMark[after[i]] = epoch;
      const w = before[i];
      if (beforeMark[w] === epoch) distinct = false;
      beforeMark[w] = epoch;
      beforeIndex[w] = i;
    }
    if (!distinct) return this.orderFanPairwise(k);
    let start = k, lowest = 0, openings = 0;
    for (let i = 0; i < k; i++) {
      if (fan[i] < fan[lowest]) lowest = i;
      if (afterMark[before[i]] !== epoch) {
        start = i;
        openings++;
      }
    }
    let shape = openings === 0 ? CLOSED : openings === 1 ? OPEN : UNORDERED;
    if (shape === CLOSED) start = lowest;
    if (shape !== UNORDERED) {
      let at = start;
      for (let done = 0; done < k; done++) {
        placed[at] = 1;
        fan[k + done] = fan[at];
        if (done + 1 === k) break;
        const w = after[at];
        if (beforeMark[w] !== epoch || placed[beforeIndex[w]]) {
          shape = UNORDERED;
          break;
        }
        at = beforeIndex[w];
      }
      if (shape !== UNORDERED) fan.copyWithin(0, k, 2 * k);
    }
    if (shape === UNORDERED) fan.subarray(0, k).sort();
    return shape;
  }

  orderFanPairwise(k) {
    const fan = this.fan, after = this.fanNext, before = this.fanPrevious, placed = this.placed;
    let start = k, lowest = 0, openings = 0;
    for (let i = 0; i < k; i++) {
      if (fan[i] < fan[lowest]) lowest = i;
      let led = false;
      for (let j = 0; j < k && !led; j++) led = j !== i && after[j] === before[i];
      if (!led) {
        start = i;
        openings++;
      }
    }
    let shape = openings === 0 ? CLOSED : openings === 1 ? OPEN : UNORDERED;
    if (shape === CLOSED) start = lowest;
    if (shape !== UNORDERED) {
      let at = start;
      for (let done = 0; done < k; done++) {
        placed[at] = 1;
        fan[k + done] = fan[at];
        if (done + 1 === k) break;
        let following = k, ways = 0;
        for (let j = 0; j < k; j++)
          if (!placed[j] && before[j] === after[at]) {
            following = j;
            ways++;
          }
        if (ways !== 1) {
          shape = UNORDERED;
          break;
        }
        at = following;
      }
      if (shape !== UNORDERED) fan.copyWithin(0, k, 2 * k);
    }
    if (shape === UNORDERED) fan.subarray(0, k).sort();
    return shape;
  }

  /* True when triangles s and t share a vertex other than v. */
  shareEdge(v, s, t) {
    const corners = this.corners;
    for (let i = 3 * s; i < 3 * s + 3; i++) {
      const a = corners[i];
      if (a === v) continue;
      if (corners[3 * t] === a || corners[3 * t + 1] === a || corners[3 * t + 2] === a) return true;
    }
    return false;
  }

  /* The corner of triangle t after v in drawing order. */
  after(t, v) {
    const c = this.corners, b = 3 * t;
    return c[b] === v ? c[b + 1] : c[b + 1] === v ? c[b + 2] : c[b];
  }

  /* The predicted restored triangles (3 corners each) into this.restored; returns their count. */
  predictRestored(p, q, k) {
    const fan = this.fan, moved = this.moved, shape = this.shape;
    // at most one per triangle of a chain, two per staying triangle otherwise
    if (6 * k > this.restored.length) this.restored = new Uint32Array(12 * k);
    const out = this.restored;
    let count = 0;
    if (shape !== UNORDERED) {
      const steps = shape === CLOSED ? k : k - 1;
      for (let i = 0; i < steps; i++) {
        const j = i + 1 === k ? 0 : i + 1;
        if (moved[i] === moved[j]) continue;
        const w = this.after(fan[i], p);
        out[3 * count] = p;
        out[3 * count + 1] = moved[i] ? w : q;
        out[3 * count + 2] = moved[i] ? q : w;
        count++;
      }
      return count;
    }
    const corners = this.corners;
    for (let s = 0; s < k; s++) {
      if (moved[s]) continue;
      const base = 3 * fan[s];
      for (let i = base; i < base + 3; i++) {
        const w = corners[i];
        if (w === p) continue;
        let bordered = false;
        for (let m = 0; m < k && !bordered; m++) {
          if (!moved[m]) continue;
          const b = 3 * fan[m];
          bordered = corners[b] === w || corners[b + 1] === w || corners[b + 2] === w;
        }
        if (!bordered) continue;
        // the new triangle crosses edge (p, w) the other way round
        const forward = this.after(fan[s], p) === w;
        out[3 * count] = p;
        out[3 * count + 1] = forward ? q : w;
        out[3 * count + 2] = forward ? w : q;
        count++;
      }
    }
    return count;
  }

  /* One split at vertex p (docs: "One split at vertex p"). */
  readSplit(coder, p) {
    const k = this.loadFan(p);
    const fan = this.fan, moved = this.moved, hint = this.hint, shape = this.shape;
    // move bits, each with its context
    let changes = 0;
    for (let i = 0; i < k; i++) {
      let context;
      if (i === 0) context = shape === UNORDERED ? 0 : shape === OPEN ? 1 : 2;
      else if (shape !== UNORDERED) {
        if (i >= 2 && moved[i - 1] !== moved[i - 2]) changes++;
        context = 3 + (shape === CLOSED ? 6 : 0) + 2 * (changes > 2 ? 2 : changes) + moved[i - 1];
      } else {
        let moving = 0, staying = 0;
        for (let j = 0; j < i; j++) {
          if (!this.shareEdge(p, fan[j], fan[i])) continue;
          if (moved[j]) moving += moving < 2 ? 1 : 0;
          else staying += staying < 2 ? 1 : 0;
        }
        context = 15 + 3 * moving + staying;
      }
      moved[i] = coder.bit(M_MOVE + context + 24 * hint[i]);
    }
    const q = this.vertexCount;
    const predicted = this.predictRestored(p, q, k);
    let count = predicted;
    let restored = this.restored;
    if (!coder.bit(M_PREDICTED_OK + (predicted > 0 ? 1 : 0))) {
      const escaped = coder.uint(M_ESCAPE);
      if (escaped < 0 || escaped > MAX_ESCAPED) throw new PayloadError(`split of vertex ${p}: bad restored triangle count`);
      count = escaped;
      restored = new Uint32Array(3 * count);
      const width = bitLength(q);
      for (let i = 0; i < count; i++) {
        const third = coder.direct(width);
        const flipped = coder.bit(M_ORIENTATION);
        if (third >= q || third === p)
          throw new PayloadError(`split of vertex ${p}: restored triangle names vertex ${third}`);
        restored[3 * i] = p;
        restored[3 * i + 1] = flipped ? third : q;
        restored[3 * i + 2] = flipped ? q : third;
      }
    }
    if (this.triangleCount + count > this.triangleCapacity)
      throw new PayloadError(`more triangles than the header and the chunk's splits allow (${this.triangleCapacity})`);
    // log, then apply
    const split = q - this.base;
    const quantised = this.quantised;
    const mx = quantised[3 * p], my = quantised[3 * p + 1], mz = quantised[3 * p + 2];
    this.logP[split] = p;
    this.logOld[3 * split] = mx;
    this.logOld[3 * split + 1] = my;
    this.logOld[3 * split + 2] = mz;
    this.logTrianglesBefore[split] = this.triangleCount;
    const attributeCount = this.attributeCount;
    if (attributeCount) {
      const old = this.attributes.subarray(attributeCount * p, attributeCount * p + attributeCount);
      this.mergedAttributes.set(old);
      this.logOldAttributes.set(old, attributeCount * split);
    }
    let movedAt = this.logMovedStart[split];
    for (let i = 0; i < k; i++) movedAt += moved[i];
    // grown 4x up to 4 moved triangles per split (the bunny moves 3.3 on average)
    if (movedAt > this.logMoved.length) this.logMoved = grown(this.logMoved, movedAt, 4 * this.info.splitCount);
    movedAt = this.logMovedStart[split];
    this.addVertex(mx, my, mz, p);
    for (let i = 0; i < k; i++)
      if (moved[i]) {
        this.moveCorner(fan[i], p, q);
        this.logMoved[movedAt++] = fan[i];
      }
    this.logMovedStart[split + 1] = movedAt;
    for (let i = 0; i < count; i++) this.addTriangle(restored[3 * i], restored[3 * i + 1], restored[3 * i + 2]);
    const kind = coder.tree(M_KIND, 2);
    if (kind > 2) throw new PayloadError(`split of vertex ${p}: bad kind ${kind}`);
    const merged = this.merged;
    merged[0] = mx;
    merged[1] = my;
    merged[2] = mz;
    if (kind !== 1 && !this.readVertex(coder, q, merged))
      throw new PayloadError(`vertex ${q}: position or attribute out of range`);
    if (kind !== 0 && !this.readVertex(coder, p, merged))
      throw new PayloadError(`vertex ${p}: position or attribute out of range`);
  }

  /* Takes back the last split in the log. */
  undoSplit() {
    const q = this.vertexCount - 1;
    const split = q - this.base;
    const p = this.logP[split];
    const before = this.logTrianglesBefore[split];
    while (this.triangleCount > before) {
      const t = --this.triangleCount;
      for (let corner = 3 * t; corner < 3 * t + 3; corner++) this.unlinkCorner(corner);
    }
    for (let m = this.logMovedStart[split + 1]; m-- > this.logMovedStart[split];) this.moveCorner(this.logMoved[m], q, p);
    this.quantised[3 * p] = this.logOld[3 * split];
    this.quantised[3 * p + 1] = this.logOld[3 * split + 1];
    this.quantised[3 * p + 2] = this.logOld[3 * split + 2];
    const count = this.attributeCount;
    if (count)
      this.attributes.set(this.logOldAttributes.subarray(count * split, count * split + count), count * p);
    this.vertexCount--;
  }

  /** Applies a split chunk's payload whole, or takes it back and throws PayloadError. */
  applyChunk(payload, chunk) {
    if (!this.hasBase) throw new PayloadError('a split chunk before the base chunk');
    const splitCount = chunk.splitCount;
    const startVertices = this.vertexCount;
    this.reserve(this.vertexCount + splitCount, this.triangleCount + MAX_TRIANGLES_PER_SPLIT * splitCount);
    const logged = this.vertexCount - this.base + splitCount;
    const allSplits = this.info.splitCount;
    if (logged > this.logP.length) {
      this.logP = grown(this.logP, logged, allSplits);
      this.logOld = grown(this.logOld, 3 * logged, 3 * allSplits);
      this.logTrianglesBefore = grown(this.logTrianglesBefore, logged, allSplits);
      this.logMovedStart = grown(this.logMovedStart, logged + 1, allSplits + 1);
    }
    if (this.attributeCount * logged > this.logOldAttributes.length)
      this.logOldAttributes = grown(this.logOldAttributes, this.attributeCount * logged, this.attributeCount * allSplits);
    // a chunk taken back takes its model updates back too
    const before = this.splitModels.slice();
    const coder = new RangeDecoder(payload, this.splitModels);
    let applied = 0;
    try {
      while (applied < splitCount) {
        let size = coder.uint(M_BATCH);
        if (size < 0 || size >= splitCount - applied) throw new PayloadError(`split ${applied}: batch larger than the chunk`);
        size++;
        if (size > this.batch.length) this.batch = new Uint32Array(2 * size);
        const serial = ++this.serial;
        const stamp = this.stamp;
        const present = this.vertexCount;
        let cursor = 0;
        for (let i = 0; i < size; i++) {
          // one bit per vertex not yet excluded, until a 1
          let v = cursor;
          for (;; v++) {
            while (v < present && stamp[v] === serial) v++;
            if (v >= present || coder.bit(M_SPLIT + this.splitContext(v))) break;
          }
          if (v >= present) throw new PayloadError(`split ${applied + i}: split vertex beyond the ${present} present`);
          this.batch[i] = v;
          this.exclude(v, serial);
          cursor = v + 1;
        }
        for (let i = 0; i < size; i++, applied++) this.readSplit(coder, this.batch[i]);
        if (coder.overrun) throw new PayloadError('the payload ends before its last symbol');
      }
      this.payloadEnd(coder);
      if (this.triangleCount !== chunk.triangleCount)
        throw new PayloadError(`${this.triangleCount} triangles decoded, the table says ${chunk.triangleCount}`);
    } catch (error) {
      while (this.vertexCount > startVertices) this.undoSplit();
      this.splitModels.set(before);
      throw error;
    }
  }

  /**
   * The mesh at `level` (<= the decoded level): n = base + level vertices
   * (dequantised Float32Array positions and their quantised values) and its
   * triangles (Uint32Array, 3 corners each, counter-clockwise). Lower levels
   * undo the later splits from the log. At the decoded level `quantised` is
   * a view of the decoder's own array (decoding on changes it), not a copy:
   * web/stream_worker.js asks for the level after every chunk and only reads
   * the positions, and each copy was fresh memory in the worker.
   */
  levelGeometry(level) {
    const current = this.level;
    if (level > current) level = current;
    if (level < 0) level = 0;
    const n = this.base + level;
    const quantised = level < current ? this.quantised.slice(0, 3 * this.vertexCount) : this.quantised;
    const triangleCount = level < current ? this.logTrianglesBefore[level] : this.triangleCount;
    const triangles = this.corners.slice(0, 3 * triangleCount);
    for (let split = current - 1; split >= level; split--) {
      const p = this.logP[split];
      const q = this.base + split;
      quantised[3 * p] = this.logOld[3 * split];
      quantised[3 * p + 1] = this.logOld[3 * split + 1];
      quantised[3 * p + 2] = this.logOld[3 * split + 2];
      for (let m = this.logMovedStart[split]; m < this.logMovedStart[split + 1]; m++) {
        const t = this.logMoved[m];
        if (t >= triangleCount) continue; // restored after this level: dropped
        const b = 3 * t;
        if (triangles[b] === q) triangles[b] = p;
        else if (triangles[b + 1] === q) triangles[b + 1] = p;
        else triangles[b + 2] = p;
      }
    }
    const positions = dequantisedPositions(quantised, n, this.info);
    return { level, vertexCount: n, positions, triangles, quantised: quantised.subarray(0, 3 * n) };
  }
}

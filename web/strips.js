// SPDX-License-Identifier: MIT
// DTFS filter (degenerate-triangle-free scanning, section 4 of the
// progressive-strips paper), the same decisions as lk_strip_filter in
// src/strips.c so that the viewer sends the GPU what the C library would:
// the non-degenerate triangles of a strip, in order, rebuilt into one
// strip. A triangle sharing the open edge {u,v} of the output (with the
// right orientation) costs one index, or two (the swap u,f) when only that
// leaves an edge leading on to the next survivor; any other triangle
// starts a new strip joined by degenerate triangles (3, 4 or 5 indices),
// since WebGL 1 / OpenGL ES 2.0 has no primitive restart.

/** Largest output of stripFilter for an input of `length` indices. */
export function stripFilterBound(length) {
  return length < 3 ? 0 : 5 * (length - 2);
}

const degenerate = (a, b, c) => a === b || b === c || a === c;

/* The triangle the triple at a position of this parity draws. */
function drawnTriangle(x, y, z, parity, out) {
  if (parity & 1) {
    out[0] = y; out[1] = x; out[2] = z;
  } else {
    out[0] = x; out[1] = y; out[2] = z;
  }
}

function thirdCorner(t, a, b) {
  for (let k = 0; k < 3; k++) if (t[k] !== a && t[k] !== b) return t[k];
  return t[0];
}

/* Does the triple (x, y, f) at a position of `parity` draw triangle t? */
function attaches(x, y, parity, t) {
  if (!t) return false;
  const from = parity & 1 ? y : x;
  const to = parity & 1 ? x : y;
  return (t[0] === from && t[1] === to) || (t[1] === from && t[2] === to) || (t[2] === from && t[0] === to);
}

class Output {
  constructor(destination) {
    this.destination = destination;
    this.length = 0;
    this.w = 0;
    this.u = 0;
    this.v = 0;
  }

  put(value) {
    if (this.destination) this.destination[this.length] = value;
    this.length++;
    this.w = this.u;
    this.u = this.v;
    this.v = value;
  }

  /* Appends triangle t (which does not hold the open edge) as a new strip. */
  start(t, next) {
    let bestScore = 1 << 30;
    let bestCost = 0;
    let best = [t[0], t[1], t[2]];
    for (let k = 0; k < 3; k++) {
      const r = t[k], a = t[(k + 1) % 3], b = t[(k + 2) % 3];
      let cost, position;
      if (this.length === 0) { cost = 3; position = 0; }
      else if (r === this.v) { cost = 3; position = this.length; }
      else if (r === this.u) { cost = 4; position = this.length + 1; }
      else { cost = 5; position = this.length + 2; }
      const form = [r, position & 1 ? b : a, position & 1 ? a : b];
      const leadsOn = attaches(form[1], form[2], position + 1, next);
      const score = cost + (leadsOn ? 1 : 4);
      if (score < bestScore || (score === bestScore && cost < bestCost)) {
        bestScore = score;
        bestCost = cost;
        best = form;
      }
    }
    if (this.length > 0) {
      if (best[0] === this.u) this.put(this.u);
      else if (best[0] !== this.v) {
        this.put(this.v);
        this.put(best[0]);
      }
    }
    for (let k = 0; k < 3; k++) this.put(best[k]);
  }
}

/* Next surviving triple at or after j (its triangle into t), or -1. */
function nextSurvivor(strip, length, j, t) {
  for (; j < length - 2; j++) {
    const a = strip[j], b = strip[j + 1], c = strip[j + 2];
    if (degenerate(a, b, c)) continue;
    drawnTriangle(a, b, c, j, t);
    return j;
  }
  return -1;
}

/* The last position of the run of surviving triples starting at j. */
function runEnd(strip, length, j) {
  const triples = length - 2;
  while (j + 1 < triples && !degenerate(strip[j + 1], strip[j + 2], strip[j + 3])) j++;
  return j;
}

/**
 * Filters `strip` (its first `length` entries) into `destination` (at
 * least stripFilterBound(length) entries, or null to count only).
 * Returns { length, triangles }: the output length and the number of
 * non-degenerate triangles (the same as the input's).
 */
export function stripFilter(strip, length, destination) {
  const o = new Output(destination);
  let current = [0, 0, 0];
  let next = [0, 0, 0];
  let triangles = 0;
  if (length < 3) return { length: 0, triangles: 0 };
  // inStep: the output ends with the input triple at this position, same
  // form and parity; consecutive survivors after it then go straight on.
  let inStep = -1;
  let j = nextSurvivor(strip, length, 0, current);
  while (j !== -1) {
    let k = nextSurvivor(strip, length, j + 1, next);
    let ahead = k !== -1 ? next : null;
    triangles++;
    if (inStep !== -1 && j === inStep + 1 && k === j + 1) {
      const end = runEnd(strip, length, k);
      for (let i = j + 2; i < end + 2; i++) o.put(strip[i]);
      triangles += end - j;
      j = end;
      k = nextSurvivor(strip, length, j + 1, next);
      ahead = k !== -1 ? next : null;
      drawnTriangle(strip[j], strip[j + 1], strip[j + 2], j, current);
    }
    if (o.length >= 3 && attaches(o.u, o.v, o.length - 2, current)) {
      const f = thirdCorner(current, o.u, o.v);
      const straightLeadsOn = attaches(o.v, f, o.length - 1, ahead);
      const swapLeadsOn = attaches(o.u, f, o.length, ahead);
      if (swapLeadsOn && !straightLeadsOn) o.put(o.u);
      o.put(f);
    } else {
      o.start(current, ahead);
    }
    inStep = o.w === strip[j] && o.u === strip[j + 1] && o.v === strip[j + 2] && ((o.length - 3) & 1) === (j & 1) ? j : -1;
    const swap = current;
    current = next;
    next = swap;
    j = k;
  }
  return { length: o.length, triangles };
}

/** Non-degenerate triangles of a strip (the count only). */
export function stripTriangleCount(strip, length) {
  let count = 0;
  for (let t = 0; t + 2 < length; t++) if (!degenerate(strip[t], strip[t + 1], strip[t + 2])) count++;
  return count;
}

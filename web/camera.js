// SPDX-License-Identifier: MIT
// Cameras and input. OrbitCamera: the C renderer's orbit camera
// (src/gl/camera.c: azimuth/elevation around the bounding sphere, depth
// range hugging it) driven by mouse, wheel and touch. FlyCamera: terrain
// flight with WASD/arrows and mouse look (z up, the terrain's frame).

import { perspective, viewFromAxes, normalMatrix, cross, normalize } from './gl.js';

const DEG = Math.PI / 180;

/**
 * The y-up orbit frame turned so that its y lands on another up axis, as
 * lk__camera_setup does (src/gl/camera.c): z up is +90 degrees about x, x up
 * is -90 degrees about z.
 */
export function turnToUpAxis(v, upAxis) {
  if (upAxis === 'z') return [v[0], -v[2], v[1]];
  if (upAxis === 'x') return [v[1], -v[0], v[2]];
  return v;
}

export class OrbitCamera {
  constructor() {
    this.fovY = 35;
    this.azimuth = 30;
    this.elevation = 20;
    this.zoom = 1; // distance / framing distance
    this.centre = [0, 0, 0];
    this.pan = [0, 0, 0];
    this.radius = 1;
    this.upAxis = 'y'; // 'y', 'z' or 'x': the axis the orbit turns around (lk_render_options.up_axis)
  }

  /** Frames a bounding box as lk__camera_setup does. */
  frame(min, max) {
    let squared = 0;
    for (let a = 0; a < 3; a++) {
      this.centre[a] = 0.5 * (min[a] + max[a]);
      squared += (0.5 * (max[a] - min[a])) ** 2;
    }
    this.radius = Math.max(Math.sqrt(squared), 1e-6);
    this.pan = [0, 0, 0];
  }

  /** { view, projection, normalMatrix, near, far, top, eye, distance } for a viewport. */
  matrices(width, height) {
    const aspect = width / Math.max(height, 1);
    const halfY = 0.5 * this.fovY * DEG;
    const halfX = Math.atan(Math.tan(halfY) * aspect);
    const framing = (1.05 * this.radius) / Math.sin(Math.min(halfY, halfX));
    const distance = framing * this.zoom;
    const az = this.azimuth * DEG;
    const el = this.elevation * DEG;
    let back = [Math.sin(az) * Math.cos(el), Math.sin(el), Math.cos(az) * Math.cos(el)];
    let right = [Math.cos(az), 0, -Math.sin(az)];
    let up = cross(back, right);
    [back, right, up] = [back, right, up].map((v) => turnToUpAxis(v, this.upAxis));
    const target = [0, 1, 2].map((a) => this.centre[a] + this.pan[a]);
    const eye = [0, 1, 2].map((a) => target[a] + distance * back[a]);
    const view = viewFromAxes(eye, right, up, back);
    // depth range around the model's sphere, seen from the eye
    const toCentre = Math.hypot(eye[0] - this.centre[0], eye[1] - this.centre[1], eye[2] - this.centre[2]);
    const near = Math.max(toCentre - 1.1 * this.radius, toCentre * 1e-3);
    const far = toCentre + 1.1 * this.radius;
    const top = near * Math.tan(halfY);
    return {
      view,
      projection: perspective(this.fovY, aspect, near, far),
      normalMatrix: normalMatrix(view),
      near, far, top, eye, right, up, distance,
    };
  }

  rotate(dx, dy) {
    this.azimuth -= dx * 0.4;
    this.elevation = Math.max(-89.9, Math.min(89.9, this.elevation + dy * 0.4));
  }

  /** Pans by a drag of (dx, dy) pixels in a viewport `height` pixels high. */
  panBy(dx, dy, width, height) {
    const m = this.matrices(width, height);
    const perPixel = (2 * m.distance * Math.tan(0.5 * this.fovY * DEG)) / height;
    for (let a = 0; a < 3; a++) this.pan[a] += (-dx * m.right[a] + dy * m.up[a]) * perPixel;
  }

  zoomBy(factor) {
    this.zoom = Math.max(0.02, Math.min(50, this.zoom * factor));
  }
}

export class FlyCamera {
  constructor() {
    this.position = [0, 0, 0];
    this.yaw = 0; // degrees, 0 = +x
    this.pitch = -20;
    this.fovY = 60;
    this.speed = 1; // units per second
    this.near = 1;
    this.far = 1000;
  }

  forward() {
    const yaw = this.yaw * DEG;
    const pitch = this.pitch * DEG;
    return [Math.cos(pitch) * Math.cos(yaw), Math.cos(pitch) * Math.sin(yaw), Math.sin(pitch)];
  }

  target() {
    const f = this.forward();
    return [0, 1, 2].map((a) => this.position[a] + f[a] * this.speed);
  }

  matrices(width, height) {
    const back = this.forward().map((x) => -x);
    const right = normalize(cross([0, 0, 1], back));
    const up = cross(back, right);
    const view = viewFromAxes(this.position, right, up, back);
    const aspect = width / Math.max(height, 1);
    return {
      view,
      projection: perspective(this.fovY, aspect, this.near, this.far),
      normalMatrix: normalMatrix(view),
      near: this.near, far: this.far, eye: this.position, aspect,
    };
  }

  look(dx, dy) {
    this.yaw -= dx * 0.25;
    this.pitch = Math.max(-89, Math.min(89, this.pitch - dy * 0.25));
  }

  move(forwardAmount, rightAmount, upAmount) {
    const f = this.forward();
    const right = normalize(cross(f, [0, 0, 1]));
    for (let a = 0; a < 3; a++)
      this.position[a] += f[a] * forwardAmount + right[a] * rightAmount + (a === 2 ? upAmount : 0);
  }
}

/**
 * Mouse, wheel and touch on `element`. handlers: rotate(dx, dy),
 * pan(dx, dy), zoom(factor) — pinch and wheel give factors < 1 to come
 * closer. Left drag rotates; shift-drag, right-drag or middle-drag pans;
 * two fingers pinch-zoom and pan.
 */
export function attachPointerControls(element, handlers) {
  const pointers = new Map();
  let pinchDistance = 0;
  let pinchCentre = null;
  element.addEventListener('contextmenu', (event) => event.preventDefault());
  element.addEventListener('pointerdown', (event) => {
    try {
      element.setPointerCapture(event.pointerId); // keep the drag when it leaves the canvas
    } catch { /* synthetic or already-ended pointers cannot be captured */ }
    pointers.set(event.pointerId, { x: event.clientX, y: event.clientY, button: event.button });
    if (pointers.size === 2) {
      const [a, b] = [...pointers.values()];
      pinchDistance = Math.hypot(a.x - b.x, a.y - b.y);
      pinchCentre = [(a.x + b.x) / 2, (a.y + b.y) / 2];
    }
  });
  const end = (event) => {
    pointers.delete(event.pointerId);
    pinchCentre = null;
  };
  element.addEventListener('pointerup', end);
  element.addEventListener('pointercancel', end);
  element.addEventListener('pointermove', (event) => {
    const pointer = pointers.get(event.pointerId);
    if (!pointer) return;
    const dx = event.clientX - pointer.x;
    const dy = event.clientY - pointer.y;
    pointer.x = event.clientX;
    pointer.y = event.clientY;
    if (pointers.size === 1) {
      if (event.shiftKey || pointer.button === 2 || pointer.button === 1) handlers.pan(dx, dy);
      else handlers.rotate(dx, dy);
    } else if (pointers.size === 2 && pinchCentre) {
      const [a, b] = [...pointers.values()];
      const distance = Math.hypot(a.x - b.x, a.y - b.y);
      const centre = [(a.x + b.x) / 2, (a.y + b.y) / 2];
      if (distance > 0 && pinchDistance > 0) handlers.zoom(pinchDistance / distance);
      handlers.pan(centre[0] - pinchCentre[0], centre[1] - pinchCentre[1]);
      pinchDistance = distance;
      pinchCentre = centre;
    }
  });
  element.addEventListener('wheel', (event) => {
    event.preventDefault();
    const lines = event.deltaMode === 1 ? 40 : event.deltaMode === 2 ? 800 : 1;
    handlers.zoom(Math.exp(event.deltaY * lines * 0.0015));
  }, { passive: false });
}

// The view, as client/scene/src/camera.cpp computes it, in float32 arithmetic step
// by step (Math.fround after every operation, in Eigen's order), so the page
// gets the same view_projection bits as phasecast-render; and an orbit camera
// for the page (drag rotates about the target, wheel zooms).
// A camera: {eye: [3], target: [3], up: [3], fov_y_deg}.

const f = Math.fround;
const add = (a, b) => a.map((v, i) => f(v + b[i]));
const sub = (a, b) => a.map((v, i) => f(v - b[i]));
const scale = (a, s) => a.map((v) => f(v * s));
const dot = (a, b) => f(f(f(a[0] * b[0]) + f(a[1] * b[1])) + f(a[2] * b[2]));
const norm = (a) => f(Math.sqrt(dot(a, a)));
// Eigen's normalized(): v / sqrt(squaredNorm), v itself when zero.
const normalized = (a) => {
  const n = norm(a);
  return n > 0 ? a.map((v) => f(v / n)) : a.slice();
};
const cross = (a, b) => [
  f(f(a[1] * b[2]) - f(a[2] * b[1])),
  f(f(a[2] * b[0]) - f(a[0] * b[2])),
  f(f(a[0] * b[1]) - f(a[1] * b[0])),
];

const PI_F = f(Math.PI);
// tan(0.5f * fov_y_deg * pi_v<float> / 180) in float.
const halfFovTan = (fovYDeg) => f(Math.tan(f(f(f(f(0.5) * f(fovYDeg)) * PI_F) / 180)));

export const DEFAULT_CAMERA = Object.freeze({ eye: [0, 0, 3], target: [0, 0, 0], up: [0, 1, 0], fov_y_deg: 40 });

// Bounding box of x̄ (the rest positions).
export function restBounds(meanShape) {
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < meanShape.length; i += 3) {
    for (let c = 0; c < 3; ++c) {
      const v = f(meanShape[i + c]);
      if (v < min[c]) min[c] = v;
      if (v > max[c]) max[c] = v;
    }
  }
  return { min, max };
}

// Radius of the bounding sphere of x̄ about its box centre (scene_radius).
export function sceneRadius(meanShape) {
  const { min, max } = restBounds(meanShape);
  return Math.max(f(f(0.5) * norm(sub(max, min))), f(1e-3));
}

// SceneInfo.camera when it has 10 floats, else one looking down -z at the
// box of x̄ from 1.1 times the distance that fits its sphere (scene_camera).
export function sceneCamera(basis) {
  const a = basis.camera;
  if (a && a.length === 10) {
    const v = Array.from(a, f);
    return { eye: v.slice(0, 3), target: v.slice(3, 6), up: v.slice(6, 9), fov_y_deg: v[9] };
  }
  const { min, max } = restBounds(basis.mean_shape);
  const target = add(min, max).map((v) => f(v / 2));
  const fov = DEFAULT_CAMERA.fov_y_deg;
  const distance = f(f(sceneRadius(basis.mean_shape) / halfFovTan(fov)) * f(1.1));
  return { eye: add(target, [0, 0, distance]), target, up: [0, 1, 0], fov_y_deg: fov };
}

// Perspective times look-at, column-major Float32Array(16) for GL. Depth
// range from the distance to the target and the scene radius (view_projection).
export function viewProjection(c, width, height, radius) {
  const eye = c.eye.map(f), target = c.target.map(f), up = c.up.map(f);
  const fwd = normalized(sub(target, eye));
  const s = normalized(cross(fwd, up));
  const u = cross(s, fwd);
  // view rows: s, u, -f; translation -s.eye, -u.eye, f.eye
  const view = [
    [s[0], s[1], s[2], -dot(s, eye)],
    [u[0], u[1], u[2], -dot(u, eye)],
    [-fwd[0], -fwd[1], -fwd[2], dot(fwd, eye)],
    [0, 0, 0, 1],
  ];
  const r = f(radius);
  const distance = norm(sub(target, eye));
  const far = f(distance + f(4 * r));
  const near = Math.max(f(distance - f(4 * r)), f(far * f(1e-3)));
  const t = halfFovTan(c.fov_y_deg);
  const aspect = f(f(width) / f(height));
  const proj = [
    [f(1 / f(aspect * t)), 0, 0, 0],
    [0, f(1 / t), 0, 0],
    [0, 0, f(-f(far + near) / f(far - near)), f(f(f(-2 * far) * near) / f(far - near))],
    [0, 0, -1, 0],
  ];
  // proj * view, each element summed over k = 0..3 in order (Eigen's lazy product)
  const out = new Float32Array(16);
  for (let i = 0; i < 4; ++i) {
    for (let j = 0; j < 4; ++j) {
      let sum = f(proj[i][0] * view[0][j]);
      for (let k = 1; k < 4; ++k) sum = f(sum + f(proj[i][k] * view[k][j]));
      out[4 * j + i] = sum;
    }
  }
  return out;
}

// Rotates vector v about unit axis k by angle a (Rodrigues), in doubles:
// the orbit is the page's own, not a copy of the C++.
function rotate(v, k, a) {
  const c = Math.cos(a), s = Math.sin(a);
  const kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
  const kxv = [k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]];
  return v.map((vi, i) => vi * c + kxv[i] * s + k[i] * kv * (1 - c));
}
const unit = (v) => {
  const n = Math.hypot(...v);
  return v.map((x) => x / n);
};

// Orbit about the scene camera's target: drag turns the eye about the up
// axis and about the camera's side axis, the wheel scales the distance.
// Until the user moves it, camera() is exactly the scene camera.
export class OrbitCamera {
  constructor(start) {
    this.start = start;
    this.reset();
  }

  reset() {
    this.current = { ...this.start, eye: this.start.eye.slice(), target: this.start.target.slice(), up: this.start.up.slice() };
    this.version = (this.version ?? 0) + 1;
  }

  camera() {
    return this.current;
  }

  // dx, dy in radians: yaw about up, pitch about the side axis (kept off the poles).
  rotate(dx, dy) {
    const { eye, target, up } = this.current;
    let offset = eye.map((v, i) => v - target[i]);
    const axisUp = unit(up);
    offset = rotate(offset, axisUp, -dx);
    const side = unit([
      axisUp[1] * offset[2] - axisUp[2] * offset[1],
      axisUp[2] * offset[0] - axisUp[0] * offset[2],
      axisUp[0] * offset[1] - axisUp[1] * offset[0],
    ]);
    const pitched = rotate(offset, side, dy);
    const cosUp = (pitched[0] * axisUp[0] + pitched[1] * axisUp[1] + pitched[2] * axisUp[2]) / Math.hypot(...pitched);
    if (Math.abs(cosUp) < 0.995) offset = pitched;
    this.current = { ...this.current, eye: target.map((t, i) => t + offset[i]) };
    ++this.version;
  }

  // factor > 1 moves away from the target.
  zoom(factor) {
    const { eye, target } = this.current;
    this.current = { ...this.current, eye: target.map((t, i) => t + (eye[i] - t) * factor) };
    ++this.version;
  }

  // Mouse/touch on `element`: drag to orbit, wheel to zoom, double-click resets.
  attach(element) {
    let last = null;
    element.addEventListener('pointerdown', (e) => {
      last = [e.clientX, e.clientY];
      element.setPointerCapture(e.pointerId);
    });
    element.addEventListener('pointermove', (e) => {
      if (!last) return;
      const speed = Math.PI / Math.max(200, element.clientHeight);
      this.rotate((e.clientX - last[0]) * speed, (e.clientY - last[1]) * speed);
      last = [e.clientX, e.clientY];
    });
    const end = () => (last = null);
    element.addEventListener('pointerup', end);
    element.addEventListener('pointercancel', end);
    element.addEventListener('wheel', (e) => {
      e.preventDefault();
      this.zoom(Math.exp(Math.sign(e.deltaY) * 0.1));
    }, { passive: false });
    element.addEventListener('dblclick', () => this.reset());
  }
}

// Where `count` instances stand on the native client's default grid
// (camera.cpp grid_placements): columns along x, rows going back along -z,
// ceil(sqrt(count)) to a row, 2.2 scene radii apart. Offsets [x, y, z].
export function gridOffsets(radius, count) {
  const columns = Math.ceil(Math.sqrt(count)), rows = Math.ceil(count / columns);
  const spacing = 2.2 * radius;
  const offsets = [];
  for (let i = 0; i < count; ++i) {
    offsets.push([spacing * ((i % columns) - (columns - 1) / 2), 0, spacing * ((rows - 1) / 2 - Math.floor(i / columns))]);
  }
  return offsets;
}

// The scene's camera moved to the group's centre, raised to look down on its
// rows at least 30 degrees and backed off to take in every instance
// (camera.cpp group_camera, with the group's bounding sphere). Returns
// {camera, radius}: radius bounds the group, for the depth range.
export function groupCamera(camera, radius, offsets) {
  const lo = [0, 1, 2].map((k) => Math.min(...offsets.map((o) => o[k])));
  const hi = [0, 1, 2].map((k) => Math.max(...offsets.map((o) => o[k])));
  const centre = lo.map((v, k) => (v + hi[k]) / 2);
  const groupRadius = radius + Math.hypot(...hi.map((v, k) => (v - lo[k]) / 2));
  const norm = (v) => { const n = Math.hypot(...v); return v.map((x) => x / n); };
  const up = norm(camera.up);
  let back = norm(camera.eye.map((v, k) => v - camera.target[k]));
  const minElevation = Math.sin(Math.PI / 6);
  const along = back.reduce((s, v, k) => s + v * up[k], 0);
  if (along < minElevation) {
    const level = norm(back.map((v, k) => v - along * up[k]));
    back = level.map((v, k) => v * Math.sqrt(1 - minElevation ** 2) + minElevation * up[k]);
  }
  const target = camera.target.map((v, k) => v + centre[k]);
  const distance = groupRadius / Math.tan((camera.fov_y_deg * Math.PI) / 360) * 1.05;
  return { camera: { ...camera, target, eye: target.map((v, k) => v + back[k] * distance) }, radius: groupRadius };
}

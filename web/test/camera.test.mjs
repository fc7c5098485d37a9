// The camera of client/scene/src/camera.cpp: view_projection for known cases
// worked out from its formulas, the scene camera from SceneInfo.camera or
// framed around x̄, and the orbit camera.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { viewProjection, sceneCamera, sceneRadius, OrbitCamera, DEFAULT_CAMERA, gridOffsets, groupCamera } from '../src/camera.js';
import { parseParams } from '../src/params.js';

const close = (a, b, tol, what) => assert.ok(Math.abs(a - b) <= tol * Math.max(1, Math.abs(b)), `${what}: ${a} vs ${b}`);

// camera.cpp's formulas in plain double arithmetic, written out independently.
function referenceViewProjection({ eye, target, up, fov_y_deg }, width, height, radius) {
  const sub = (a, b) => a.map((v, i) => v - b[i]);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const norm = (a) => Math.sqrt(dot(a, a));
  const nrm = (a) => a.map((v) => v / norm(a));
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const f = nrm(sub(target, eye)), s = nrm(cross(f, up)), u = cross(s, f);
  const view = [[...s, -dot(s, eye)], [...u, -dot(u, eye)], [-f[0], -f[1], -f[2], dot(f, eye)], [0, 0, 0, 1]];
  const d = norm(sub(target, eye)), far = d + 4 * radius, near = Math.max(d - 4 * radius, far * 1e-3);
  const t = Math.tan((fov_y_deg * Math.PI) / 360), aspect = width / height;
  const proj = [[1 / (aspect * t), 0, 0, 0], [0, 1 / t, 0, 0],
    [0, 0, -(far + near) / (far - near), (-2 * far * near) / (far - near)], [0, 0, -1, 0]];
  const out = new Array(16);
  for (let i = 0; i < 4; ++i) for (let j = 0; j < 4; ++j) out[4 * j + i] = [0, 1, 2, 3].reduce((a, k) => a + proj[i][k] * view[k][j], 0);
  return out;
}

test('view_projection, by hand: eye (0, 0, 3) at the origin, 90 degrees, square, radius 0.5', () => {
  // t = tan 45 = 1; distance 3: far = 5, near = max(1, 0.005) = 1;
  // P22 = -(5 + 1) / 4 = -1.5, P23 = -2 * 5 * 1 / 4 = -2.5; view = translate(0, 0, -3).
  const m = viewProjection({ eye: [0, 0, 3], target: [0, 0, 0], up: [0, 1, 0], fov_y_deg: 90 }, 100, 100, 0.5);
  const expected = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1.5, -1, 0, 0, -1.5 * -3 - 2.5, 3];
  for (let i = 0; i < 16; ++i) close(m[i], expected[i], 1e-6, `m[${i}]`);
});

test('view_projection: near plane clamps to far / 1000 when the eye is inside 4 radii', () => {
  // distance 1, radius 1: far = 5, near = max(-3, 0.005) = 0.005.
  const m = viewProjection({ eye: [0, 0, 1], target: [0, 0, 0], up: [0, 1, 0], fov_y_deg: 90 }, 64, 64, 1);
  close(m[10], -(5 + 0.005) / (5 - 0.005), 1e-6, 'P22');
  close(m[14], -(5 + 0.005) / (5 - 0.005) * -1 + (-2 * 5 * 0.005) / (5 - 0.005), 1e-6, 'm[14]');
});

test('view_projection: an oblique, non-square case agrees with the formulas to float precision', () => {
  const cam = { eye: [1.3, 0.7, 2.9], target: [0.1, 0.25, -0.4], up: [0.05, 1, 0.1], fov_y_deg: 37.5 };
  const m = viewProjection(cam, 1280, 720, 0.8);
  const r = referenceViewProjection(cam, 1280, 720, 0.8);
  for (let i = 0; i < 16; ++i) close(m[i], r[i], 2e-6, `m[${i}]`);
  assert.ok(m instanceof Float32Array);
  // A point at the target lands at the centre of the screen.
  const p = [0, 1, 2, 3].map((i) => m[i] * 0.1 + m[4 + i] * 0.25 + m[8 + i] * -0.4 + m[12 + i]);
  close(p[0] / p[3], 0, 1e-6, 'x_ndc');
  close(p[1] / p[3], 0, 1e-6, 'y_ndc');
});

test('scene camera: SceneInfo.camera when it has 10 floats', () => {
  const c = sceneCamera({ camera: [1, 2, 3, 4, 5, 6, 0, 0, 1, 55], mean_shape: Float32Array.of(0, 0, 0) });
  assert.deepEqual(c, { eye: [1, 2, 3], target: [4, 5, 6], up: [0, 0, 1], fov_y_deg: 55 });
});

test('scene camera fallback: looking down -z at the box of x̄, 1.1 times the fitting distance, 40 degrees', () => {
  // Box [-1, 3] x [0, 2] x [-2, 2]: centre (1, 1, 0), diagonal (4, 2, 4) = 6, radius 3.
  const x = Float32Array.of(-1, 0, -2, 3, 2, 2, 0, 1, 0);
  close(sceneRadius(x), 3, 1e-7, 'radius');
  for (const camera of [null, [], [1, 2, 3]]) {  // absent or not 10 floats
    const c = sceneCamera({ camera, mean_shape: x });
    assert.deepEqual(c.target, [1, 1, 0]);
    assert.deepEqual(c.up, [0, 1, 0]);
    assert.equal(c.fov_y_deg, DEFAULT_CAMERA.fov_y_deg);
    close(c.eye[2], (3 / Math.tan((20 * Math.PI) / 180)) * 1.1, 1e-6, 'eye z');
    assert.deepEqual(c.eye.slice(0, 2), [1, 1]);
  }
});

test('scene radius of a single point is 1e-3', () => {
  assert.equal(sceneRadius(Float32Array.of(5, 5, 5)), Math.fround(1e-3));
});

test('orbit camera: starts as the scene camera, keeps the distance when rotating, zooms, resets', () => {
  const start = { eye: [0, 0, 5], target: [0, 0, 0], up: [0, 1, 0], fov_y_deg: 40 };
  const orbit = new OrbitCamera(start);
  assert.deepEqual(orbit.camera(), start);
  const v0 = orbit.version;
  orbit.rotate(Math.PI / 2, 0);
  const e = orbit.camera().eye;
  close(Math.hypot(...e), 5, 1e-9, 'distance');
  close(e[0], -5, 1e-9, 'eye x after a quarter turn');  // dragging right turns the eye to -x
  assert.ok(orbit.version > v0);
  orbit.rotate(0, 10);  // past the pole: refused, still 5 away
  close(Math.hypot(...orbit.camera().eye), 5, 1e-9, 'distance');
  orbit.zoom(2);
  close(Math.hypot(...orbit.camera().eye), 10, 1e-9, 'zoomed');
  orbit.reset();
  assert.deepEqual(orbit.camera(), start);
});

test('gridOffsets: the native default grid (camera.cpp grid_placements), 2.2 radii apart, rows back along -z', () => {
  assert.deepEqual(gridOffsets(1, 4).map((o) => o.map((v) => Math.round(v * 100) / 100)),
    [[-1.1, 0, 1.1], [1.1, 0, 1.1], [-1.1, 0, -1.1], [1.1, 0, -1.1]]);
  assert.deepEqual(gridOffsets(2, 1), [[0, 0, 0]]);
  assert.equal(gridOffsets(1, 5).length, 5);
  assert.equal(new Set(gridOffsets(1, 9).map((o) => o[0])).size, 3, 'ceil(sqrt(9)) = 3 columns');
});

test('groupCamera: centred on the group, looking down at least 30 degrees, every instance within the view', () => {
  const camera = { eye: [0, 0, 3], target: [0, 0, 0], up: [0, 1, 0], fov_y_deg: 40 };
  const offsets = gridOffsets(0.5, 16);
  const { camera: c, radius } = groupCamera(camera, 0.5, offsets);
  assert.deepEqual(c.target.map((v) => Math.abs(v) < 1e-12 ? 0 : v), [0, 0, 0]);
  const back = c.eye.map((v, k) => v - c.target[k]);
  const d = Math.hypot(...back);
  close(back[1] / d, 0.5, 1e-9, 'sin of the elevation');
  assert.ok(d * Math.tan((20 * Math.PI) / 180) >= radius, `distance ${d} frames radius ${radius}`);
  close(radius, 0.5 + 1.5 * 1.1 * Math.SQRT2, 1e-12, 'the group radius: one scene radius beyond the farthest offset');
});

test('instance=all asks for every instance of the scene in one view', () => {
  assert.equal(parseParams('?instance=all', 'h:1').instance, 'all');
  assert.equal(parseParams('?instance=3', 'h:1').instance, 3);
  assert.throws(() => parseParams('?instance=some', 'h:1'), /instance='some' is invalid/);
});

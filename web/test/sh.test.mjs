// Spherical harmonics: the basis against /work/shared/reference's table
// (spherical-harmonics.md, typed in again here from its constants), the Grace
// Cathedral probe against the values tests/client/sh_light_test.cpp checks
// for the C++, and the rotation into the support frame against independent
// computations.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  shBasis, shBand, graceCathedral, directionalLight, shRotation, lightInSupportFrame, FIT_DIRECTIONS,
  FrameLights, packLights, supportRotation, LIGHT_PROBE_NAMES, lightProbe, sceneLight,
} from '../src/sh.js';
import { supportMatrix } from '../src/packing.js';

const close = (a, b, tol, what) => assert.ok(Math.abs(a - b) <= tol, `${what}: ${a} vs ${b} (tolerance ${tol})`);

// The reference table (6-digit constants), k = l(l+1)+m, Condon-Shortley signs.
function referenceY(x, y, z) {
  return [
    0.282095, -0.488603 * y, 0.488603 * z, -0.488603 * x,
    1.092548 * x * y, -1.092548 * y * z, 0.315392 * (3 * z * z - 1), -1.092548 * x * z, 0.546274 * (x * x - y * y),
    -0.590044 * y * (3 * x * x - y * y), 2.890611 * x * y * z, -0.457046 * y * (5 * z * z - 1),
    0.373176 * z * (5 * z * z - 3), -0.457046 * x * (5 * z * z - 1), 1.445306 * z * (x * x - y * y),
    -0.590044 * x * (x * x - 3 * y * y),
  ];
}

const unit = (v) => v.map((x) => x / Math.hypot(...v));
const DIRECTIONS = [[0, 0, 1], [1, 0, 0], [0, 1, 0], unit([0.3, -0.8, 0.52]), unit([-1, 2, -3]), unit([0.1, 0.2, -0.9])];

test('shBasis matches the reference table', () => {
  for (const [x, y, z] of DIRECTIONS) {
    const Y = shBasis(x, y, z), R = referenceY(x, y, z);
    for (let k = 0; k < 16; ++k) close(Y[k], R[k], 5e-6, `Y_${k}(${x}, ${y}, ${z})`);
  }
});

test('shBasis at the north pole: only m = 0 functions, with the full-precision values', () => {
  const Y = shBasis(0, 0, 1);
  const zonal = { 0: 0.2820947917738781, 2: 0.4886025119029199, 6: 0.9461746957575601 - 0.3153915652525201,
    12: 1.865881662950577 - 1.119528997770346 };
  for (let k = 0; k < 16; ++k) close(Y[k], zonal[k] ?? 0, 1e-7, `Y_${k}(0, 0, 1)`);
});

test('shBasis values are float32, as core::sh_basis returns them', () => {
  const Y = shBasis(...unit([0.3, -0.8, 0.52]));
  for (const v of Y) assert.equal(v, Math.fround(v));
});

test('the basis is orthonormal (midpoint quadrature over the sphere)', () => {
  const n = 200, G = Array.from({ length: 16 }, () => new Float64Array(16));
  for (let i = 0; i < n; ++i) {
    const theta = ((i + 0.5) * Math.PI) / n;
    for (let j = 0; j < 2 * n; ++j) {
      const phi = ((j + 0.5) * Math.PI) / n;
      const w = Math.sin(theta) * (Math.PI / n) ** 2;
      const Y = shBasis(Math.sin(theta) * Math.cos(phi), Math.sin(theta) * Math.sin(phi), Math.cos(theta));
      for (let a = 0; a < 16; ++a) for (let b = 0; b < 16; ++b) G[a][b] += w * Y[a] * Y[b];
    }
  }
  for (let a = 0; a < 16; ++a) for (let b = 0; b < 16; ++b) close(G[a][b], a === b ? 1 : 0, 2e-4, `<Y_${a}, Y_${b}>`);
});

test('bands', () => {
  assert.deepEqual(Array.from({ length: 16 }, (_, k) => shBand(k)), [0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3]);
});

test('Grace Cathedral: Ramamoorthi-Hanrahan values with odd |m| negated (as the C++ tests check)', () => {
  const g = graceCathedral();
  assert.equal(g[0][0], Math.fround(0.78908));
  assert.equal(g[0][1], Math.fround(-0.39499));
  assert.equal(g[0][2], Math.fround(-0.33974));
  assert.equal(g[2][7], Math.fround(-0.13915));
  assert.equal(g[1][3], Math.fround(0.05562));   // L11 green, odd m: -(-.05562)
  assert.equal(g[2][8], Math.fround(-0.30374));  // L22 blue, even m: as published
  for (let c = 0; c < 3; ++c) for (let k = 9; k < 16; ++k) assert.equal(g[c][k], 0);
});

test('64 Fibonacci fitting directions, unit length, z from 1 - 1/64 down to -1 + 1/64', () => {
  assert.equal(FIT_DIRECTIONS.length, 64);
  for (const d of FIT_DIRECTIONS) close(Math.hypot(...d), 1, 1e-12, 'length');
  close(FIT_DIRECTIONS[0][2], 1 - 1 / 64, 1e-15, 'first z');
  close(FIT_DIRECTIONS[63][2], -1 + 1 / 64, 1e-15, 'last z');
});

const ROT_Y_90 = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]];  // x -> -z, z -> x
const apply = (R, v) => R.map((row) => row[0] * v[0] + row[1] * v[1] + row[2] * v[2]);
const transpose = (R) => [0, 1, 2].map((i) => R.map((row) => row[i]));
function rotation(axis, angle) {
  const [x, y, z] = unit(axis), c = Math.cos(angle), s = Math.sin(angle), t = 1 - c;
  return [[t * x * x + c, t * x * y - s * z, t * x * z + s * y], [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
    [t * x * z - s * y, t * y * z + s * x, t * z * z + c]];
}

test('rotation by 90 degrees about y, band 1 by hand: Y_3 = -c x becomes c z = Y_2', () => {
  // f(w) = -c1 x; f_rot(w) = f(R^T w) = -c1 (R^T w)_x = -c1 (-w_z) = Y_2(w).
  const D = shRotation(ROT_Y_90);
  close(D[2][3], 1, 1e-6, 'D[2][3]');
  close(D[3][2], -1, 1e-6, 'D[3][2]');  // Y_2 = c z -> c (R^T w)_z = c w_x = -Y_3
  close(D[1][1], 1, 1e-6, 'D[1][1]');   // y is the axis
  close(D[0][0], 1, 1e-9, 'D[0][0]');
});

test("rotating a directional light's SH projection equals projecting the rotated direction", () => {
  for (const R of [ROT_Y_90, rotation([1, 0.3, 0.2], -1.1), rotation([0.2, -1, 0.4], 2.5)]) {
    for (const s of DIRECTIONS) {
      const D = shRotation(R);
      const Ys = shBasis(...s), expected = shBasis(...apply(R, s));
      for (let a = 0; a < 16; ++a) {
        const rotated = D[a].reduce((sum, d, b) => sum + d * Ys[b], 0);
        close(rotated, expected[a], 1e-5, `coefficient ${a}`);
      }
    }
  }
});

test('the light in the support frame is the world light seen from the support (R^T s)', () => {
  const s = unit([0.3, 0.8, 0.52]), rgb = [2.6, 2.45, 2.2];
  for (const R of [ROT_Y_90, rotation([0, 0, 1], 0.4), rotation([1, 2, 3], 1.9)]) {
    const local = lightInSupportFrame(directionalLight(s, rgb), R);
    const expected = directionalLight(apply(transpose(R), s), rgb);
    for (let c = 0; c < 3; ++c) for (let k = 0; k < 16; ++k) close(local[c][k], expected[c][k], 1e-5, `L[${c}][${k}]`);
  }
});

test('rotation matrices are orthogonal, block diagonal and compose (as the C++ test)', () => {
  const R = rotation([1, 0.3, 0.2], -1.1), Q = rotation([0, 0, 1], 0.4);
  const D = shRotation(R);
  for (let a = 0; a < 16; ++a) {
    for (let b = 0; b < 16; ++b) {
      const ddt = D[a].reduce((s, v, k) => s + v * D[b][k], 0);
      close(ddt, a === b ? 1 : 0, 1e-6, `(D D^T)[${a}][${b}]`);
      if (shBand(a) !== shBand(b)) assert.equal(D[a][b], 0);
    }
  }
  const RQ = R.map((row) => [0, 1, 2].map((j) => row[0] * Q[0][j] + row[1] * Q[1][j] + row[2] * Q[2][j]));
  const DRQ = shRotation(RQ), DQ = shRotation(Q);
  for (let a = 0; a < 16; ++a) {
    for (let b = 0; b < 16; ++b) close(DRQ[a][b], D[a].reduce((s, v, k) => s + v * DQ[k][b], 0), 1e-6, `D(RQ)[${a}][${b}]`);
  }
  const I = shRotation([[1, 0, 0], [0, 1, 0], [0, 0, 1]]);
  for (let a = 0; a < 16; ++a) for (let b = 0; b < 16; ++b) close(I[a][b], a === b ? 1 : 0, 1e-9, `D(I)[${a}][${b}]`);
});

test('frame lights: world at vec4 0, support frame at vec4 12; recomputed only for a new rotation', () => {
  const grace = graceCathedral();
  const lights = new FrameLights(grace);
  const m = supportMatrix([0, 0, 1, 5, 0, 1, 0, 6, -1, 0, 0, 7]);  // ROT_Y_90 with a translation
  assert.deepEqual(supportRotation(m), ROT_Y_90);
  const packed = Array.from(lights.forSupport(m));
  const expected = Array.from(packLights(grace, lightInSupportFrame(grace, ROT_Y_90)));
  assert.deepEqual(packed, expected);
  assert.equal(packed[16 + 1], grace[1][1]);  // channel 1, k = 1: light[4].y
  const first = lights.key;
  lights.forSupport(supportMatrix([0, 0, 1, -3, 0, 1, 0, 0, -1, 0, 0, 1]));  // same rotation, moved
  assert.equal(lights.key, first);
});

// The probes a scene's [view] light names (core::kLightProbeNames), against
// closed forms. The sky is 0.18/0.16/0.14 below the horizon and a + b y above
// it, so over the sphere: integral of Y_0 = c0 (2 pi g + 2 pi a + pi b), of
// Y_1 = -c1 y is -c1 (-pi g + pi a + 2 pi b / 3), and it does not depend on x or z.
test('the light probes: white, sky and sun against closed forms', () => {
  assert.deepEqual(LIGHT_PROBE_NAMES, ['grace', 'sky', 'sun', 'white']);
  const white = lightProbe('white');
  for (let c = 0; c < 3; ++c) {
    close(white[c][0], 4 * Math.PI * 0.2820947917738781, 1e-6, 'white Y_0');
    for (let k = 1; k < 16; ++k) assert.equal(white[c][k], 0);
  }
  const sky = lightProbe('sky');
  const ground = [0.18, 0.16, 0.14], a = [0.45, 0.60, 0.95], b = [0.35, 0.30, 0.05];
  const c0 = 0.2820947917738781, c1 = 0.4886025119029199, PI = Math.PI;
  for (let c = 0; c < 3; ++c) {
    close(sky[c][0], c0 * (2 * PI * ground[c] + 2 * PI * a[c] + PI * b[c]), 2e-3, `sky Y_0, channel ${c}`);
    close(sky[c][1], -c1 * (-PI * ground[c] + PI * a[c] + (2 * PI * b[c]) / 3), 2e-3, `sky Y_1, channel ${c}`);
    close(sky[c][2], 0, 1e-4, `sky Y_2 (z), channel ${c}`);
    close(sky[c][3], 0, 1e-4, `sky Y_3 (x), channel ${c}`);
  }
  const sun = lightProbe('sun'), direct = directionalLight([0.3, 0.8, 0.52], [2.6, 2.45, 2.2]);
  for (let c = 0; c < 3; ++c) {
    for (let k = 0; k < 16; ++k) close(sun[c][k], direct[c][k] + 0.3 * sky[c][k], 1e-6, `sun ${c}/${k}`);
  }
  assert.equal(lightProbe('moon'), null);
  assert.equal(lightProbe('toString'), null, 'only probe names, not what every object has');
});

test('sceneLight: the scene view light and exposure, grace and 1 where it says nothing', () => {
  const plain = sceneLight({ name: 'door', view: null });
  assert.equal(plain.probe, 'grace');
  assert.equal(plain.exposure, 1);
  assert.deepEqual(plain.light, graceCathedral());
  assert.equal(plain.problem, null);
  const lit = sceneLight({ name: 'door', view: { light: 'sun', exposure: 1.5, floor_height: null } });
  assert.equal(lit.probe, 'sun');
  assert.equal(lit.exposure, 1.5);
  assert.deepEqual(lit.light, lightProbe('sun'));
  // protobufjs decodes an absent optional exposure as null, an absent light as ''.
  assert.equal(sceneLight({ name: 'door', view: { light: '', exposure: null } }).probe, 'grace');
  assert.equal(sceneLight({ name: 'door', view: { light: '', exposure: null } }).exposure, 1);
  const unknown = sceneLight({ name: 'door', view: { light: 'moon' } });
  assert.equal(unknown.probe, 'grace');
  assert.equal(unknown.problem,
    "scene 'door' asks for light 'moon', which this page does not know (expected one of grace, sky, sun, white): " +
    'drawn under grace');
});

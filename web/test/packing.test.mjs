// Packing of the bases into RGBA32F textures: layouts checked against
// layouts worked out by hand from shaders/low_rank.vert's indexing.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import {
  vec4Blocks, padColumns, pointFlags, packPoints, packNormals, chooseTextureWidth, texelCoord,
  textureImage, packScene, packReduced, supportMatrix, instanceTexels, packInstance,
} from '../src/packing.js';

test('ranks are padded to whole vec4 blocks', () => {
  assert.deepEqual([0, 1, 4, 5, 8, 11, 15].map(vec4Blocks), [0, 1, 1, 2, 2, 3, 4]);
});

test('padColumns: 3 rows x 5 columns become 3 x 8, zero-filled (U_u of one point, r_u = 5)', () => {
  const U = Float32Array.from({ length: 15 }, (_, i) => i + 1);  // row r: 5r+1 .. 5r+5
  const padded = padColumns(U, 5);
  assert.deepEqual(Array.from(padded), [
    1, 2, 3, 4, 5, 0, 0, 0,
    6, 7, 8, 9, 10, 0, 0, 0,
    11, 12, 13, 14, 15, 0, 0, 0,
  ]);
  // low_rank.vert reads row (3v + c), block b at texel (3v + c) * r_u4 + b:
  // texel 3 = row 1, block 1 = (10, 0, 0, 0).
  assert.deepEqual(Array.from(padded.subarray(4 * 3, 4 * 4)), [10, 0, 0, 0]);
});

test('padColumns leaves multiples of 4 and rank 0 as they are', () => {
  const U = Float32Array.from({ length: 8 }, (_, i) => i);
  assert.deepEqual(Array.from(padColumns(U, 4)), Array.from(U));
  assert.equal(padColumns(new Float32Array(0), 0).length, 0);
});

test('point flags: bit 0 deformable, bit 1 attached; packed into x̄ texels as w', () => {
  const flags = pointFlags(Uint8Array.of(1, 0, 1, 0), Uint8Array.of(0, 1, 1, 0));
  assert.deepEqual(Array.from(flags), [1, 2, 3, 0]);
  const x = Float32Array.of(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12);
  assert.deepEqual(Array.from(packPoints(x, flags)), [1, 2, 3, 1, 4, 5, 6, 2, 7, 8, 9, 3, 10, 11, 12, 0]);
  assert.deepEqual(Array.from(packNormals(Float32Array.of(0, 0, 1, 0, 1, 0))), [0, 0, 1, 0, 0, 1, 0, 0]);
});

test('texture width: smallest power of two whose square holds the largest texture', () => {
  assert.equal(chooseTextureWidth([1], 4096), 1);
  assert.equal(chooseTextureWidth([10, 3], 4096), 4);     // 4 x 4 = 16 >= 10
  assert.equal(chooseTextureWidth([16], 4096), 4);
  assert.equal(chooseTextureWidth([17], 4096), 8);
  assert.equal(chooseTextureWidth([238464], 16384), 512); // U_a of S = 1242, r_a = 15: 48S x 4 texels
  assert.equal(chooseTextureWidth([3e6], 2048), 2048);    // capped: 2048 x 1465
  assert.throws(() => chooseTextureWidth([5e6], 2048), /5000000 RGBA32F texels.*MAX_TEXTURE_SIZE is 2048/);
  assert.equal(chooseTextureWidth([100], 3000), 16);      // a non-power-of-two limit still gives 2^k
});

test('texel index -> (x, y) in rows of the width', () => {
  assert.deepEqual(texelCoord(0, 4), [0, 0]);
  assert.deepEqual(texelCoord(13, 4), [1, 3]);
  assert.deepEqual(texelCoord(511, 512), [511, 0]);
  assert.deepEqual(texelCoord(512 * 7 + 5, 512), [5, 7]);
});

test('texture images are whole rows, zero-filled, at least one texel', () => {
  const img = textureImage(Float32Array.from({ length: 4 * 5 }, (_, i) => i + 1), 4);
  assert.equal(img.width, 4);
  assert.equal(img.height, 2);
  assert.equal(img.data.length, 4 * 4 * 2);
  assert.deepEqual(Array.from(img.data.subarray(16, 20)), [17, 18, 19, 20]);  // texel 4 = (0, 1)
  assert.deepEqual(Array.from(img.data.subarray(20)), new Array(12).fill(0));
  const empty = textureImage(new Float32Array(0), 8);
  assert.equal(empty.height, 1);
  assert.equal(empty.data.length, 32);
});

test('packScene: a two-point scene laid out as low_rank.vert reads it', () => {
  const basis = {
    points: 2, rank_u: 2, rank_a: 5,
    mean_shape: Float32Array.of(0, 1, 2, 3, 4, 5),
    normals: Float32Array.of(0, 0, 1, 1, 0, 0),
    deformable: Uint8Array.of(1, 0),
    attached: Uint8Array.of(0, 1),
    U_u: Float32Array.from({ length: 12 }, (_, i) => i),          // 6 rows x 2
    mean_transfer: Float32Array.from({ length: 96 }, (_, i) => i), // [2][3][16]
    U_a: Float32Array.from({ length: 96 * 5 }, (_, i) => i),      // 96 rows x 5
  };
  const p = packScene(basis, 4096);
  assert.equal(p.r_u4, 1);
  assert.equal(p.r_a4, 2);
  // Largest: U_a, 96 rows x 2 blocks = 192 texels -> width 16 (16^2 = 256 >= 192).
  assert.equal(p.width, 16);
  assert.equal(p.log2Width, 4);
  assert.equal(p.images.U_a.height, 12);
  // U_a row 95, block 1 (texel 95 * 2 + 1 = 191 -> (15, 11)): columns 4..7 = (479, 0, 0, 0)
  const t = 191, img = p.images.U_a;
  assert.deepEqual(texelCoord(t, p.width), [15, 11]);
  assert.deepEqual(Array.from(img.data.subarray(4 * t, 4 * t + 4)), [479, 0, 0, 0]);
  // U_u row 5 (point 1, z), block 0 = (10, 11, 0, 0) at texel 5.
  assert.deepEqual(Array.from(p.images.U_u.data.subarray(20, 24)), [10, 11, 0, 0]);
  // M̄ point 1, channel 2, k = 12..15 at texel 12 * 1 + 4 * 2 + 3 = 23 = (7, 1).
  assert.deepEqual(Array.from(p.images.M_bar.data.subarray(4 * 23, 4 * 24)), [92, 93, 94, 95]);
  assert.deepEqual(Array.from(p.images.points.data.subarray(0, 8)), [0, 1, 2, 1, 3, 4, 5, 2]);
});

test('packScene without an appearance model still has valid (one-texel) transfer textures', () => {
  const p = packScene({
    points: 1, rank_u: 0, rank_a: 0, mean_shape: Float32Array.of(0, 0, 0), normals: Float32Array.of(0, 0, 1),
    deformable: Uint8Array.of(0), attached: Uint8Array.of(0), U_u: new Float32Array(0), mean_transfer: null, U_a: null,
  }, 4096);
  assert.equal(p.images.M_bar.data.length, 4);
  assert.equal(p.images.U_a.data.length, 4);
});

test('per frame: q_u then q_a, each padded to vec4 blocks, one spare vec4', () => {
  const q = packReduced([1, 2, 3, 4, 5], [6, 7], 2, 1);
  assert.deepEqual(Array.from(q), [1, 2, 3, 4, 5, 0, 0, 0, 6, 7, 0, 0, 0, 0, 0, 0]);
});

test('support: row-major 3x4 [R | t] becomes a column-major 4x4; none: identity', () => {
  const m = supportMatrix([1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
  assert.deepEqual(Array.from(m), [1, 5, 9, 0, 2, 6, 10, 0, 3, 7, 11, 0, 4, 8, 12, 1]);
  assert.deepEqual(Array.from(supportMatrix([])), [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
});

test('an instance row: q without its spare vec4, support, placement, support-frame light', () => {
  const r_u4 = 1, r_a4 = 1;
  assert.equal(instanceTexels(r_u4, r_a4), 22);
  const q = packReduced([1, 2, 3], [4], r_u4, r_a4);
  const support = Float32Array.from({ length: 16 }, (_, i) => 10 + i);
  const placement = Float32Array.from({ length: 16 }, (_, i) => 30 + i);
  const supportLight = Float32Array.from({ length: 48 }, (_, i) => 50 + i);
  const row = packInstance(new Float32Array(4 * 22), { q, support, placement, supportLight }, r_u4, r_a4);
  // shaders.js: q[i] = texel i; support from texel R_Q, placement R_Q + 4, light R_Q + 8.
  assert.deepEqual(Array.from(row.subarray(0, 8)), [1, 2, 3, 0, 4, 0, 0, 0]);
  assert.deepEqual(Array.from(row.subarray(4 * 2, 4 * 6)), Array.from(support));
  assert.deepEqual(Array.from(row.subarray(4 * 6, 4 * 10)), Array.from(placement));
  assert.deepEqual(Array.from(row.subarray(4 * 10, 4 * 22)), Array.from(supportLight));
});

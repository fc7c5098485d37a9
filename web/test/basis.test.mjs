// The chunked basis download against a fake server whose replies go through
// the real PageEvent encoding (so 64-bit fields arrive as the page sees them).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { loadDescriptor } from '../tools/descriptor.mjs';
import { Protocol } from '../src/protocol.js';
import { downloadBasis, checkedSpec, BasisError, ContentHashChanged, CHUNK_BYTES, hasTransfer } from '../src/basis.js';

const protocol = new Protocol(loadDescriptor());
const HASH = '12196828402476178145';  // a943d6cf7bfcdae1: above 2^53
const roundTrip = (event) => protocol.decodeEvent(protocol.PageEvent.encode(protocol.PageEvent.fromObject(event)).finish());

// A scene of S points, F triangles, ranks r_u, r_a with deterministic data.
function fakeScene({ S = 3, F = 1, r_u = 2, r_a = 5 } = {}) {
  const floats = (n, seed) => Float32Array.from({ length: n }, (_, i) => Math.fround(Math.sin(seed + i) * 10));
  const data = {
    1: floats(3 * S, 1), 2: Uint32Array.from({ length: 3 * F }, (_, i) => i % S), 3: floats(3 * S, 2),
    4: Uint8Array.from({ length: S }, (_, i) => i % 2), 5: Uint8Array.from({ length: S }, (_, i) => (i + 1) % 2),
    6: floats(3 * S * r_u, 3), 7: floats(48 * S, 4), 8: floats(48 * S * r_a, 5),
  };
  const shapes = { 1: [S, 3], 2: [F, 3], 3: [S, 3], 4: [S], 5: [S], 6: [3 * S, r_u], 7: [48 * S], 8: [48 * S, r_a] };
  const dtypes = { 1: 'float32', 2: 'uint32', 3: 'float32', 4: 'uint8', 5: 'uint8', 6: 'float32', 7: 'float32', 8: 'float32' };
  const parts = Object.keys(data).map((p) => ({ part: Number(p), dtype: dtypes[p], shape: shapes[p], total_bytes: data[p].byteLength }));
  const scene = roundTrip({ reply: { id: 1, ok: true, scenes: { scenes: [{
    name: 'cloth', content_hash: HASH, points: S, triangles: F, rank_u: r_u, rank_a: r_a, parts,
    camera: [0, 0, 3, 0, 0, 0, 0, 1, 0, 40] }] } } }).reply.scenes.scenes[0];
  return { scene, data };
}

// call(body) as the request layer's call: replies with chunks of at most
// `cap` bytes; `tamper(chunk)` may spoil one.
function fakeServer(data, { cap = Infinity, tamper = (c) => c } = {}) {
  const requests = [];
  const call = async (body) => {
    requests.push(body.basis);
    const { part, offset, max_bytes } = body.basis;
    const bytes = new Uint8Array(data[part].buffer);
    const n = Math.min(max_bytes, cap, bytes.length - offset);
    const chunk = tamper({ scene: 'cloth', part, offset, total_bytes: bytes.length, data: bytes.slice(offset, offset + n),
      content_hash: HASH });
    return roundTrip({ reply: { id: 1, ok: true, basis: chunk } }).reply;
  };
  return { call, requests };
}

test('every listed part arrives whole, as typed arrays of its dtype', async () => {
  const { scene, data } = fakeScene();
  const { call, requests } = fakeServer(data);
  const progress = [];
  const b = await downloadBasis(call, scene, { onProgress: (done, total) => progress.push([done, total]) });
  assert.deepEqual(b.mean_shape, data[1]);
  assert.deepEqual(b.triangles, data[2]);
  assert.deepEqual(b.deformable, data[4]);
  assert.deepEqual(b.U_a, data[8]);
  assert.ok(b.U_u instanceof Float32Array && b.triangles instanceof Uint32Array && b.attached instanceof Uint8Array);
  assert.equal(b.contentHash, 'a943d6cf7bfcdae1');
  assert.deepEqual(b.camera, [0, 0, 3, 0, 0, 0, 0, 1, 0, 40]);
  assert.ok(hasTransfer(b));
  assert.equal(requests.length, 8);
  assert.ok(requests.every((r) => r.max_bytes === CHUNK_BYTES && new TextDecoder().decode(r.scene) === 'cloth'));
  const total = Object.values(data).reduce((s, a) => s + a.byteLength, 0);
  assert.deepEqual(progress.at(-1), [total, total]);
  assert.ok(progress.every(([d], i) => i === 0 || d >= progress[i - 1][0]));
});

test('parts larger than a chunk come in several, each continuing at the bytes so far', async () => {
  const { scene, data } = fakeScene({ S: 40, r_a: 7 });
  const { call, requests } = fakeServer(data, { cap: 1000 });  // the server caps below max_bytes
  const b = await downloadBasis(call, scene, { chunkBytes: 4096 });
  assert.deepEqual(b.U_a, data[8]);
  const ua = requests.filter((r) => r.part === 8).map((r) => r.offset);
  assert.deepEqual(ua, Array.from({ length: Math.ceil(data[8].byteLength / 1000) }, (_, i) => 1000 * i));
});

test('a chunk from another package stops the download with ContentHashChanged', async () => {
  const { scene, data } = fakeScene();
  const { call } = fakeServer(data, { tamper: (c) => (c.part === 6 ? { ...c, content_hash: '5' } : c) });
  await assert.rejects(downloadBasis(call, scene), (e) => e instanceof ContentHashChanged &&
    /basis cloth U_U: content hash changed during the download \(0000000000000005, expected a943d6cf7bfcdae1\)/.test(e.message));
});

test('a chunk at the wrong offset, empty, or past the end is refused', async () => {
  const { scene, data } = fakeScene();
  for (const [tamper, pattern] of [
    [(c) => ({ ...c, offset: c.offset + 4 }), /chunk at offset 4 with 36 bytes \(expected offset 0 and 1\.\.36 bytes\)/],
    [(c) => ({ ...c, data: new Uint8Array(0) }), /chunk at offset 0 with 0 bytes/],
    [(c) => ({ ...c, data: new Uint8Array(c.data.length + 4) }), /with 40 bytes \(expected offset 0 and 1\.\.36 bytes\)/],
    [(c) => ({ ...c, total_bytes: 99 }), /total_bytes 99/],
  ]) {
    const { call } = fakeServer(data, { tamper: (c) => (c.part === 1 ? tamper(c) : c) });
    await assert.rejects(downloadBasis(call, scene), (e) => e instanceof BasisError && pattern.test(e.message), String(pattern));
  }
});

test('listed parts are checked against the scene sizes before any download', () => {
  const { scene } = fakeScene();
  const info = scene.parts[5];  // U_U [9, 2]
  assert.equal(checkedSpec(info, scene).totalBytes, 72);
  assert.throws(() => checkedSpec({ ...info, shape: [9, 3] }, scene), /basis part U_U is float32 \[9, 3\] \(expected float32 \[9, 2\]\)/);
  assert.throws(() => checkedSpec({ ...info, dtype: 'uint8' }, scene), /expected float32/);
  assert.throws(() => checkedSpec({ ...info, total_bytes: 70 }, scene), /total_bytes 70 \(expected 72 for its shape\)/);
  assert.throws(() => checkedSpec({ ...info, part: 12 }, scene), /basis part 12 is unknown/);
});

test('bases are validated: triangle indices, finite values, required parts', async () => {
  const { scene, data } = fakeScene();
  data[2][1] = 3;  // S = 3
  await assert.rejects(downloadBasis(fakeServer(data).call, scene), /a triangle refers to point 3 \(expected indices < S = 3\)/);
  data[2][1] = 1;
  data[6][4] = NaN;
  await assert.rejects(downloadBasis(fakeServer(data).call, scene), /basis part U_U has a non-finite value NaN at index 4/);
  data[6][4] = 0;
  const noNormals = { ...scene, parts: scene.parts.filter((p) => p.part !== 3), name: 'cloth' };
  await assert.rejects(downloadBasis(fakeServer(data).call, noNormals), /basis parts NORMALS are not listed/);
});

test('a scene without an appearance model (r_a = 0, no transfer parts) downloads and has no transfer', async () => {
  const { scene, data } = fakeScene({ r_a: 0 });
  const plain = { ...scene, parts: scene.parts.filter((p) => p.part < 7), name: 'cloth' };
  const b = await downloadBasis(fakeServer(data).call, plain);
  assert.equal(hasTransfer(b), false);
  assert.equal(b.mean_transfer, null);
});

// The static data a thin client downloads once per scene (§5.3): every part
// of SceneInfo.parts, in chunks of at most 1 MiB, each chunk checked against
// the scene's content hash and the bytes so far (as client/network/src/network.cpp).
import { asHex, asNumber, utf8 } from './protocol.js';

export const CHUNK_BYTES = 1 << 20;

// The parts of docs/protocol.md: dtype and shape for a scene of S points,
// F triangles and ranks r_u, r_a (BasisPart enum values as keys).
const PART_SPECS = {
  1: { name: 'MEAN_SHAPE', dtype: 'float32', shape: (s) => [s.points, 3] },
  2: { name: 'TRIANGLES', dtype: 'uint32', shape: (s) => [s.triangles, 3] },
  3: { name: 'NORMALS', dtype: 'float32', shape: (s) => [s.points, 3] },
  4: { name: 'DEFORMABLE', dtype: 'uint8', shape: (s) => [s.points] },
  5: { name: 'ATTACHED', dtype: 'uint8', shape: (s) => [s.points] },
  6: { name: 'U_U', dtype: 'float32', shape: (s) => [3 * s.points, s.rank_u] },
  7: { name: 'MEAN_TRANSFER', dtype: 'float32', shape: (s) => [48 * s.points] },
  8: { name: 'U_A', dtype: 'float32', shape: (s) => [48 * s.points, s.rank_a] },
};
const ELEMENT_BYTES = { float32: 4, uint32: 4, uint8: 1 };
// Parts every scene lists, by the basis member they fill.
const REQUIRED = {
  mean_shape: 'MEAN_SHAPE',
  triangles: 'TRIANGLES',
  normals: 'NORMALS',
  deformable: 'DEFORMABLE',
  attached: 'ATTACHED',
  U_u: 'U_U',
};

export class BasisError extends Error {}
// The server's package changed under the download: list scenes again, restart.
export class ContentHashChanged extends BasisError {}

// Sizes of a SceneInfo as plain numbers.
export function sceneSizes(scene) {
  return {
    points: scene.points,
    triangles: scene.triangles,
    rank_u: scene.rank_u,
    rank_a: scene.rank_a,
  };
}

// The spec of a listed part after checking dtype, shape and total_bytes.
export function checkedSpec(info, scene) {
  const part = Number(info.part);
  const spec = PART_SPECS[part];
  if (!spec) throw new BasisError(`scene '${scene.name}': basis part ${part} is unknown (expected MEAN_SHAPE..U_A)`);
  const expected = spec.shape(sceneSizes(scene));
  const shape = (info.shape ?? []).map(asNumber);
  if (info.dtype !== spec.dtype || shape.join() !== expected.join()) {
    throw new BasisError(
      `scene '${scene.name}': basis part ${spec.name} is ${info.dtype} [${shape.join(', ')}] ` +
        `(expected ${spec.dtype} [${expected.join(', ')}])`,
    );
  }
  const bytes = expected.reduce((a, b) => a * b, 1) * ELEMENT_BYTES[spec.dtype];
  if (asNumber(info.total_bytes) !== bytes) {
    throw new BasisError(
      `scene '${scene.name}': basis part ${spec.name} has total_bytes ${asNumber(info.total_bytes)} ` +
        `(expected ${bytes} for its shape)`,
    );
  }
  return { part, ...spec, totalBytes: bytes };
}

// A chunk must continue the part exactly where the bytes so far end, from the
// same package the scene was listed from.
export function checkChunk(chunk, scene, spec, done) {
  if (asHex(chunk.content_hash) !== asHex(scene.content_hash)) {
    throw new ContentHashChanged(
      `basis ${scene.name} ${spec.name}: content hash changed during the download (${asHex(chunk.content_hash)}, ` +
        `expected ${asHex(scene.content_hash)}); the server reloaded the package`,
    );
  }
  const size = chunk.data?.length ?? 0;
  const offset = asNumber(chunk.offset);
  if (Number(chunk.part) !== spec.part || asNumber(chunk.total_bytes) !== spec.totalBytes) {
    throw new BasisError(
      `basis ${scene.name} ${spec.name}: chunk of part ${chunk.part} with total_bytes ${asNumber(chunk.total_bytes)} ` +
        `(expected part ${spec.part} with ${spec.totalBytes} bytes)`,
    );
  }
  if (offset !== done || size === 0 || size > spec.totalBytes - done) {
    throw new BasisError(
      `basis ${scene.name} ${spec.name}: chunk at offset ${offset} with ${size} bytes ` +
        `(expected offset ${done} and 1..${spec.totalBytes - done} bytes)`,
    );
  }
}

// Little-endian bytes -> typed array. Every WebGL platform is little-endian;
// a big-endian one would need byte swapping, so refuse it clearly instead.
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;
export function typedArray(dtype, buffer) {
  if (!LITTLE_ENDIAN && dtype !== 'uint8') throw new BasisError('this machine is big-endian (basis parts are little-endian)');
  if (dtype === 'float32') return new Float32Array(buffer);
  if (dtype === 'uint32') return new Uint32Array(buffer);
  return new Uint8Array(buffer);
}

// One part's bytes, chunk after chunk. call(body) -> Reply (ok, else throws).
async function downloadPart(call, scene, spec, { chunkBytes, onBytes }) {
  const bytes = new Uint8Array(spec.totalBytes);
  let done = 0;
  while (done < spec.totalBytes) {
    const reply = await call({
      basis: { scene: utf8(scene.name), part: spec.part, offset: done, max_bytes: chunkBytes },
    });
    const chunk = reply.basis;
    if (!chunk) throw new BasisError(`basis ${scene.name} ${spec.name}: the reply carries no chunk`);
    checkChunk(chunk, scene, spec, done);
    bytes.set(chunk.data, done);
    done += chunk.data.length;
    onBytes(chunk.data.length);
  }
  return typedArray(spec.dtype, bytes.buffer);
}

// Every listed part of `scene`, downloaded concurrently (the request layer
// keeps at most max_requests_in_flight on the wire). onProgress(done, total)
// in bytes over all parts.
export async function downloadBasis(call, scene, { chunkBytes = CHUNK_BYTES, onProgress = () => {} } = {}) {
  const specs = (scene.parts ?? []).map((info) => checkedSpec(info, scene));
  const total = specs.reduce((sum, s) => sum + s.totalBytes, 0);
  let done = 0;
  const onBytes = (n) => {
    done += n;
    onProgress(done, total);
  };
  onProgress(0, total);
  const arrays = await Promise.all(specs.map((spec) => downloadPart(call, scene, spec, { chunkBytes, onBytes })));
  const parts = {};
  specs.forEach((spec, i) => (parts[spec.name] = arrays[i]));
  return assembleBasis(scene, parts);
}

// The client basis of a scene from its parts, validated (client_basis.cpp).
export function assembleBasis(scene, parts) {
  const camera = (scene.camera ?? []).map(Number);
  const basis = {
    scene: scene.name,
    contentHash: asHex(scene.content_hash),
    ...sceneSizes(scene),
    camera: camera.length === 10 ? camera : null,
    mean_shape: parts.MEAN_SHAPE,
    triangles: parts.TRIANGLES,
    normals: parts.NORMALS,
    deformable: parts.DEFORMABLE,
    attached: parts.ATTACHED,
    U_u: parts.U_U,
    mean_transfer: parts.MEAN_TRANSFER ?? null,
    U_a: parts.U_A ?? null,
  };
  validateBasis(basis);
  return basis;
}

function expectLength(basis, name, array, expected, how) {
  const actual = array ? array.length : 0;
  if (actual !== expected) {
    throw new BasisError(`scene '${basis.scene}': basis part ${name} has ${actual} values (expected ${expected} = ${how})`);
  }
}

function expectFinite(basis, name, array) {
  if (!array) return;
  for (let i = 0; i < array.length; ++i) {
    if (!Number.isFinite(array[i])) {
      throw new BasisError(`scene '${basis.scene}': basis part ${name} has a non-finite value ${array[i]} at index ${i}`);
    }
  }
}

export function validateBasis(b) {
  const missing = Object.entries(REQUIRED).filter(([key]) => !b[key]).map(([, name]) => name);
  if (missing.length > 0) throw new BasisError(`scene '${b.scene}': basis parts ${missing.join(', ')} are not listed`);
  const S = b.points;
  if (!(S > 0)) throw new BasisError(`scene '${b.scene}': ${S} points (expected S > 0)`);
  expectLength(b, 'MEAN_SHAPE', b.mean_shape, 3 * S, '3S');
  expectLength(b, 'NORMALS', b.normals, 3 * S, '3S');
  expectLength(b, 'DEFORMABLE', b.deformable, S, 'S');
  expectLength(b, 'ATTACHED', b.attached, S, 'S');
  expectLength(b, 'U_U', b.U_u, 3 * S * b.rank_u, '3S x r_u');
  if (b.triangles.length === 0 || b.triangles.length % 3 !== 0) {
    throw new BasisError(`scene '${b.scene}': ${b.triangles.length} triangle indices (expected a positive multiple of 3)`);
  }
  const worst = b.triangles.reduce((m, v) => (v > m ? v : m), 0);
  if (worst >= S) throw new BasisError(`scene '${b.scene}': a triangle refers to point ${worst} (expected indices < S = ${S})`);
  if (b.mean_transfer) {
    expectLength(b, 'MEAN_TRANSFER', b.mean_transfer, 48 * S, '48S');
    expectLength(b, 'U_A', b.U_a, 48 * S * b.rank_a, '48S x r_a');
  } else if (b.rank_a !== 0) {
    throw new BasisError(`scene '${b.scene}': r_a = ${b.rank_a} but MEAN_TRANSFER is not listed (expected 48S values)`);
  }
  for (const [name, key] of [['MEAN_SHAPE', 'mean_shape'], ['NORMALS', 'normals'], ['U_U', 'U_u'],
    ['MEAN_TRANSFER', 'mean_transfer'], ['U_A', 'U_a']]) expectFinite(b, name, b[key]);
}

// Whether the scene has an appearance model (§4), as ClientBasis::has_transfer.
export const hasTransfer = (b) => b.mean_transfer !== null && b.mean_transfer.length > 0;

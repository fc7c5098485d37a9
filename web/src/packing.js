// Packing the bases for WebGL2. WebGL2 has no shader storage buffers, so
// every array low_rank.vert reads from a buffer becomes an RGBA32F texture
// read with texelFetch: texel i of a texture of width W (a power of two) is
// at (i & (W - 1), i >> log2 W). Row-major layouts (the native client tiles
// its storage buffers by points instead, shaders/bindings.glsl): ranks padded
// to whole vec4 blocks, r_u4 = ceil(r_u / 4), r_a4 = ceil(r_a / 4), so each
// basis row is one run of vec4 texels.
// Pure functions: tested in node (test/packing.test.mjs).

export const vec4Blocks = (rank) => Math.ceil(rank / 4);

// Row-major rows x cols -> rows x 4 ceil(cols / 4), zero-padded
// (pad_columns of low_rank_renderer.cpp).
export function padColumns(matrix, cols) {
  const padded = 4 * vec4Blocks(cols);
  if (cols === 0 || cols === padded) return Float32Array.from(matrix);
  const rows = matrix.length / cols;
  const out = new Float32Array(rows * padded);
  for (let r = 0; r < rows; ++r) out.set(matrix.subarray(r * cols, (r + 1) * cols), r * padded);
  return out;
}

// Bit 0 deformable, bit 1 attached (shaders/low_rank.vert).
export function pointFlags(deformable, attached) {
  const flags = new Uint8Array(deformable.length);
  for (let v = 0; v < flags.length; ++v) flags[v] = (deformable[v] ? 1 : 0) | (attached[v] ? 2 : 0);
  return flags;
}

// One texel per point: x̄ in xyz, the flags in w (0..3, exact as a float),
// so the per-point pass reads position and flags with one fetch.
export function packPoints(meanShape, flags) {
  const S = flags.length;
  const out = new Float32Array(4 * S);
  for (let v = 0; v < S; ++v) {
    out[4 * v] = meanShape[3 * v];
    out[4 * v + 1] = meanShape[3 * v + 1];
    out[4 * v + 2] = meanShape[3 * v + 2];
    out[4 * v + 3] = flags[v];
  }
  return out;
}

// Rest normals, one texel per point (w = 0).
export function packNormals(normals) {
  const S = normals.length / 3;
  const out = new Float32Array(4 * S);
  for (let v = 0; v < S; ++v) out.set(normals.subarray(3 * v, 3 * v + 3), 4 * v);
  return out;
}

// The smallest power-of-two width W <= maxTextureSize with W >= sqrt(texels),
// so the largest texture is about square; one W for every texture of a scene
// (the shader gets it as a compile-time constant). Throws when the largest
// texture does not fit in maxTextureSize x maxTextureSize texels.
export function chooseTextureWidth(texelCounts, maxTextureSize) {
  const most = Math.max(1, ...texelCounts);
  const maxWidth = 2 ** Math.floor(Math.log2(maxTextureSize));
  let width = 1;
  while (width * width < most && width < maxWidth) width *= 2;
  const height = Math.ceil(most / width);
  if (height > maxTextureSize) {
    throw new Error(
      `a basis texture needs ${most} RGBA32F texels, more than ${maxWidth} x ${maxTextureSize} ` +
        `(this GPU's MAX_TEXTURE_SIZE is ${maxTextureSize})`,
    );
  }
  return width;
}

// Linear texel index -> (x, y) in a texture of power-of-two width.
export function texelCoord(index, width) {
  return [index & (width - 1), Math.floor(index / width)];
}

// vec4 data (4 floats per texel) laid out in rows of `width` texels; the
// last row is zero-filled. At least one texel, so every sampler is valid.
export function textureImage(vec4Data, width) {
  const texels = Math.max(1, vec4Data.length / 4);
  const height = Math.ceil(texels / width);
  const data = new Float32Array(4 * width * height);
  data.set(vec4Data);
  return { width, height, data };
}

// Everything the WebGL renderer uploads once per scene, as texture images,
// plus the sizes its shaders are compiled with.
export function packScene(basis, maxTextureSize) {
  const flags = pointFlags(basis.deformable, basis.attached);
  const r_u4 = vec4Blocks(basis.rank_u);
  const r_a4 = vec4Blocks(basis.rank_a);
  const arrays = {
    points: packPoints(basis.mean_shape, flags),       // [S]: x̄, flags
    normals: packNormals(basis.normals),              // [S]
    U_u: padColumns(basis.U_u, basis.rank_u),          // [3S][r_u4]
    M_bar: basis.mean_transfer ? Float32Array.from(basis.mean_transfer) : new Float32Array(0), // [S][3][4]
    U_a: basis.U_a ? padColumns(basis.U_a, basis.rank_a) : new Float32Array(0),             // [48S][r_a4]
  };
  const width = chooseTextureWidth(Object.values(arrays).map((a) => a.length / 4), maxTextureSize);
  const images = {};
  for (const [name, array] of Object.entries(arrays)) images[name] = textureImage(array, width);
  return { width, log2Width: Math.log2(width), r_u4, r_a4, points: basis.points, images };
}

// Per frame: q_u then q_a, each padded to vec4 blocks (upload_reduced).
export function packReduced(q_u, q_a, r_u4, r_a4, out = new Float32Array(4 * (r_u4 + r_a4) + 4)) {
  out.fill(0);
  out.set(q_u.slice(0, 4 * r_u4), 0);
  out.set(q_a.slice(0, 4 * r_a4), 4 * r_u4);
  return out;
}

// The instance texture (shaders.js instances_tex) holds one row per instance
// drawn: q_u and q_a (packReduced, without its spare vec4), the support
// matrix and the placement (4 columns each), then the light in the support
// frame (12 vec4s). One upload per frame serves every instance's draw.
export const instanceTexels = (r_u4, r_a4) => r_u4 + r_a4 + 20;

// Writes one instance's row into `row` (4 instanceTexels floats); q: the
// packed q (packReduced), support and placement: column-major 4x4s,
// supportLight: the 48 support-frame light coefficients (sh.js packLights).
export function packInstance(row, { q, support, placement, supportLight }, r_u4, r_a4) {
  const at = 4 * (r_u4 + r_a4);
  row.set(q.subarray(0, at), 0);
  row.set(support, at);
  row.set(placement, at + 16);
  row.set(supportLight, at + 32);
  return row;
}

// Frame.support (3x4 row-major [R | t], support frame -> world) as a
// column-major 4x4 for GLSL; identity when the frame has none.
export function supportMatrix(support) {
  const m = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
  if (support && support.length === 12) {
    for (let i = 0; i < 3; ++i) for (let j = 0; j < 4; ++j) m[4 * j + i] = support[4 * i + j];
  }
  return m;
}

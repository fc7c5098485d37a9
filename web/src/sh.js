// Spherical harmonics of the lights (core/include/phasecast/core/sh.h and
// client/scene/src/sh_light.cpp): real SH of order 4 (16 functions, k = l(l+1)+m,
// Condon-Shortley phase, z = cos(theta)), the Grace Cathedral probe, and the
// rotation of a light into the support frame by the same least-squares fit at
// 64 Fibonacci directions, so the page lights points as the C++ client does.
// A light is [3][16] float32 coefficients (RGB channel, k).

const PI = Math.PI;
const f32 = Math.fround;

// Y_k(x, y, z), k = 0..15, for a unit vector; each value rounded to float32 as
// core::sh_basis returns floats.
export function shBasis(x, y, z) {
  const c0 = 0.2820947917738781, c1 = 0.4886025119029199, c2a = 1.092548430592079;
  const c2b = 0.9461746957575601, c2c = 0.3153915652525201, c2d = 0.5462742152960395;
  const c3a = 0.5900435899266435, c3b = 2.890611442640554, c3c = 0.4570457994644658;
  const c3d = 1.865881662950577, c3e = 1.119528997770346, c3f = 1.445305721320277;
  const x2 = x * x, y2 = y * y, z2 = z * z;
  return Float64Array.from(
    [c0, -c1 * y, c1 * z, -c1 * x,
      c2a * x * y, -c2a * y * z, c2b * z2 - c2c, -c2a * x * z, c2d * (x2 - y2),
      -c3a * y * (3 * x2 - y2), c3b * x * y * z, -c3c * y * (5 * z2 - 1), c3d * z2 * z - c3e * z,
      -c3c * x * (5 * z2 - 1), c3f * z * (x2 - y2), -c3a * x * (x2 - 3 * y2)],
    f32,
  );
}

// Band l of coefficient k.
export const shBand = (k) => (k < 1 ? 0 : k < 4 ? 1 : k < 9 ? 2 : 3);

const emptyLight = () => [new Float32Array(16), new Float32Array(16), new Float32Array(16)];

// Grace Cathedral, Ramamoorthi & Hanrahan 2001 (9 coefficients, RGB, their
// all-positive constants): odd |m| entries (k = 1, 3, 5, 7) negated for the
// Condon-Shortley convention of shBasis. Bands 3 are zero.
export function graceCathedral() {
  const rh = [
    [0.78908, 0.4371, 0.54161], [0.39499, 0.34989, 0.60488], [-0.33974, -0.18236, -0.2694],
    [-0.29213, -0.05562, 0.00944], [-0.11141, -0.0509, -0.12231], [-0.2624, -0.22401, -0.47479],
    [-0.1557, -0.09471, -0.14733], [0.56014, 0.21444, 0.13915], [0.21205, -0.05432, -0.30374],
  ];
  const light = emptyLight();
  for (let k = 0; k < 9; ++k) {
    for (let c = 0; c < 3; ++c) light[c][k] = k % 2 === 1 ? -rh[k][c] : rh[k][c];
  }
  return light;
}

// A light of radiance rgb arriving from unit direction towards_light
// (directional_light of sh_light.cpp): L_ck = rgb_c Y_k(s).
export function directionalLight([x, y, z], rgb) {
  const n = Math.hypot(x, y, z);
  const Y = shBasis(x / n, y / n, z / n);
  const light = emptyLight();
  for (let c = 0; c < 3; ++c) for (let k = 0; k < 16; ++k) light[c][k] = rgb[c] * Y[k];
  return light;
}

// Coefficients of radiance(x, y, z) -> [r, g, b] by a theta/phi product rule
// with `samples` steps in theta and twice that in phi (project_light of
// sh_light.cpp, the same order of summation), rounded to float32.
export function projectLight(radiance, samples = 128) {
  const sum = [new Float64Array(16), new Float64Array(16), new Float64Array(16)];
  const dTheta = PI / samples, dPhi = (2 * PI) / (2 * samples);
  for (let i = 0; i < samples; ++i) {
    const theta = (i + 0.5) * dTheta;
    const weight = Math.sin(theta) * dTheta * dPhi;
    for (let j = 0; j < 2 * samples; ++j) {
      const phi = (j + 0.5) * dPhi;
      const x = Math.sin(theta) * Math.cos(phi), y = Math.sin(theta) * Math.sin(phi), z = Math.cos(theta);
      const L = radiance(x, y, z), Y = shBasis(x, y, z);
      for (let c = 0; c < 3; ++c) for (let k = 0; k < 16; ++k) sum[c][k] += weight * L[c] * Y[k];
    }
  }
  return sum.map((channel) => Float32Array.from(channel));
}

// The probes of light_probe (sh_light.cpp), by the names packages store in
// their [view] light (core::kLightProbeNames).
const sky = () => projectLight((x, y) =>
  (y < 0 ? [0.18, 0.16, 0.14] : [0.45 + 0.35 * y, 0.60 + 0.30 * y, 0.95 + 0.05 * y]));

function sun() {
  const light = directionalLight([0.3, 0.8, 0.52], [2.6, 2.45, 2.2]);
  const ambient = sky();
  // 0.3f * ambient in float arithmetic, as the C++ adds it.
  for (let c = 0; c < 3; ++c) {
    for (let k = 0; k < 16; ++k) light[c][k] = f32(light[c][k] + f32(f32(0.3) * ambient[c][k]));
  }
  return light;
}

function whiteFurnace() {
  const light = emptyLight();
  for (let c = 0; c < 3; ++c) light[c][0] = 4 * PI * 0.2820947917738781;
  return light;
}

const PROBES = { grace: graceCathedral, sky, sun, white: whiteFurnace };
export const LIGHT_PROBE_NAMES = Object.keys(PROBES);

// The named probe, or null for a name this page does not know.
export function lightProbe(name) {
  return Object.hasOwn(PROBES, name) ? PROBES[name]() : null;
}

// The scene's [view] light and exposure (SceneInfo.view), as phasecast-render
// takes them without its own flags: grace and 1 where the scene says nothing.
// A probe this page does not know is drawn under grace, and said.
export function sceneLight(scene) {
  const view = scene.view ?? {};
  const asked = view.light || 'grace';
  const light = lightProbe(asked);
  return {
    probe: light ? asked : 'grace',
    light: light ?? lightProbe('grace'),
    exposure: view.exposure ?? 1,
    problem: light ? null : `scene '${scene.name}' asks for light '${asked}', which this page does not know ` +
      `(expected one of ${LIGHT_PROBE_NAMES.join(', ')}): drawn under grace`,
  };
}

// The 64 fitting directions (Fibonacci sphere) of sh_light.cpp.
export const FIT_DIRECTIONS = (() => {
  const n = 64, golden = PI * (3 - Math.sqrt(5));
  const dirs = [];
  for (let i = 0; i < n; ++i) {
    const z = 1 - (2 * i + 1) / n, r = Math.sqrt(1 - z * z), phi = golden * i;
    dirs.push([r * Math.cos(phi), r * Math.sin(phi), z]);
  }
  return dirs;
})();

// Solves the symmetric positive definite system G X = B in place (Cholesky);
// G is n x n, B is n x m, both arrays of rows.
function choleskySolve(G, B) {
  const n = G.length;
  const L = G.map((row) => row.slice());
  for (let j = 0; j < n; ++j) {
    for (let k = 0; k < j; ++k) L[j][j] -= L[j][k] * L[j][k];
    L[j][j] = Math.sqrt(L[j][j]);
    for (let i = j + 1; i < n; ++i) {
      for (let k = 0; k < j; ++k) L[i][j] -= L[i][k] * L[j][k];
      L[i][j] /= L[j][j];
    }
  }
  const X = B.map((row) => row.slice());
  for (let col = 0; col < X[0].length; ++col) {
    for (let i = 0; i < n; ++i) {
      let s = X[i][col];
      for (let k = 0; k < i; ++k) s -= L[i][k] * X[k][col];
      X[i][col] = s / L[i][i];
    }
    for (let i = n - 1; i >= 0; --i) {
      let s = X[i][col];
      for (let k = i + 1; k < n; ++k) s -= L[k][i] * X[k][col];
      X[i][col] = s / L[i][i];
    }
  }
  return X;
}

// The least-squares solver for coefficients from values at FIT_DIRECTIONS:
// pinv(A) = (A^T A)^-1 A^T, 16 x 64, A_ik = Y_k(d_i). A has full column rank,
// so this is the solution sh_light.cpp gets from a QR solve.
export const FIT_PSEUDO_INVERSE = (() => {
  const A = FIT_DIRECTIONS.map(([x, y, z]) => shBasis(x, y, z));
  const G = Array.from({ length: 16 }, (_, a) =>
    Array.from({ length: 16 }, (_, b) => A.reduce((s, row) => s + row[a] * row[b], 0)));
  const At = Array.from({ length: 16 }, (_, a) => A.map((row) => row[a]));
  return choleskySolve(G, At);
})();

// 16 x 16 matrix D (array of rows) with D c = coefficients of f(R^T w) for
// f with coefficients c: fitted at the 64 directions, cross-band round-off
// dropped (sh_rotation of sh_light.cpp). R: 3x3 array of rows.
export function shRotation(R) {
  const B = FIT_DIRECTIONS.map(([x, y, z]) => {
    // R^T d
    const u = R[0][0] * x + R[1][0] * y + R[2][0] * z;
    const v = R[0][1] * x + R[1][1] * y + R[2][1] * z;
    const w = R[0][2] * x + R[1][2] * y + R[2][2] * z;
    return shBasis(u, v, w);
  });
  const D = [];
  for (let a = 0; a < 16; ++a) {
    const row = new Float64Array(16);
    for (let b = 0; b < 16; ++b) {
      if (shBand(a) !== shBand(b)) continue;
      let s = 0;
      for (let i = 0; i < B.length; ++i) s += FIT_PSEUDO_INVERSE[a][i] * B[i][b];
      row[b] = s;
    }
    D.push(row);
  }
  return D;
}

const transpose3 = (R) => [0, 1, 2].map((i) => [R[0][i], R[1][i], R[2][i]]);

// The world light seen from the support frame (light_in_support_frame):
// R is the support's rotation (support frame -> world), so a world direction
// w is R^T w there; each channel is rotated by shRotation(R^T).
export function lightInSupportFrame(world, R) {
  const D = shRotation(transpose3(R));
  const out = emptyLight();
  for (let c = 0; c < 3; ++c) {
    for (let a = 0; a < 16; ++a) {
      let s = 0;
      for (let b = 0; b < 16; ++b) s += D[a][b] * world[c][b];
      out[c][a] = s;
    }
  }
  return out;
}

// The 3x3 rotation of a column-major 4x4 support matrix (packing.supportMatrix).
export function supportRotation(m) {
  return [0, 1, 2].map((i) => [m[i], m[4 + i], m[8 + i]]);
}

// Light coefficients 16c + k as low_rank.vert's uniform vec4 light[24]:
// the world light at vec4 0, the support-frame light at vec4 12.
export function packLights(world, local, out = new Float32Array(96)) {
  for (let c = 0; c < 3; ++c) {
    out.set(world[c], 16 * c);
    out.set(local[c], 48 + 16 * c);
  }
  return out;
}

// Light as the uniform array for a frame: the support-frame light is only
// recomputed when the support rotation changes.
export class FrameLights {
  constructor(world) {
    this.world = world;
    this.key = null;
    this.packed = new Float32Array(96);
  }

  forSupport(supportMatrix4) {
    const R = supportRotation(supportMatrix4);
    const key = R.flat().join();
    if (key !== this.key) {
      packLights(this.world, lightInSupportFrame(this.world, R), this.packed);
      this.key = key;
    }
    return this.packed;
  }
}

// The benchmarks' synthetic scene, frames and timer (lightdot.mjs, instances.mjs).

// A side x side grid of points in the z = 0 plane, two triangles per cell,
// random small bases; half the points attached to the support.
export function syntheticBasis(side, rank_u, rank_a) {
  const S = side * side;
  let seed = 1;
  const rnd = () => ((seed = (seed * 16807) % 2147483647) / 2147483647) - 0.5;
  const mean_shape = new Float32Array(3 * S), normals = new Float32Array(3 * S);
  for (let i = 0; i < S; ++i) {
    mean_shape.set([(i % side) / side - 0.5, Math.floor(i / side) / side - 0.5, 0], 3 * i);
    normals.set([0, 0, 1], 3 * i);
  }
  const triangles = [];
  for (let y = 0; y + 1 < side; ++y) {
    for (let x = 0; x + 1 < side; ++x) {
      const i = y * side + x;
      triangles.push(i, i + 1, i + side, i + 1, i + side + 1, i + side);
    }
  }
  return {
    scene: 'synthetic', contentHash: '0', points: S, rank_u, rank_a, camera: null,
    mean_shape, normals, triangles: Uint32Array.from(triangles),
    deformable: new Uint8Array(S).fill(1), attached: Uint8Array.from({ length: S }, (_, i) => i % 2),
    U_u: Float32Array.from({ length: 3 * S * rank_u }, () => 0.01 * rnd()),
    mean_transfer: Float32Array.from({ length: 48 * S }, () => 0.1 + 0.05 * rnd()),
    U_a: Float32Array.from({ length: 48 * S * rank_a }, () => 0.01 * rnd()),
  };
}

const sync = (gl) => gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));

export function frames(basis, count) {
  return Array.from({ length: count }, (_, i) => {
    const a = 0.01 * i, c = Math.cos(a), s = Math.sin(a);  // the support turns every frame
    return { q_u: Array.from({ length: basis.rank_u }, (_, j) => Math.sin(i + j)),
      q_a: Array.from({ length: basis.rank_a }, (_, j) => Math.cos(i + j)),
      support: [c, 0, s, 0, 0, 1, 0, 0, -s, 0, c, 0] };
  });
}

export function time(gl, list, drawOne) {
  drawOne(list[0]);
  sync(gl);
  const t0 = performance.now();
  for (const f of list) drawOne(f);
  sync(gl);
  return (performance.now() - t0) / list.length;
}


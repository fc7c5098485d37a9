// Browser side of tools/bench/instances.mjs: times N instances of a synthetic
// cloth-sized scene drawn by the page's renderer (one instanced per-point
// pass and one triangle draw) against two baselines in the same run: the
// same N instances drawn as static meshes (the triangle draw alone, from
// points evaluated once), and each instance evaluated and drawn in turn by
// the same program (2N draw calls, the page's structure before its one
// instanced draw; its shader then took q and the light as uniforms). The
// static meshes draw the points one_draw evaluated just before them in each
// round (in_turn leaves only instance 0's slot of the buffer filled).
import { Renderer } from '../../src/renderer.js';
import { sceneCamera, sceneRadius, gridOffsets, groupCamera } from '../../src/camera.js';
import { syntheticBasis, frames, time } from './synthetic.js';

window.bench = ({ side, rank_u, rank_a, count, instances }) => {
  const r = new Renderer(document.getElementById('c'));
  const gl = r.gl;
  const basis = syntheticBasis(side, rank_u, rank_a);
  r.useScene(r.createScene(basis));
  const radius = sceneRadius(basis.mean_shape), offsets = gridOffsets(radius, instances);
  const { camera, radius: viewRadius } = groupCamera(sceneCamera(basis), radius, offsets);
  const all = frames(basis, count * instances);
  const groups = Array.from({ length: count }, (_, i) => all.slice(i * instances, (i + 1) * instances));
  const variants = {
    one_draw: (fs) => r.drawMany(fs, offsets, camera, viewRadius),
    static: () => {
      r.beginFrame();
      r.drawTriangles(r.scene, camera, viewRadius, instances);
    },
    in_turn: (fs) => {
      r.beginFrame();
      fs.forEach((f, i) => {
        r.evaluatePoints(r.scene, [f], [offsets[i]]);
        r.drawTriangles(r.scene, camera, viewRadius, 1);
      });
    },
  };
  // Three rounds, the variants interleaved in this order (static after
  // one_draw); each variant's fastest round.
  const ms = { one_draw: Infinity, static: Infinity, in_turn: Infinity };
  for (let round = 0; round < 3; ++round) {
    for (const [name, drawOne] of Object.entries(variants)) ms[name] = Math.min(ms[name], time(gl, groups, drawOne));
  }
  const [oneDraw, staticMeshes, inTurn] = [ms.one_draw, ms.static, ms.in_turn];
  return { S: basis.points, instances, rank_u, rank_a, static_ms: staticMeshes, one_draw_ms: oneDraw, in_turn_ms: inTurn,
    one_draw_of_static: staticMeshes / oneDraw, in_turn_of_static: staticMeshes / inTurn,
    renderer: gl.getParameter(gl.RENDERER) };
};

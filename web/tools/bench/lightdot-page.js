// Browser side of tools/bench/lightdot.mjs: times the renderer's per-frame
// light-dot (variant A, what the page ships) against light-dotting on the
// CPU when the light seen by the points changes (variant B, as
// light_dot.comp does on the GPU in the C++ client) on a synthetic scene.
import { Renderer } from '../../src/renderer.js';
import { packScene, supportMatrix } from '../../src/packing.js';
import { evaluationVertexShader } from '../../src/shaders.js';
import { sceneCamera, sceneRadius } from '../../src/camera.js';
import { syntheticBasis, frames, time } from './synthetic.js';
import { FrameLights } from '../../src/sh.js';

// Variant B's vertex shader: transfer_radiance reads M̄.L (M_bar_tex, [S])
// and U_a.L (U_a_tex, [S][3][r_a4]) light-dotted beforehand.
function predottedShader(packed) {
  const source = evaluationVertexShader({ ...packed, hasTransfer: true });
  const start = source.indexOf('vec3 transfer_radiance');
  const end = source.indexOf('#endif', start);
  return source.slice(0, start) + `vec3 transfer_radiance(int v) {
  vec3 rgb = fetch(M_bar_tex, v).xyz;
  for (int c = 0; c < 3; ++c) {
    for (int b = 0; b < R_A4; ++b) rgb[c] += dot(fetch(U_a_tex, (3 * v + c) * R_A4 + b), q[R_U4 + b]);
  }
  return rgb;
}
` + source.slice(end);
}

// light_dot.comp in JS: M_dot [S] vec4, U_dot [S][3][r_a4] vec4 (rows of the image data).
function lightDot(basis, packed, lights, mDot, uDot) {
  const S = basis.points, n = 4 * packed.r_a4, Ua = packed.images.U_a.data, M = basis.mean_transfer;
  for (let v = 0; v < S; ++v) {
    const base = basis.attached[v] ? 48 : 0;
    for (let c = 0; c < 3; ++c) {
      let m = 0;
      const out = (3 * v + c) * n;
      uDot.fill(0, out, out + n);
      for (let k = 0; k < 16; ++k) {
        const L = lights[base + 16 * c + k], row = (48 * v + 16 * c + k) * n;
        m += M[48 * v + 16 * c + k] * L;
        for (let j = 0; j < n; ++j) uDot[out + j] += Ua[row + j] * L;
      }
      mDot[4 * v + c] = m;
    }
  }
}

window.bench = ({ side, rank_u, rank_a, count }) => {
  const canvas = document.getElementById('c');
  const r = new Renderer(canvas);
  const gl = r.gl;
  const basis = syntheticBasis(side, rank_u, rank_a);
  const scene = r.createScene(basis);
  r.useScene(scene);
  const camera = sceneCamera(basis), radius = sceneRadius(basis.mean_shape);
  const list = frames(basis, count);
  const A = time(gl, list, (f) => r.draw(f, camera, radius));

  // Variant B: swap in the pre-dotted program and textures (same slots).
  const packed = packScene(basis, r.maxTextureSize);
  const vs = gl.createShader(gl.VERTEX_SHADER);
  gl.shaderSource(vs, predottedShader(packed));
  gl.compileShader(vs);
  if (!gl.getShaderParameter(vs, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(vs));
  const fs = gl.createShader(gl.FRAGMENT_SHADER);
  gl.shaderSource(fs, '#version 300 es\nprecision mediump float;out vec4 o;void main(){o=vec4(0.0);}');
  gl.compileShader(fs);
  const p = gl.createProgram();
  gl.attachShader(p, vs);
  gl.attachShader(p, fs);
  gl.transformFeedbackVaryings(p, ['world_position', 'radiance'], gl.INTERLEAVED_ATTRIBS);
  gl.linkProgram(p);
  scene.program = p;
  for (const name of Object.keys(scene.uniforms)) scene.uniforms[name] = gl.getUniformLocation(p, name);
  const width = packed.width, S = basis.points;
  const mImg = { h: Math.ceil(S / width) }, uImg = { h: Math.ceil((3 * S * packed.r_a4) / width) };
  const mDot = new Float32Array(4 * width * mImg.h), uDot = new Float32Array(4 * width * uImg.h);
  const upload = (texture, data, h) => {
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, h, 0, gl.RGBA, gl.FLOAT, data);
  };
  const frameLights = new FrameLights(r.world);
  const redot = (f) => {
    const lights = frameLights.forSupport(supportMatrix(f.support));
    const t = performance.now();
    lightDot(basis, packed, lights, mDot, uDot);
    upload(scene.textures.M_bar, mDot, mImg.h);
    upload(scene.textures.U_a, uDot, uImg.h);
    return performance.now() - t;
  };
  redot(list[0]);
  const rest = list.map((f) => ({ ...f, support: list[0].support }));
  const Brest = time(gl, rest, (f) => r.draw(f, camera, radius));
  let cpu = 0;
  const Brot = time(gl, list, (f) => { cpu += redot(f); r.draw(f, camera, radius); });
  return { S, triangles: basis.triangles.length / 3, rank_u, rank_a, A_ms: A, B_rest_ms: Brest, B_rotating_ms: Brot,
    B_redot_cpu_ms: cpu / (list.length + 1), renderer: gl.getParameter(gl.RENDERER) };
};

// WebGL2 renderer of the low-rank superposition (§5.3), after
// client/render/src/low_rank_renderer.cpp: the bases go to the GPU once per scene
// (RGBA32F textures, packing.js); per frame only q_u, q_a (uniforms), the
// support matrix and the lights change. Each frame: a per-point pass
// evaluates x̄ + U_u q_u, the support transform and the light-dotted transfer
// once per scene point into a transform-feedback buffer; the triangles are
// then drawn from that buffer (shared points are not evaluated again).
import { packScene, packReduced, supportMatrix } from './packing.js';
import { hasTransfer } from './basis.js';
import { FrameLights, graceCathedral } from './sh.js';
import { viewProjection } from './camera.js';
import {
  evaluationVertexShader,
  DISCARD_FRAGMENT_SHADER,
  DRAW_VERTEX_SHADER,
  RADIANCE_FRAGMENT_SHADER,
} from './shaders.js';

export class RenderError extends Error {}

// Column-major 4x4 helpers for placements.
function translation([x, y, z]) {
  return new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1]);
}

function multiply(a, b) {
  const out = new Float32Array(16);
  for (let c = 0; c < 4; ++c) {
    for (let r = 0; r < 4; ++r) {
      let sum = 0;
      for (let k = 0; k < 4; ++k) sum += a[4 * k + r] * b[4 * c + k];
      out[4 * c + r] = sum;
    }
  }
  return out;
}

const CLEAR_COLOUR = [0.02, 0.02, 0.025, 1];  // low_rank_renderer.cpp begin_frame
const TEXTURES = ['points', 'normals', 'U_u', 'M_bar', 'U_a'];

// The first line of a GL info log: enough for a one-line error.
const firstLine = (log) => (log || '').split('\n').find((l) => l.trim()) || '(no log)';

function compile(gl, type, source, name) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) {
    const log = gl.getShaderInfoLog(shader);
    gl.deleteShader(shader);
    throw new RenderError(`shader ${name} does not compile: ${firstLine(log)}`);
  }
  return shader;
}

// A linked program; `varyings`: captured by transform feedback (interleaved).
function link(gl, vertexSource, fragmentSource, name, varyings = null) {
  const vs = compile(gl, gl.VERTEX_SHADER, vertexSource, `${name}.vert`);
  const fs = compile(gl, gl.FRAGMENT_SHADER, fragmentSource, `${name}.frag`);
  const program = gl.createProgram();
  gl.attachShader(program, vs);
  gl.attachShader(program, fs);
  if (varyings) gl.transformFeedbackVaryings(program, varyings, gl.INTERLEAVED_ATTRIBS);
  gl.linkProgram(program);
  gl.deleteShader(vs);  // a linked program no longer needs them
  gl.deleteShader(fs);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) {
    throw new RenderError(`shader program ${name} does not link: ${firstLine(gl.getProgramInfoLog(program))}`);
  }
  return program;
}

function uniforms(gl, program, names) {
  const out = {};
  for (const name of names) out[name] = gl.getUniformLocation(program, name);
  return out;
}

function floatTexture(gl, image) {
  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, image.width, image.height, 0, gl.RGBA, gl.FLOAT, image.data);
  return texture;
}

export class Renderer {
  constructor(canvas) {
    const gl = canvas.getContext('webgl2', {
      preserveDrawingBuffer: true,  // tests read pixels after the frame
      antialias: false,             // as the C++ client's single-sample framebuffer
      alpha: false,
      depth: true,
    });
    if (!gl) throw new RenderError('this browser gives no WebGL2 context (WebGL2 is needed for the bases as float textures)');
    this.gl = gl;
    this.canvas = canvas;
    this.drawProgram = link(gl, DRAW_VERTEX_SHADER, RADIANCE_FRAGMENT_SHADER, 'static_mesh');
    this.drawUniforms = uniforms(gl, this.drawProgram, ['view_projection', 'exposure']);
    this.lights = new FrameLights(graceCathedral());
    this.exposure = 1;
    this.scene = null;
  }

  get maxTextureSize() {
    return this.gl.getParameter(this.gl.MAX_TEXTURE_SIZE);
  }

  // The light in world coordinates ([3][16] SH coefficients, sh.js).
  setLight(world) {
    this.lights = new FrameLights(world);
  }

  // Uploads one scene's bases; returns its GPU state for useScene (the page
  // keeps one per scene and content hash, so bases go up once).
  createScene(basis) {
    const gl = this.gl;
    const packed = packScene(basis, this.maxTextureSize);
    this.checkUniformBudget(packed);
    const transfer = hasTransfer(basis);
    const program = link(gl, evaluationVertexShader({ ...packed, hasTransfer: transfer }), DISCARD_FRAGMENT_SHADER,
      'low_rank', ['world_position', 'radiance']);
    const textures = {};
    for (const name of TEXTURES) textures[name] = floatTexture(gl, packed.images[name]);
    const scene = {
      basis: { scene: basis.scene, contentHash: basis.contentHash, points: basis.points },
      r_u4: packed.r_u4,
      r_a4: packed.r_a4,
      program,
      uniforms: uniforms(gl, program, ['q', 'support', 'placement', 'light', ...TEXTURES.map((t) => `${t}_tex`)]),
      textures,
      q: new Float32Array(4 * (packed.r_u4 + packed.r_a4) + 4),
      indexCount: basis.triangles.length,
      textureBytes: Object.values(packed.images).reduce((s, i) => s + i.data.byteLength, 0),
    };
    this.createBuffers(scene, basis);
    this.check('uploading the bases');
    return scene;
  }

  // q and the lights are uniforms: r_u4 + r_a4 + 1 + 24 + 4 vec4s must fit.
  checkUniformBudget({ r_u4, r_a4 }) {
    const budget = this.gl.getParameter(this.gl.MAX_VERTEX_UNIFORM_VECTORS);
    const needed = r_u4 + r_a4 + 1 + 24 + 4;
    if (needed > budget) {
      throw new RenderError(`ranks r_u4 + r_a4 = ${r_u4 + r_a4} vec4s need ${needed} uniform vectors ` +
        `(this GPU has ${budget})`);
    }
  }

  // The evaluated points (6 floats each: position, radiance), written by
  // transform feedback and read by the triangle draw through `vao`.
  createBuffers(scene, basis) {
    const gl = this.gl;
    scene.evaluated = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, scene.evaluated);
    gl.bufferData(gl.ARRAY_BUFFER, 24 * basis.points, gl.DYNAMIC_COPY);
    scene.vao = gl.createVertexArray();
    gl.bindVertexArray(scene.vao);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
    gl.enableVertexAttribArray(0);
    gl.enableVertexAttribArray(1);
    scene.indices = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, scene.indices);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, basis.triangles, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    // The per-point pass reads no attributes: an empty vertex array.
    scene.pointVao = gl.createVertexArray();
    scene.feedback = gl.createTransformFeedback();
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, scene.feedback);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, scene.evaluated);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
  }

  deleteScene(scene) {
    const gl = this.gl;
    for (const t of Object.values(scene.textures)) gl.deleteTexture(t);
    gl.deleteBuffer(scene.evaluated);
    gl.deleteBuffer(scene.indices);
    gl.deleteVertexArray(scene.vao);
    gl.deleteVertexArray(scene.pointVao);
    gl.deleteTransformFeedback(scene.feedback);
    gl.deleteProgram(scene.program);
    if (this.scene === scene) this.scene = null;
  }

  useScene(scene) {
    this.scene = scene;
  }

  check(what) {
    const error = this.gl.getError();
    if (error !== this.gl.NO_ERROR) {
      throw new RenderError(`WebGL error 0x${error.toString(16).padStart(4, '0')} while ${what}`);
    }
  }

  // Draws `frame` ({q_u, q_a, support}) seen by `camera` (camera.js) into the
  // canvas's drawing buffer; radius: scene_radius for the depth range.
  draw(frame, camera, radius) {
    this.drawMany([frame], [[0, 0, 0]], camera, radius);
  }

  // Several instances of the scene in one view: frame i drawn at offsets[i]
  // (a translation, the native default grid), each evaluated and drawn in
  // turn; readEvaluated() then holds the last one's points.
  drawMany(frames, offsets, camera, radius) {
    const scene = this.scene;
    if (!scene) throw new RenderError('draw: no scene was loaded');
    this.beginFrame();
    frames.forEach((frame, i) => {
      const placement = translation(offsets[i]);
      this.evaluatePoints(scene, frame, multiply(placement, supportMatrix(frame.support)), placement);
      this.drawTriangles(scene, camera, radius);
    });
  }

  // Pass 1: the low-rank program once per point, captured into scene.evaluated.
  evaluatePoints(scene, frame, support, placement) {
    const gl = this.gl;
    gl.useProgram(scene.program);
    const u = scene.uniforms;
    TEXTURES.forEach((name, unit) => {
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, scene.textures[name]);
      gl.uniform1i(u[`${name}_tex`], unit);
    });
    gl.uniform4fv(u.q, packReduced(frame.q_u, frame.q_a ?? [], scene.r_u4, scene.r_a4, scene.q));
    gl.uniformMatrix4fv(u.support, false, support);
    gl.uniformMatrix4fv(u.placement, false, placement);
    gl.uniform4fv(u.light, this.lights.forSupport(support));
    gl.enable(gl.RASTERIZER_DISCARD);
    gl.bindVertexArray(scene.pointVao);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, scene.feedback);
    gl.beginTransformFeedback(gl.POINTS);
    gl.drawArrays(gl.POINTS, 0, scene.basis.points);
    gl.endTransformFeedback();
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
    gl.disable(gl.RASTERIZER_DISCARD);
  }

  // Pass 2: clear, depth LESS, back faces culled (package triangles are
  // counter-clockwise seen from their normal's side; thin surfaces are two
  // layers of opposite winding, only the one facing the camera may draw).
  beginFrame() {
    const gl = this.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, gl.drawingBufferWidth, gl.drawingBufferHeight);
    gl.clearColor(...CLEAR_COLOUR);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  }

  drawTriangles(scene, camera, radius) {
    const gl = this.gl;
    const width = gl.drawingBufferWidth, height = gl.drawingBufferHeight;
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.enable(gl.CULL_FACE);
    gl.cullFace(gl.BACK);
    gl.frontFace(gl.CCW);
    gl.useProgram(this.drawProgram);
    gl.uniformMatrix4fv(this.drawUniforms.view_projection, false, viewProjection(camera, width, height, radius));
    gl.uniform1f(this.drawUniforms.exposure, this.exposure);
    gl.bindVertexArray(scene.vao);
    gl.drawElements(gl.TRIANGLES, scene.indexCount, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }

  // The last per-point pass: 6 floats per point (world position, linear
  // radiance), as phasecast-render --dump-vertices writes them; for tests.
  readEvaluated() {
    const gl = this.gl, scene = this.scene;
    if (!scene) throw new RenderError('readEvaluated: no scene was loaded');
    const out = new Float32Array(6 * scene.basis.points);
    gl.bindBuffer(gl.ARRAY_BUFFER, scene.evaluated);
    gl.getBufferSubData(gl.ARRAY_BUFFER, 0, out);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    return out;
  }

  // RGBA rows top first, for tests and debugging.
  readPixels() {
    const gl = this.gl;
    const width = gl.drawingBufferWidth, height = gl.drawingBufferHeight;
    const bottomUp = new Uint8Array(4 * width * height);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, bottomUp);
    const rows = new Uint8Array(bottomUp.length);
    for (let y = 0; y < height; ++y) rows.set(bottomUp.subarray((height - 1 - y) * 4 * width, (height - y) * 4 * width), y * 4 * width);
    return { width, height, rgba: rows };
  }
}

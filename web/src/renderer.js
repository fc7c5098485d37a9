// WebGL2 renderer of the low-rank superposition (§5.3), after
// client/render/src/low_rank_renderer.cpp: the bases go to the GPU once per scene
// (RGBA32F textures, packing.js); per frame only each instance's q_u, q_a,
// support matrix and support-frame light change (one row each of the
// instance texture). Each frame, for every instance in view at once: one
// instanced per-point pass evaluates x̄ + U_u q_u, the support transform and
// the light-dotted transfer once per scene point into a transform-feedback
// buffer; one draw then draws every instance's triangles from that buffer
// (shared points are not evaluated again). Two draw calls per frame, however
// many instances.
import { packScene, packReduced, supportMatrix, instanceTexels, packInstance } from './packing.js';
import { hasTransfer } from './basis.js';
import { FrameLights, graceCathedral, packLights } from './sh.js';
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
    this.setLight(graceCathedral());
    this.exposure = 1;
    this.scene = null;
    this.drawCalls = 0;  // draw calls of the last frame drawn
  }

  get maxTextureSize() {
    return this.gl.getParameter(this.gl.MAX_TEXTURE_SIZE);
  }

  // The light in world coordinates ([3][16] SH coefficients, sh.js).
  setLight(world) {
    this.world = world;
    this.worldPacked = packLights(world, world);
    this.lights = [];  // per instance drawn: its light in its support frame, turned only when it turns
  }

  // Uploads one scene's bases; returns its GPU state for useScene (the page
  // keeps one per scene and content hash, so bases go up once).
  createScene(basis) {
    const gl = this.gl;
    const packed = packScene(basis, this.maxTextureSize);
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
      uniforms: uniforms(gl, program, ['instances_tex', 'world_light', ...TEXTURES.map((t) => `${t}_tex`)]),
      textures,
      q: new Float32Array(4 * (packed.r_u4 + packed.r_a4) + 4),
      triangles: basis.triangles,
      indexCount: basis.triangles.length,
      instanceTexels: instanceTexels(packed.r_u4, packed.r_a4),
      capacity: 0,  // instances the buffers below hold
      textureBytes: Object.values(packed.images).reduce((s, i) => s + i.data.byteLength, 0),
    };
    this.createBuffers(scene);
    this.reserveInstances(scene, 1);
    this.check('uploading the bases');
    return scene;
  }

  // The evaluated points (6 floats each: position, radiance; instance after
  // instance), written by transform feedback and read by the triangle draw
  // through `vao`; sized by reserveInstances.
  createBuffers(scene) {
    const gl = this.gl;
    scene.evaluated = gl.createBuffer();
    scene.instances = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, scene.instances);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.bindBuffer(gl.ARRAY_BUFFER, scene.evaluated);
    scene.vao = gl.createVertexArray();
    gl.bindVertexArray(scene.vao);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
    gl.enableVertexAttribArray(0);
    gl.enableVertexAttribArray(1);
    scene.indices = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, scene.indices);
    gl.bindVertexArray(null);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    // The per-point pass reads no attributes: an empty vertex array.
    scene.pointVao = gl.createVertexArray();
    scene.feedback = gl.createTransformFeedback();
  }

  // Room for `count` instances: the instance texture's rows, the evaluated
  // points and the triangles' indices repeated with each instance's offset
  // (WebGL2 has no base vertex per instance). Grows only.
  reserveInstances(scene, count) {
    if (count <= scene.capacity) return;
    const gl = this.gl, S = scene.basis.points;
    if (count > this.maxTextureSize) {
      throw new RenderError(`${count} instances in one view need ${count} rows of the instance texture ` +
        `(this GPU allows ${this.maxTextureSize})`);
    }
    gl.bindTexture(gl.TEXTURE_2D, scene.instances);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, scene.instanceTexels, count, 0, gl.RGBA, gl.FLOAT, null);
    scene.instanceRows = new Float32Array(4 * scene.instanceTexels * count);
    gl.bindBuffer(gl.ARRAY_BUFFER, scene.evaluated);
    gl.bufferData(gl.ARRAY_BUFFER, 24 * S * count, gl.DYNAMIC_COPY);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, scene.feedback);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, scene.evaluated);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
    const triangles = scene.triangles, indices = new Uint32Array(triangles.length * count);
    for (let i = 0; i < count; ++i) {
      const at = i * triangles.length, offset = i * S;
      for (let k = 0; k < triangles.length; ++k) indices[at + k] = triangles[k] + offset;
    }
    gl.bindVertexArray(scene.vao);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    scene.capacity = count;
  }

  deleteScene(scene) {
    const gl = this.gl;
    for (const t of Object.values(scene.textures)) gl.deleteTexture(t);
    gl.deleteTexture(scene.instances);
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
  // (a translation, the native default grid), all evaluated by one instanced
  // draw and drawn by one more; readEvaluated(i) then holds instance i's points.
  drawMany(frames, offsets, camera, radius) {
    const scene = this.scene;
    if (!scene) throw new RenderError('draw: no scene was loaded');
    this.reserveInstances(scene, frames.length);
    this.drawCalls = 0;
    this.beginFrame();
    this.evaluatePoints(scene, frames, offsets);
    this.drawTriangles(scene, camera, radius, frames.length);
    scene.drawn = frames.length;
  }

  // Each instance's row of the instance texture, uploaded in one call.
  packInstances(scene, frames, offsets) {
    const rowFloats = 4 * scene.instanceTexels;
    frames.forEach((frame, i) => {
      const placement = translation(offsets[i]);
      const support = multiply(placement, supportMatrix(frame.support));
      packInstance(scene.instanceRows.subarray(i * rowFloats, (i + 1) * rowFloats), {
        q: packReduced(frame.q_u, frame.q_a ?? [], scene.r_u4, scene.r_a4, scene.q),
        support,
        placement,
        supportLight: (this.lights[i] ??= new FrameLights(this.world)).forSupport(support).subarray(48),
      }, scene.r_u4, scene.r_a4);
    });
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D, scene.instances);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, scene.instanceTexels, frames.length, gl.RGBA, gl.FLOAT,
      scene.instanceRows.subarray(0, frames.length * rowFloats));
  }

  // Pass 1: the low-rank program once per point and instance (one instanced
  // draw), captured into scene.evaluated instance after instance.
  evaluatePoints(scene, frames, offsets) {
    const gl = this.gl;
    gl.useProgram(scene.program);
    const u = scene.uniforms;
    TEXTURES.forEach((name, unit) => {
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, scene.textures[name]);
      gl.uniform1i(u[`${name}_tex`], unit);
    });
    gl.activeTexture(gl.TEXTURE0 + TEXTURES.length);
    this.packInstances(scene, frames, offsets);
    gl.uniform1i(u.instances_tex, TEXTURES.length);
    gl.uniform4fv(u.world_light, this.worldPacked.subarray(0, 48));
    gl.enable(gl.RASTERIZER_DISCARD);
    gl.bindVertexArray(scene.pointVao);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, scene.feedback);
    gl.beginTransformFeedback(gl.POINTS);
    gl.drawArraysInstanced(gl.POINTS, 0, scene.basis.points, frames.length);
    ++this.drawCalls;
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

  drawTriangles(scene, camera, radius, instances) {
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
    gl.drawElements(gl.TRIANGLES, instances * scene.indexCount, gl.UNSIGNED_INT, 0);
    ++this.drawCalls;
    gl.bindVertexArray(null);
  }

  // Instance i's points in the last per-point pass (i: its place among the
  // frames drawn): 6 floats per point (world position, linear radiance), as
  // phasecast-render --dump-vertices writes them; for tests.
  readEvaluated(i = 0) {
    const gl = this.gl, scene = this.scene;
    if (!scene) throw new RenderError('readEvaluated: no scene was loaded');
    const drawn = scene.drawn ?? 0;
    if (!(Number.isInteger(i) && i >= 0 && i < drawn)) throw new RenderError(`readEvaluated: instance ${i} was not drawn (${drawn} were)`);
    const out = new Float32Array(6 * scene.basis.points);
    gl.bindBuffer(gl.ARRAY_BUFFER, scene.evaluated);
    gl.getBufferSubData(gl.ARRAY_BUFFER, i * out.byteLength, out);
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

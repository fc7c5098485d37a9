// The page: follows one instance of a phasecast-server through
// phasecast-gateway, as phasecast-render does natively, or every instance of
// a scene in one view (instance=all, or "all instances" in the picker). Bases are downloaded
// once per scene (and again only when the package's content hash changed),
// frames carry only q_u, q_a and the support transform.
import descriptor from './generated/phasecast.json';
import { Protocol, asHex, asNumber, utf8 } from './protocol.js';
import { GatewayConnection } from './gateway.js';
import { downloadBasis, ContentHashChanged } from './basis.js';
import { Renderer } from './renderer.js';
import { OrbitCamera, gridOffsets, groupCamera, sceneCamera, sceneRadius } from './camera.js';
import { FrameFollower, RateMeter, frameProblem } from './frames.js';
import { parseParams } from './params.js';
import { Ui } from './ui.js';
import { sceneLight } from './sh.js';

const POLL_MS = 250;  // list_instances about 4 times a second: palette rules change with the IRFs

// Test hooks (README.md), kept up to date.
const hooks = (window.phasecast = {
  ready: false,
  firstFrameMs: null,
  framesRendered: 0,
  frozenFrame: null,
  instance: null,
  instances: [],      // with every instance in view: their ids, in grid order
  missedFrames: 0,
  bytesReceived: 0,
  lastError: null,
  palette: [],
  lastImpulseReply: null,
  basisDownloads: 0,  // scenes whose bases were downloaded (again after a hash change)
  frame: null,        // {frame, seq, palette_index, irf} of the frame drawn last
  light: null,        // {probe, exposure} the followed scene is drawn with
});

class App {
  constructor(params) {
    this.params = params;
    this.ui = new Ui({
      onPickInstance: (id) => this.pick(id),
      onPickTarget: () => this.updatePalette(),
      onImpulse: (name) => this.impulse(name),
    });
    this.renderer = new Renderer(this.ui.canvas);
    this.follower = new FrameFollower(params.freeze);
    this.fps = new RateMeter();
    this.bandwidth = new RateMeter();
    this.scenes = [];          // SceneInfo of list_scenes
    this.instances = [];       // InstanceInfo of list_instances
    this.gpuScenes = new Map(); // scene name -> {contentHash, gpu, camera, radius}
    this.followed = null;      // {instance, ids, offsets, radius, scene: name, entry, info: SceneInfo}
    this.latestOf = new Map(); // instance -> its last frame, with several in view
    this.wanted = null;        // instance picked in #instance
    this.subscribed = false;   // on this connection
    this.following = Promise.resolve();  // follow() calls run one after another
    this.orbit = null;
    this.drawn = { frame: null, cameraVersion: -1 };
    this.frozen = false;
    this.gateway = new GatewayConnection(params.ws, new Protocol(descriptor), {
      onHello: () => this.session(),
      onFrame: (frame) => this.onFrame(frame),
      onGatewayError: (text) => this.error(text),
      onDown: (reason, delay) => this.error(`${reason}; reconnecting in ${(delay / 1000).toFixed(1)} s`),
      onBytes: (n) => {
        hooks.bytesReceived += n;
        this.bandwidth.add(performance.now(), n);
      },
    });
  }

  start() {
    this.ui.sizeCanvas(this.params.size);
    this.ui.setStatus(`connecting to ${this.params.ws}`);
    this.gateway.connect();
    setInterval(() => this.poll(), POLL_MS);
    setInterval(() => this.showHud(), 500);
    requestAnimationFrame(() => this.animate());
  }

  error(text) {
    hooks.lastError = text;
    this.ui.setError(text);
  }

  // After every hello (first connection and each reconnect): scenes, then
  // the instance to follow, its bases (again only if the hash changed), the
  // subscription (a new connection starts with none).
  async session() {
    this.subscribed = false;
    this.inSession = true;
    this.ui.setError(null);
    this.ui.setStatus(`connected to ${this.params.ws}`);
    try {
      await this.listScenes();
      await this.listInstances();
      await this.follow(this.wantedInstance());
    } catch (e) {
      this.error(e.message);
    } finally {
      this.inSession = false;
    }
  }

  // The user's pick, else instance=N, else the first instance of the first scene.
  wantedInstance() {
    return this.wanted ?? this.params.instance ?? this.defaultInstance();
  }

  async listScenes() {
    this.scenes = (await this.gateway.call({ list_scenes: {} })).scenes.scenes;
  }

  async listInstances() {
    this.instances = (await this.gateway.call({ list_instances: {} })).instances.instances;
    this.ui.setInstances(this.instances, this.followed ? (this.followed.all ? 'all' : this.followed.instance) : null,
      this.allScene());
    this.updatePalette();
  }

  // The first scene, in list_scenes order, that has an instance: what "all" shows.
  allScene() {
    return this.scenes.find((s) => this.instances.some((i) => i.scene === s.name))?.name ?? null;
  }

  // Every instance of allScene(), in id order (the grid's order).
  allInstances() {
    const scene = this.allScene();
    if (!scene) throw new Error('the server has no instance of any scene');
    return this.instances.filter((i) => i.scene === scene).map((i) => i.instance).sort((a, b) => a - b);
  }

  // The first instance of the first scene, as phasecast-render.
  defaultInstance() {
    if (this.scenes.length === 0) throw new Error('the server has no scenes');
    const scene = this.scenes[0].name;
    const info = this.instances.find((i) => i.scene === scene);
    if (!info) throw new Error(`the server has no instance of scene '${scene}'`);
    return info.instance;
  }

  // Follows instance `id`; calls queue behind each other, so a poll, a pick
  // and a reconnect never download the same bases twice at once.
  follow(id) {
    const next = this.following.then(() => this.followNow(id));
    this.following = next.catch(() => {});
    return next;
  }

  async followNow(wanted) {
    const ids = wanted === 'all' ? this.allInstances() : [wanted];
    const id = ids[0];
    const info = this.instances.find((i) => i.instance === id);
    if (!info) {
      throw new Error(`instance=${id}: the server has no such instance (it has ` +
        `${this.instances.map((i) => i.instance).join(', ') || 'none'})`);
    }
    const scene = this.scenes.find((s) => s.name === info.scene);
    if (!scene) throw new Error(`instance ${id} plays scene '${info.scene}', which list_scenes does not list`);
    const entry = await this.sceneOnGpu(scene);
    const offsets = gridOffsets(entry.radius, ids.length);
    const view = ids.length > 1 ? groupCamera(entry.camera, entry.radius, offsets) : { camera: entry.camera, radius: entry.radius };
    const same = this.followed?.scene === scene.name && this.followed.ids.join() === ids.join();
    if (!same) this.orbit = new OrbitCamera(view.camera);
    this.followed = { instance: id, ids, offsets, radius: view.radius, all: wanted === 'all', scene: scene.name, entry, info: scene };
    this.latestOf.clear();
    this.renderer.useScene(entry.gpu);
    this.renderer.setLight(entry.lit.light);
    this.renderer.exposure = entry.lit.exposure;
    hooks.light = { probe: entry.lit.probe, exposure: entry.lit.exposure };
    if (entry.lit.problem) this.error(entry.lit.problem);
    this.follower.follow(id);
    hooks.instance = id;
    hooks.instances = ids.length > 1 ? ids : [];
    this.ui.setInstances(this.instances, wanted, this.allScene());
    this.ui.setTargets(ids.length > 1 ? ids : []);
    this.updatePalette();
    this.subscribed = this.gateway.subscribe(ids);
    this.ui.setStatus(ids.length > 1 ? `following ${ids.length} instances of '${scene.name}' in one view`
      : `following instance ${id} of '${scene.name}'`);
  }

  // The scene's bases on the GPU: downloaded once per scene and content hash.
  async sceneOnGpu(scene, attempts = 3) {
    const hash = asHex(scene.content_hash);
    const cached = this.gpuScenes.get(scene.name);
    if (cached && cached.contentHash === hash) return cached;
    try {
      const started = performance.now();
      const basis = await downloadBasis((body) => this.gateway.call(body), scene, {
        onProgress: (done, total) => {
          this.ui.setProgress(done, total);
          this.ui.setStatus(`downloading the bases of '${scene.name}': ${(done / 1024).toFixed(0)} of ${(total / 1024).toFixed(0)} KiB`);
        },
      });
      ++hooks.basisDownloads;
      if (cached) this.renderer.deleteScene(cached.gpu);
      const entry = {
        contentHash: hash,
        gpu: this.renderer.createScene(basis),
        // The page keeps only what it needs on the CPU once the GPU has the bases.
        camera: sceneCamera(basis),
        radius: sceneRadius(basis.mean_shape),
        lit: sceneLight(scene),
        downloadMs: performance.now() - started,
      };
      this.gpuScenes.set(scene.name, entry);
      return entry;
    } catch (e) {
      // The server reloaded the package mid-download: list again, start over.
      if (!(e instanceof ContentHashChanged) || attempts <= 1) throw e;
      await this.listScenes();
      const again = this.scenes.find((s) => s.name === scene.name);
      if (!again) throw new Error(`scene '${scene.name}' is no longer listed by the server`);
      return this.sceneOnGpu(again, attempts - 1);
    }
  }

  async pick(id) {
    if (id === (this.followed?.all ? 'all' : this.followed?.instance)) return;
    this.wanted = id;
    try {
      this.ui.setError(null);
      await this.follow(id);
    } catch (e) {
      this.error(e.message);
    }
  }

  async poll() {
    if (!this.gateway.connected || this.polling || this.inSession) return;
    this.polling = true;
    try {
      await this.listInstances();
      // The instance was not there yet (or the session failed), or the
      // instances of the scene in view came or went: follow again.
      const moved = this.followed?.all && this.allInstances().join() !== this.followed.ids.join();
      if (!this.subscribed || moved) {
        await this.follow(this.wantedInstance());
        this.ui.setError(null);
      }
    } catch (e) {
      this.error(e.message);
    } finally {
      this.polling = false;
    }
  }

  // One button per palette entry, enabled when the rules allow it next (allowed_now).
  updatePalette() {
    if (!this.followed) return;
    const target = this.followed.ids.length > 1 ? this.ui.targetValue() : 'all';
    const shown = target === 'all' ? this.followed.instance : target;
    const info = this.instances.find((i) => i.instance === shown);
    const allowed = new Set(info ? info.allowed_now : []);
    hooks.palette = this.followed.info.palette.map((p) => ({ name: p.name, index: p.index, enabled: allowed.has(p.index) }));
    this.ui.setPalette(hooks.palette);
  }

  // The palette drives the instance followed, or with several in view the
  // picked target: one of them, or all of them (one request each).
  async impulse(name) {
    const f = this.followed;
    if (!f) return;
    const target = f.ids.length > 1 ? this.ui.targetValue() : f.instance;
    const targets = target === 'all' ? f.ids : [target];
    for (const instance of targets) await this.impulseTo(instance, name, targets.length);
    this.poll();
  }

  async impulseTo(instance, name, of) {
    try {
      const reply = await this.gateway.request({ impulse: { instance, name: utf8(name) } });
      const accepted = reply.ok ? reply.impulse : null;
      hooks.lastImpulseReply = {
        ok: reply.ok,
        error: reply.error,
        name,
        instance,
        palette_index: accepted ? accepted.palette_index : null,
        at_frame: accepted ? asNumber(accepted.at_frame) : null,
      };
      const which = of > 1 ? ` (one of ${of})` : '';
      this.ui.setStatus(reply.ok
        ? `impulse '${name}' accepted for instance ${instance}${which}, frame ${asNumber(accepted.at_frame)}`
        : `impulse '${name}' refused for instance ${instance}: ${reply.error}`);
    } catch (e) {
      hooks.lastImpulseReply = { ok: false, error: e.message, name, instance, palette_index: null, at_frame: null };
      this.ui.setStatus(`impulse '${name}' failed: ${e.message}`);
    }
  }

  onFrame(frame) {
    const f = this.followed;
    if (!f || !f.ids.includes(frame.instance)) return;
    const problem = frameProblem(frame, f.info);
    if (problem) {
      this.error(`instance ${frame.instance}: ${problem}; frame not drawn`);
      this.recheck('a frame does not fit the bases');
      return;
    }
    this.latestOf.set(frame.instance, frame);
    if (frame.instance !== f.instance) return;  // sequence, freeze and restarts: the first one's
    const restarts = this.follower.restarts;
    this.follower.accept(frame);
    hooks.missedFrames = this.follower.missed;
    // The server started again behind the gateway: its package may have
    // changed, so check the scenes' content hashes as after a reconnect.
    if (this.follower.restarts > restarts) this.recheck('the stream started again');
  }

  // A new session on the same connection (re-lists scenes, downloads bases
  // whose hash changed, subscribes again); at most once per 2 s.
  recheck(why) {
    const now = performance.now();
    if (this.inSession || now - (this.lastRecheck ?? -Infinity) < 2000) return;
    this.lastRecheck = now;
    this.ui.setStatus(`${why}: checking the scene's bases`);
    this.session();
  }

  animate() {
    if (this.frozen) return;  // freeze=F: the canvas keeps exactly that frame
    requestAnimationFrame(() => this.animate());
    const resized = this.ui.sizeCanvas(this.params.size);
    const frame = this.follower.latest;
    if (!frame || !this.followed) return;
    const camera = this.orbit;
    if (!resized && frame === this.drawn.frame && camera.version === this.drawn.cameraVersion) return;
    const f = this.followed;
    const frames = f.ids.length > 1 ? f.ids.map((id) => (id === f.instance ? frame : this.latestOf.get(id))) : [frame];
    if (frames.some((x) => !x)) return;  // each instance in view draws from its first frame on
    try {
      this.renderer.drawMany(frames, f.offsets, camera.camera(), f.radius);
    } catch (e) {
      this.error(e.message);
      return;
    }
    this.drawn = { frame, cameraVersion: camera.version };
    this.afterDraw(frame);
  }

  afterDraw(frame) {
    const now = performance.now();
    this.fps.add(now);
    ++hooks.framesRendered;
    hooks.drawCalls = this.renderer.drawCalls;
    hooks.frame = { frame: asNumber(frame.frame), seq: asNumber(frame.seq), palette_index: frame.palette_index, irf: frame.irf };
    if (hooks.firstFrameMs === null) {
      hooks.firstFrameMs = now;  // performance.now() counts from the page's navigation
      hooks.ready = true;
    }
    if (this.follower.pinned) {
      this.frozen = true;
      hooks.frozenFrame = asNumber(frame.frame);
    }
  }

  showHud() {
    const now = performance.now();
    const frame = this.follower.latest;
    const f = this.followed;
    this.ui.setHud([
      `${this.fps.rate(now).toFixed(1)} frames/s rendered`,
      `${(this.bandwidth.rate(now) / 1024).toFixed(1)} KiB/s received`,
      `${this.follower.missed} frames missed (seq gaps)`,
      `first frame ${hooks.firstFrameMs === null ? '-' : `${hooks.firstFrameMs.toFixed(0)} ms`} after page load`,
      f ? `${f.ids.length > 1 ? `${f.ids.length} instances from ` : ''}instance ${f.instance} '${f.scene}', ` +
        `frame ${frame ? asNumber(frame.frame) : '-'}` +
        `${this.frozen ? ' (frozen)' : ''}` : 'no instance yet',
      f ? `bases ${(f.entry.gpu.textureBytes / 1048576).toFixed(2)} MiB on the GPU, downloaded in ${f.entry.downloadMs.toFixed(0)} ms` : '',
    ]);
  }
}

function main() {
  let params;
  try {
    params = parseParams(location.search, location.host, location.protocol === 'https:');
    const app = new App(params);
    // Tests send bytes the gateway cannot read on this page's own connection.
    hooks.sendRaw = (bytes) => app.gateway.socket?.send(new Uint8Array(bytes));
    // As freeze=F, set once the page runs (a test picks F from an impulse's at_frame).
    hooks.freezeAt = (frame) => app.follower.freeze(frame);
    // Positions and radiance of the frame drawn last, read back from the GPU.
    hooks.evaluated = () => Array.from(app.renderer.readEvaluated());
    app.start();
  } catch (e) {
    hooks.lastError = e.message;
    const error = document.getElementById('error');
    error.textContent = e.message;
    error.hidden = false;
  }
}

main();

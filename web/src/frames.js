// The frames of the followed instance: the latest one to draw, dropped
// frames from Frame.seq gaps, and the freeze=F test mode. Pure (no DOM).
import { asNumber } from './protocol.js';

// About 9 s of frames at 35 ms: longer than any reply a loaded machine keeps a test waiting.
const kRecentFrames = 256;

export class FrameFollower {
  constructor(freezeAt = null) {
    this.freezeAt = freezeAt;  // null: follow forever
    this.instance = null;
    this.latest = null;
    this.lastSeq = null;
    this.missed = 0;           // frames lost to seq gaps, over the page's life
    this.restarts = 0;         // seq went back: the server started again
    this.pinned = false;       // the freeze frame has arrived; later frames are ignored
    this.recent = [];          // the last kRecentFrames accepted, for freeze() on a frame already past
  }

  // freeze=F set while the page runs: pins the first frame at or past F. If
  // that frame has already arrived (F was set late, as a test does after an
  // impulse's reply), it is taken from the recent frames, so the frame pinned
  // does not depend on how long the reply took.
  freeze(at) {
    this.freezeAt = at;
    const past = this.recent.find((f) => asNumber(f.frame) >= at);
    if (past === undefined) return false;
    this.latest = past;
    this.pinned = true;
    return true;
  }

  // Follow another instance (or the same one after a reconnect: seq goes on).
  follow(instance) {
    if (instance !== this.instance) {
      this.lastSeq = null;
      this.latest = null;
      this.recent = [];
    }
    this.instance = instance;
  }

  // A frame from the gateway; returns true when it becomes the one to draw.
  accept(frame) {
    if (frame.instance !== this.instance || this.pinned) return false;
    const seq = asNumber(frame.seq);
    if (this.lastSeq !== null) {
      if (seq > this.lastSeq + 1) this.missed += seq - this.lastSeq - 1;
      else if (seq <= this.lastSeq) ++this.restarts;
    }
    this.lastSeq = seq;
    this.latest = frame;
    this.recent.push(frame);
    if (this.recent.length > kRecentFrames) this.recent.shift();
    // freeze=F: the first frame at or past F is shown and kept, whatever
    // arrives after it before the next animation frame.
    if (this.freezeAt !== null && asNumber(frame.frame) >= this.freezeAt) this.pinned = true;
    return true;
  }
}

// Events per second over the last `windowMs` (frames drawn, bytes received).
export class RateMeter {
  constructor(windowMs = 1000) {
    this.windowMs = windowMs;
    this.events = [];  // [time, amount]
  }

  add(now, amount = 1) {
    this.events.push([now, amount]);
    this.trim(now);
  }

  trim(now) {
    while (this.events.length > 0 && this.events[0][0] <= now - this.windowMs) this.events.shift();
  }

  rate(now) {
    this.trim(now);
    const sum = this.events.reduce((s, [, a]) => s + a, 0);
    return (sum * 1000) / this.windowMs;
  }
}

// Why a frame cannot be drawn with the bases of `scene` (SceneInfo), or
// null; the checks of validate_frame in client/scene/src/frame_state.cpp.
export function frameProblem(frame, scene) {
  const where = `frame ${asNumber(frame.frame)}`;
  if (frame.q_u.length !== scene.rank_u) return `${where}: q_u has ${frame.q_u.length} values (expected r_u = ${scene.rank_u})`;
  if (frame.q_a.length !== scene.rank_a) return `${where}: q_a has ${frame.q_a.length} values (expected r_a = ${scene.rank_a})`;
  if (frame.support.length !== 0 && frame.support.length !== 12) {
    return `${where}: support has ${frame.support.length} values (expected 12, a 3x4 row-major transform)`;
  }
  for (const name of ['q_u', 'q_a', 'support']) {
    const i = frame[name].findIndex((v) => !Number.isFinite(v));
    if (i >= 0) return `${where}: ${name}[${i}] is ${frame[name][i]} (expected a finite number)`;
  }
  return null;
}

// Page logic without a browser: following frames (seq gaps, freeze=F),
// frame checks, rates, URL parameters, reconnect backoff.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { FrameFollower, RateMeter, frameProblem } from '../src/frames.js';
import { parseParams, parseSize } from '../src/params.js';
import { backoffDelay } from '../src/gateway.js';

const frame = (seq, extra = {}) => ({ instance: 2, seq, frame: seq + 100, q_u: [0, 0], q_a: [], support: [], ...extra });

test('seq gaps count the frames missed; only the followed instance counts', () => {
  const f = new FrameFollower();
  f.follow(2);
  assert.ok(f.accept(frame(5)));
  assert.ok(f.accept(frame(6)));
  assert.ok(f.accept(frame(9)));   // 7 and 8 lost
  assert.ok(!f.accept({ ...frame(20), instance: 3 }));
  assert.ok(f.accept(frame(12)));  // 10, 11 lost
  assert.equal(f.missed, 4);
  assert.equal(f.latest.seq, 12);
  f.accept(frame(0));              // the server started again: not a gap
  assert.equal(f.missed, 4);
  assert.equal(f.restarts, 1);
  f.follow(3);                     // another instance: its seq starts afresh
  assert.equal(f.latest, null);
  f.accept({ ...frame(50), instance: 3 });
  assert.equal(f.missed, 4);
});

test('freeze=F keeps the first frame at or past F, whatever comes after it', () => {
  const f = new FrameFollower(103);
  f.follow(2);
  f.accept(frame(1));               // frame 101
  assert.equal(f.pinned, false);
  f.accept(frame(4));               // frame 104 >= 103: pinned
  assert.equal(f.pinned, true);
  assert.equal(f.accept(frame(5)), false);
  assert.equal(f.latest.frame, 104);
});

test('freeze(F) set after F has passed pins frame F itself, not whatever comes next', () => {
  const f = new FrameFollower();
  f.follow(2);
  for (let seq = 1; seq <= 40; ++seq) f.accept(frame(seq));  // frames 101..140
  assert.equal(f.freeze(130), true);
  assert.equal(f.pinned, true);
  assert.equal(f.latest.frame, 130);
  assert.equal(f.accept(frame(41)), false);
  assert.equal(f.latest.frame, 130);
});

test('freeze(F) ahead of the stream waits for F; the recent frames are bounded', () => {
  const f = new FrameFollower();
  f.follow(2);
  for (let seq = 1; seq <= 300; ++seq) f.accept(frame(seq));
  assert.equal(f.recent.length, 256);
  assert.equal(f.freeze(110), true);     // long gone: the oldest kept frame at or past it
  assert.equal(f.latest.frame, 145);
  const g = new FrameFollower();
  g.follow(2);
  g.accept(frame(1));
  assert.equal(g.freeze(105), false);
  assert.equal(g.pinned, false);
  g.accept(frame(6));                    // frame 106 >= 105
  assert.equal(g.pinned, true);
  assert.equal(g.latest.frame, 106);
});

test('frames that do not fit the scene are named, as validate_frame', () => {
  const scene = { rank_u: 2, rank_a: 0 };
  assert.equal(frameProblem(frame(1), scene), null);
  assert.equal(frameProblem(frame(1, { q_u: [1] }), scene), 'frame 101: q_u has 1 values (expected r_u = 2)');
  assert.equal(frameProblem(frame(1, { q_a: [1] }), scene), 'frame 101: q_a has 1 values (expected r_a = 0)');
  assert.match(frameProblem(frame(1, { support: [1, 2, 3] }), scene), /support has 3 values \(expected 12/);
  assert.equal(frameProblem(frame(1, { q_u: [0, NaN] }), scene), 'frame 101: q_u[1] is NaN (expected a finite number)');
});

test('rates over the last second', () => {
  const r = new RateMeter(1000);
  for (let t = 0; t < 2000; t += 10) r.add(t, 5);
  assert.equal(r.rate(1999), 500);
  assert.equal(r.rate(5000), 0);
});

test('URL parameters', () => {
  assert.deepEqual(parseParams('', 'host:8080'), { instance: null, size: null, freeze: null, ws: 'ws://host:8080/ws' });
  assert.deepEqual(parseParams('?instance=3&size=640x480&freeze=120&ws=ws://x:1/ws', 'h'),
    { instance: 3, size: [640, 480], freeze: 120, ws: 'ws://x:1/ws' });
  assert.equal(parseParams('', 'h', true).ws, 'wss://h/ws');
  assert.throws(() => parseParams('?instance=-1', 'h'), /instance='-1' is invalid \(expected a whole number >= 0/);
  assert.throws(() => parseParams('?freeze=soon', 'h'), /freeze='soon' is invalid/);
  assert.throws(() => parseSize('640*480'), /size='640\*480' is invalid \(expected WIDTHxHEIGHT/);
  assert.throws(() => parseSize('0x480'), /invalid/);
  assert.deepEqual(parseSize('1X2'), [1, 2]);
});

test('reconnect backoff doubles from 0.5 s up to 8 s', () => {
  assert.deepEqual([0, 1, 2, 3, 4, 5, 9].map(backoffDelay), [500, 1000, 2000, 4000, 8000, 8000, 8000]);
});

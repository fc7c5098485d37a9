// The page's request layer and PageMessage encoding (no samples needed).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { loadDescriptor } from '../tools/descriptor.mjs';
import { Protocol, RequestChannel, RequestTimeout, asHex, asNumber, utf8 } from '../src/protocol.js';

const protocol = new Protocol(loadDescriptor());
const Request = protocol.PageMessage.fields.request.resolve().resolvedType;

test('PageMessage encoding: a request keeps its id and body, names as UTF-8 bytes', () => {
  const bytes = protocol.encodeMessage({ request: { id: 42, impulse: { instance: 3, name: utf8('öffnen') } } });
  const back = protocol.PageMessage.decode(bytes);
  assert.equal(back.body, 'request');
  assert.equal(asNumber(back.request.id), 42);
  assert.equal(back.request.body, 'impulse');
  assert.equal(new TextDecoder().decode(back.request.impulse.name), 'öffnen');
  assert.equal(back.request.impulse.entry, 'name');
  assert.equal(Request.name, 'Request');
});

test('PageMessage encoding: subscribe and an empty body (list_scenes) are on the wire', () => {
  const sub = protocol.PageMessage.decode(protocol.encodeMessage({ subscribe: { instances: [1, 7] } }));
  assert.deepEqual(sub.subscribe.instances, [1, 7]);
  const list = protocol.PageMessage.decode(protocol.encodeMessage({ request: { id: 1, list_scenes: {} } }));
  assert.equal(list.request.body, 'list_scenes');
});

test('64-bit values decode exactly (content hashes above 2^53)', () => {
  const Event = protocol.PageEvent;
  const bytes = Event.encode(Event.fromObject({ reply: { id: 1, ok: true, basis: { content_hash: '12196828402476178145' } } })).finish();
  const event = protocol.decodeEvent(bytes);
  assert.equal(asHex(event.reply.basis.content_hash), 'a943d6cf7bfcdae1');
});

// A channel whose sent messages are kept for the test to answer.
function channel(options = {}) {
  const sent = [];
  const ch = new RequestChannel({ send: (m) => (sent.push(m), true), maxInFlight: 2, timeoutMs: 1000, ...options });
  return { ch, sent, answer: (i, reply = {}) => ch.deliver({ id: sent[i].request.id, ok: true, ...reply }) };
}

test('requests get increasing ids and their own replies, in any order', async () => {
  const { ch, sent, answer } = channel();
  const a = ch.request({ list_scenes: {} }), b = ch.request({ list_instances: {} });
  assert.deepEqual(sent.map((m) => m.request.id), [1, 2]);
  answer(1, { error: 'second' });
  answer(0, { error: 'first' });
  assert.equal((await a).error, 'first');
  assert.equal((await b).error, 'second');
});

test('at most max_requests_in_flight unanswered: the rest wait in the page', async () => {
  const { ch, sent, answer } = channel();
  const replies = [0, 1, 2, 3].map(() => ch.request({ stats: {} }));
  assert.equal(sent.length, 2);
  answer(0);
  assert.equal(sent.length, 3);
  answer(1);
  answer(2);
  assert.equal(sent.length, 4);
  answer(3);
  await Promise.all(replies);
  ch.setMaxInFlight(5);
  assert.equal(ch.maxInFlight, 5);
});

test('call() turns a refusal into an error carrying the server line and the reply', async () => {
  const { ch, sent } = channel();
  const p = ch.call({ impulse: { instance: 0, index: 9 } });
  ch.deliver({ id: sent[0].request.id, ok: false, error: "impulse: instance 0 (plate): unknown palette entry 9" });
  await assert.rejects(p, (e) => e.message.startsWith('impulse: instance 0') && e.reply.ok === false);
});

test('a request without a reply times out with a clear error; its slot waits for the late reply', async () => {
  const { ch, sent } = channel({ timeoutMs: 20, maxInFlight: 1 });
  const p = ch.request({ list_scenes: {} });
  await assert.rejects(p, (e) => e instanceof RequestTimeout &&
    /list_scenes: no reply from the gateway within 20 ms \(sent; is phasecast-gateway connected/.test(e.message));
  const q = ch.request({ list_instances: {} });
  assert.equal(sent.length, 1, 'the timed-out request still counts as unanswered');
  ch.deliver({ id: sent[0].request.id, ok: true });  // the late reply frees the slot
  assert.equal(sent.length, 2);
  ch.deliver({ id: sent[1].request.id, ok: true });
  assert.equal((await q).ok, true);
});

test('a queued request times out too, saying it was still queued', async () => {
  const { ch } = channel({ timeoutMs: 20, maxInFlight: 1 });
  ch.request({ list_scenes: {} }).catch(() => {});
  await assert.rejects(ch.request({ stats: {} }), /stats: no reply .* \(still queued behind 1 unanswered requests/);
});

test('a lost connection fails every request at once and frees the slots', async () => {
  const { ch } = channel();
  const all = [0, 1, 2].map(() => ch.request({ stats: {} }));
  ch.failAll('the connection to the gateway was lost');
  for (const p of all) await assert.rejects(p, /stats: the connection to the gateway was lost/);
  assert.equal(ch.waiting, 0);
});

test('requests while not connected fail at once', async () => {
  const ch = new RequestChannel({ send: () => false, maxInFlight: 4, timeoutMs: 1000 });
  await assert.rejects(ch.request({ list_scenes: {} }), /list_scenes: not connected to the gateway/);
  assert.equal(ch.waiting, 0);
});

test('replies nobody waits for are ignored', () => {
  const { ch } = channel();
  assert.equal(ch.deliver({ id: 99, ok: true }), false);
});

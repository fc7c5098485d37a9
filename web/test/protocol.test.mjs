// Decoding PageEvents written by the C++ encoder.
//
// Contract with the sample writer (ctest sets PHASECAST_PROTO_SAMPLES):
// the directory $PHASECAST_PROTO_SAMPLES holds
//   hello.bin        a serialized PageEvent with body hello (GatewayHello)
//   frame.bin        a serialized PageEvent with body frame (Frame)
//   basis_reply.bin  a serialized PageEvent with body reply (Reply with a BasisChunk)
//   samples.json     {"hello": E, "frame": E, "basis_reply": E}, one entry per .bin
// where E is the expected PageEvent: {"hello": {...}} / {"frame": {...}} /
// {"reply": {...}} (or just the body's fields). Field names as in
// proto/phasecast.proto (snake_case; lowerCamelCase also accepted). Only the
// fields listed are checked. Values: numbers as JSON numbers; 64-bit integers
// as numbers or decimal strings (strings are exact); float fields are compared
// after rounding the JSON number to float32 (print 9 significant digits or the
// shortest float round-trip), doubles to 1e-12 relative; bytes as base64;
// enums as number or name; repeated fields as arrays (compared whole).
// tools/make_samples.py writes such a directory from Python.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, existsSync } from 'node:fs';
import path from 'node:path';
import { loadDescriptor } from '../tools/descriptor.mjs';
import { Protocol, asHex } from '../src/protocol.js';

const protocol = new Protocol(loadDescriptor());
const SAMPLES = process.env.PHASECAST_PROTO_SAMPLES;

const snake = (name) => name.replace(/[A-Z]/g, (c) => `_${c.toLowerCase()}`);
const INT64 = new Set(['int64', 'uint64', 'sint64', 'fixed64', 'sfixed64']);

// Compares one decoded field value with its JSON expectation.
function checkValue(field, actual, expected, where) {
  field.resolve();
  if (field.resolvedType && field.resolvedType.values) {  // enum
    const number = typeof expected === 'string' ? field.resolvedType.values[expected] : expected;
    assert.equal(actual, number, `${where}: enum ${actual} (expected ${expected})`);
  } else if (field.resolvedType) {                          // message
    checkMessage(field.resolvedType, actual, expected, where);
  } else if (INT64.has(field.type)) {
    if (typeof expected === 'string' || Number.isSafeInteger(expected)) {
      assert.equal(BigInt(actual.toString()), BigInt(expected), `${where}: ${actual} (expected ${expected})`);
    } else {
      assert.equal(Number(actual.toString()), expected, `${where}: ${actual} (expected ${expected}; write 64-bit values as strings to compare exactly)`);
    }
  } else if (field.type === 'float') {
    assert.equal(actual, Math.fround(expected), `${where}: ${actual} (expected float32 of ${expected})`);
  } else if (field.type === 'double') {
    assert.ok(Math.abs(actual - expected) <= 1e-12 * Math.max(1, Math.abs(expected)), `${where}: ${actual} (expected ${expected})`);
  } else if (field.type === 'bytes') {
    assert.equal(Buffer.from(actual).toString('base64'), expected, `${where}: bytes differ`);
  } else {
    assert.equal(actual, expected, `${where}: ${actual} (expected ${expected})`);
  }
}

function checkMessage(type, message, expected, where) {
  assert.ok(message, `${where}: missing (expected ${JSON.stringify(expected).slice(0, 80)})`);
  for (const [key, value] of Object.entries(expected)) {
    const name = snake(key);
    const field = type.fields[name];
    assert.ok(field, `${where}.${key}: ${type.name} has no such field`);
    const actual = message[name];
    if (field.repeated) {
      assert.equal(actual.length, value.length, `${where}.${name}: ${actual.length} values (expected ${value.length})`);
      value.forEach((v, i) => checkValue(field, actual[i], v, `${where}.${name}[${i}]`));
    } else {
      checkValue(field, actual, value, `${where}.${name}`);
    }
  }
}

function loadSamples() {
  assert.ok(SAMPLES, 'PHASECAST_PROTO_SAMPLES is not set: set it to a directory of PageEvent samples from the C++ ' +
    'encoder (hello.bin, frame.bin, basis_reply.bin, samples.json; ctest sets it, or run ' +
    'web/tools/make_samples.py for a Python-made set)');
  const file = path.join(SAMPLES, 'samples.json');
  assert.ok(existsSync(file), `PHASECAST_PROTO_SAMPLES=${SAMPLES} has no samples.json`);
  return JSON.parse(readFileSync(file, 'utf8'));
}

// The event decoded from NAME.bin, checked against samples.json[NAME].
function checkSample(name, body) {
  const samples = loadSamples();
  assert.ok(samples[name], `samples.json has no entry '${name}'`);
  const event = protocol.decodeEvent(readFileSync(path.join(SAMPLES, `${name}.bin`)));
  assert.equal(event.body, body, `${name}.bin: the PageEvent carries '${event.body}' (expected '${body}')`);
  let expected = samples[name];
  const keys = Object.keys(expected);
  if (keys.length === 1 && keys[0] === body && typeof expected[body] === 'object' && !Array.isArray(expected[body])) {
    expected = expected[body];
  }
  const type = protocol.PageEvent.fields[body].resolve().resolvedType;
  checkMessage(type, event[body], expected, `${name}.${body}`);
  return event;
}

test('decodes the C++ hello sample', () => {
  const event = checkSample('hello', 'hello');
  assert.ok(event.hello.max_requests_in_flight >= 1, 'max_requests_in_flight must allow at least one request');
});

test('decodes the C++ frame sample', () => {
  const event = checkSample('frame', 'frame');
  assert.ok(Array.isArray(event.frame.q_u));
});

test('decodes the C++ basis reply sample (chunk bytes and the 64-bit content hash exact)', () => {
  const event = checkSample('basis_reply', 'reply');
  const chunk = event.reply.basis;
  assert.ok(chunk, 'the reply carries a BasisChunk');
  assert.ok(chunk.data instanceof Uint8Array);
  assert.match(asHex(chunk.content_hash), /^[0-9a-f]{16}$/);
});

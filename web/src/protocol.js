// The page's side of the gateway protocol (proto/phasecast.proto, "Browser
// pages"): PageMessage out, PageEvent in, each one binary WebSocket message;
// and the request/reply layer: ids, at most hello.max_requests_in_flight
// unanswered requests (the rest wait in the page), timeouts.
import protobuf from 'protobufjs/light.js';

// 64-bit fields (content_hash, seq, frame, ids) decode to Long so hashes stay
// exact; protobufjs bundles long.js itself. Without it hashes would be
// rounded to doubles and two different packages could compare equal.
if (!protobuf.util.Long) throw new Error('protobufjs was built without long.js (64-bit fields would be rounded)');

export class Protocol {
  constructor(descriptor) {
    const root = protobuf.Root.fromJSON(descriptor);
    this.PageMessage = root.lookupType('phasecast.v1.PageMessage');
    this.PageEvent = root.lookupType('phasecast.v1.PageEvent');
    this.BasisPart = root.lookupEnum('phasecast.v1.BasisPart');
  }

  // obj: a plain PageMessage, e.g. {subscribe: {instances: [3]}}.
  encodeMessage(obj) {
    return this.PageMessage.encode(this.PageMessage.fromObject(obj)).finish();
  }

  // A PageEvent; event.body names the field set ('hello', 'reply', 'frame', 'error').
  decodeEvent(bytes) {
    return this.PageEvent.decode(bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes));
  }
}

// uint64 as a JS number (counters, frames, ids: far below 2^53).
export function asNumber(v) {
  return typeof v === 'number' ? v : v == null ? 0 : v.toNumber();
}

// uint64 as 16 hex digits, exact (content hashes).
export function asHex(v) {
  const n = typeof v === 'number' ? BigInt(v) : BigInt(v.toString());
  return n.toString(16).padStart(16, '0');
}

export const utf8 = (text) => new TextEncoder().encode(text);

// The Request body kind, for error messages: 'list_scenes', 'basis', ...
const kindOf = (body) => Object.keys(body)[0] ?? 'request';

export class RequestTimeout extends Error {}

// Request/reply over one connection. send(PageMessage object) is given by
// the connection (false: not connected); replies come in through deliver(reply).
export class RequestChannel {
  constructor({ send, maxInFlight = 8, timeoutMs = 10000 }) {
    this.send = send;
    this.maxInFlight = Math.max(1, maxInFlight);
    this.timeoutMs = timeoutMs;
    this.nextId = 1;
    this.queue = [];             // waiting for an in-flight slot
    this.inFlight = new Map();   // id -> pending, sent and unanswered
  }

  // Resolves with the Reply (ok or not); rejects on timeout or disconnect.
  // body: one Request body, e.g. {list_scenes: {}} or {basis: {...}}.
  request(body) {
    return new Promise((resolve, reject) => {
      const pending = { id: this.nextId++, body, kind: kindOf(body), resolve, reject, settled: false };
      // The clock starts when the page asks, so a stalled queue times out too.
      pending.timer = setTimeout(() => this.expire(pending), this.timeoutMs);
      this.queue.push(pending);
      this.pump();
    });
  }

  // Like request, but a refusal (ok = false) rejects with the server's line.
  async call(body) {
    const reply = await this.request(body);
    if (!reply.ok) {
      const error = new Error(reply.error || `${kindOf(body)}: refused without a reason`);
      error.reply = reply;
      throw error;
    }
    return reply;
  }

  setMaxInFlight(n) {
    this.maxInFlight = Math.max(1, n || 1);
    this.pump();
  }

  pump() {
    while (this.queue.length > 0 && this.inFlight.size < this.maxInFlight) {
      const pending = this.queue.shift();
      if (this.send({ request: { id: pending.id, ...pending.body } }) === false) {
        this.settle(pending, () => pending.reject(new Error(`${pending.kind}: not connected to the gateway`)));
        continue;
      }
      this.inFlight.set(pending.id, pending);
    }
  }

  // A Reply from the gateway. Returns false for an id nobody waits for.
  deliver(reply) {
    const id = asNumber(reply.id);
    const pending = this.inFlight.get(id);
    if (!pending) return false;
    // A request that timed out keeps its slot until its late reply comes: the
    // gateway counts it as unanswered until then.
    this.inFlight.delete(id);
    this.settle(pending, () => pending.resolve(reply));
    this.pump();
    return true;
  }

  expire(pending) {
    const queued = this.queue.indexOf(pending);
    if (queued >= 0) this.queue.splice(queued, 1);
    const where = queued >= 0 ? `still queued behind ${this.inFlight.size} unanswered requests` : 'sent';
    this.settle(pending, () =>
      pending.reject(
        new RequestTimeout(
          `${pending.kind}: no reply from the gateway within ${this.timeoutMs} ms (${where}; ` +
            'is phasecast-gateway connected to a running phasecast-server?)',
        ),
      ),
    );
  }

  // The connection is gone: every request fails, slots are free again.
  failAll(message) {
    const all = [...this.inFlight.values(), ...this.queue];
    this.inFlight.clear();
    this.queue = [];
    for (const pending of all) this.settle(pending, () => pending.reject(new Error(`${pending.kind}: ${message}`)));
  }

  settle(pending, action) {
    if (pending.settled) return;
    pending.settled = true;
    clearTimeout(pending.timer);
    action();
  }

  get waiting() {
    return this.queue.length + this.inFlight.size;
  }
}

// One WebSocket to phasecast-gateway, reconnected with backoff when it goes.
// Binary PageMessage out, PageEvent in (protocol.js); replies go to the
// request layer, everything else to the page's handlers.
import { RequestChannel } from './protocol.js';

export const BACKOFF_MS = { first: 500, max: 8000 };

// Delay before reconnect attempt n (0, 1, ...): doubling, capped.
export const backoffDelay = (attempt) => Math.min(BACKOFF_MS.max, BACKOFF_MS.first * 2 ** attempt);

export class GatewayConnection {
  // handlers: {onHello(hello), onFrame(frame), onGatewayError(text), onDown(reason, delayMs), onBytes(n)}
  constructor(url, protocol, handlers, { timeoutMs = 10000, WebSocketImpl = globalThis.WebSocket } = {}) {
    this.url = url;
    this.protocol = protocol;
    this.handlers = handlers;
    this.WebSocketImpl = WebSocketImpl;
    this.attempt = 0;
    this.socket = null;
    this.hello = null;
    this.channel = new RequestChannel({ send: (msg) => this.send(msg), maxInFlight: 1, timeoutMs });
  }

  connect() {
    let socket;
    try {
      socket = new this.WebSocketImpl(this.url);
    } catch (e) {
      this.down(`the gateway address ${this.url} is not usable (${e.message})`);
      return;
    }
    socket.binaryType = 'arraybuffer';
    this.socket = socket;
    socket.onmessage = (e) => this.receive(e.data);
    socket.onclose = (e) => {
      if (this.socket !== socket) return;
      this.socket = null;
      const why = this.hello
        ? `the connection to the gateway at ${this.url} was lost (code ${e.code}${e.reason ? `: ${e.reason}` : ''})`
        : `cannot reach the gateway at ${this.url} (code ${e.code}; is phasecast-gateway running?)`;
      this.down(why);
    };
  }

  down(reason) {
    this.hello = null;
    this.channel.failAll(reason);
    const delay = backoffDelay(this.attempt++);
    this.handlers.onDown?.(reason, delay);
    this.timer = setTimeout(() => this.connect(), delay);
  }

  get connected() {
    return this.hello !== null;
  }

  send(message) {
    if (!this.socket || this.socket.readyState !== 1) return false;
    this.socket.send(this.protocol.encodeMessage(message));
    return true;
  }

  receive(data) {
    this.handlers.onBytes?.(data.byteLength);
    let event;
    try {
      event = this.protocol.decodeEvent(new Uint8Array(data));
    } catch (e) {
      this.handlers.onGatewayError?.(`a gateway event does not parse as a PageEvent (${e.message})`);
      return;
    }
    switch (event.body) {
      case 'hello':
        this.hello = event.hello;
        this.attempt = 0;
        this.channel.setMaxInFlight(event.hello.max_requests_in_flight);
        this.handlers.onHello?.(event.hello);
        break;
      case 'reply':
        this.channel.deliver(event.reply);
        break;
      case 'frame':
        this.handlers.onFrame?.(event.frame);
        break;
      case 'error':
        this.handlers.onGatewayError?.(`the gateway could not read a page message: ${event.error.error}`);
        break;
      default:
        this.handlers.onGatewayError?.('the gateway sent an empty PageEvent');
    }
  }

  request(body) {
    return this.channel.request(body);
  }

  call(body) {
    return this.channel.call(body);
  }

  subscribe(instances) {
    return this.send({ subscribe: { instances } });
  }
}

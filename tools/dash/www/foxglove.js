// A client of the Foxglove WebSocket protocol v1 (subprotocol foxglove.websocket.v1), the part the
// page needs: serverInfo, status, advertise/unadvertise, subscribe, binary message data (opcode
// 0x01: uint32 subscription id, uint64 timestamp [ns], payload; little-endian), time (opcode 0x02),
// and, for a server with the capability clientPublish, the client's own channels (advertise and
// binary opcode 0x01: uint32 channel id, payload).
// Spec: https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md

export const SUBPROTOCOL = "foxglove.websocket.v1";

const BINARY_MESSAGE_DATA = 0x01;
const BINARY_TIME = 0x02;
const CLIENT_BINARY_MESSAGE_DATA = 0x01;

export class FoxgloveClient {
  /// handlers: onOpen(), onClose(event), onServerInfo(info), onStatus(status),
  /// onAdvertise(channels), onUnadvertise(ids), onMessage(channel, timestampNs (BigInt), payload
  /// (Uint8Array)), onTime(timestampNs)
  constructor(url, handlers) {
    this.url = url;
    this.handlers = handlers;
    this.channels = new Map();       // channel id -> channel as advertised
    this.subscriptions = new Map();  // subscription id -> channel id
    this.nextSubscription = 1;
    this.nextClientChannel = 1;
    this.serverInfo = null;
    this.ws = null;
  }

  connect() {
    const ws = new WebSocket(this.url, [SUBPROTOCOL]);
    ws.binaryType = "arraybuffer";
    ws.onopen = () => this.handlers.onOpen?.();
    ws.onclose = (e) => {
      this.channels.clear();
      this.subscriptions.clear();
      this.handlers.onClose?.(e);
    };
    ws.onmessage = (e) => (typeof e.data === "string" ? this.#text(e.data) : this.#binary(e.data));
    this.ws = ws;
  }

  #text(data) {
    let m;
    try {
      m = JSON.parse(data);
    } catch (err) {
      this.handlers.onStatus?.({ level: 2, message: `undecodable message from the server: ${err}` });
      return;
    }
    switch (m.op) {
      case "serverInfo":
        this.serverInfo = m;
        this.handlers.onServerInfo?.(m);
        break;
      case "status":
        this.handlers.onStatus?.(m);
        break;
      case "advertise": {
        const fresh = [];
        for (const c of m.channels ?? []) {
          if (this.channels.has(c.id)) continue;
          this.channels.set(c.id, c);
          fresh.push(c);
        }
        this.handlers.onAdvertise?.(fresh);
        break;
      }
      case "unadvertise":
        for (const id of m.channelIds ?? []) this.channels.delete(id);
        for (const [sub, ch] of this.subscriptions) if (!this.channels.has(ch)) this.subscriptions.delete(sub);
        this.handlers.onUnadvertise?.(m.channelIds ?? []);
        break;
      default:
        break;  // other operations (parameters, services, ...) are not the page's
    }
  }

  #binary(buffer) {
    const view = new DataView(buffer);
    if (view.byteLength < 1) return;
    const op = view.getUint8(0);
    if (op === BINARY_MESSAGE_DATA && view.byteLength >= 13) {
      const sub = view.getUint32(1, true);
      const stamp = view.getBigUint64(5, true);
      const channel = this.channels.get(this.subscriptions.get(sub));
      if (channel) this.handlers.onMessage?.(channel, stamp, new Uint8Array(buffer, 13));
    } else if (op === BINARY_TIME && view.byteLength >= 9) {
      this.handlers.onTime?.(view.getBigUint64(1, true));
    }
  }

  #send(obj) {
    if (this.ws?.readyState === WebSocket.OPEN) this.ws.send(JSON.stringify(obj));
  }

  /// Subscribes to the channels (ids); returns their subscription ids. fieldsOf(channelId): more
  /// fields of a subscription, such as pneu-dash's {maxRateHz} (a server that knows none ignores them).
  subscribe(channelIds, fieldsOf = () => ({})) {
    const subs = channelIds.map((channelId) => ({ id: this.nextSubscription++, channelId, ...fieldsOf(channelId) }));
    for (const s of subs) this.subscriptions.set(s.id, s.channelId);
    if (subs.length) this.#send({ op: "subscribe", subscriptions: subs });
    return subs.map((s) => s.id);
  }

  /// Advertises a channel of the client's own (capability clientPublish); returns its id.
  advertise(topic, encoding, schemaName) {
    const id = this.nextClientChannel++;
    this.#send({ op: "advertise", channels: [{ id, topic, encoding, schemaName }] });
    return id;
  }

  /// Publishes `payload` (a Uint8Array) on a channel the client advertised.
  publish(channelId, payload) {
    if (this.ws?.readyState !== WebSocket.OPEN) return false;
    const frame = new Uint8Array(5 + payload.byteLength);
    const view = new DataView(frame.buffer);
    view.setUint8(0, CLIENT_BINARY_MESSAGE_DATA);
    view.setUint32(1, channelId, true);
    frame.set(payload, 5);
    this.ws.send(frame);
    return true;
  }

  close() {
    this.ws?.close();
  }
}

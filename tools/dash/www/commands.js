// The command panel's implementation (issue 31, the `cmd` part): installed into the page
// (window.pneuDash.installCommands) when the server takes commands (its serverInfo has the
// capability clientPublish; pneu-dash has it only with --commands-token-file).
//
// Its own connection to /ws, so that its session is its own: the token is published once on
// pneu.commands.login (the server answers with a status, id pneu.commands.login, naming the
// session), then each command on pneu.commands.command (answered with a status, id
// pneu.commands.command, naming its sequence number). pneud's verdict is the command_accepted /
// command_rejected event on PNEU_EVENT with that sequence number and this session: the panel
// shows that, pneud's words. The token is kept in memory only (sent again on a new connection),
// never in the browser's storage.
import { FoxgloveClient } from "./foxglove.js";

const LOGIN_TOPIC = "pneu.commands.login";
const COMMAND_TOPIC = "pneu.commands.command";
const VERDICT_TIMEOUT_MS = 5000;

const encoder = new TextEncoder();
const decoder = new TextDecoder();

const link = {
  client: null,
  ready: false,        // serverInfo received, our channels advertised
  loginChannel: 0,
  commandChannel: 0,
  token: null,         // the token the session was given for
  session: 0,          // 0: none
  waiting: [],         // status waiters: {id, resolve}
  verdicts: new Map(), // seq -> resolve, waiting for pneud's event
  early: new Map(),    // seq -> event that came before the status naming its seq
  installed: false,
};

// "seq 123" / "session 456" in a status message.
const numberAfter = (word, text) => {
  const m = new RegExp(`${word} (\\d+)`).exec(text ?? "");
  return m ? Number(m[1]) : 0;
};

function isVerdict(kind) {
  return kind === "command_accepted" || kind === "command_rejected" || kind === 5 || kind === 6;
}

function onEvent(e) {
  if (!isVerdict(e.kind) || !link.session || Number(e.session) !== link.session) return;
  const seq = Number(e.seq);
  const accepted = e.kind === "command_accepted" || e.kind === 5;
  const verdict = { accepted, text: e.text ?? "", by: "pneud", seq, session: link.session, origin: e.origin };
  const resolve = link.verdicts.get(seq);
  if (resolve) {
    link.verdicts.delete(seq);
    resolve(verdict);
  } else {
    link.early.set(seq, verdict);
    if (link.early.size > 64) link.early.delete(link.early.keys().next().value);
  }
}

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  const client = new FoxgloveClient(url, {
    onServerInfo: (info) => {
      if (!(info.capabilities ?? []).includes("clientPublish")) return;  // commands off
      link.loginChannel = client.advertise(LOGIN_TOPIC, "json", LOGIN_TOPIC);
      link.commandChannel = client.advertise(COMMAND_TOPIC, "json", COMMAND_TOPIC);
      link.ready = true;
      if (!link.installed && window.pneuDash?.installCommands) {
        link.installed = true;
        window.pneuDash.installCommands(send);
      }
    },
    onAdvertise: (channels) => {
      const events = channels.filter((c) => /EVENT$/.test(c.topic));
      if (events.length) client.subscribe(events.map((c) => c.id));
    },
    onMessage: (channel, _stamp, payload) => {
      try {
        onEvent(JSON.parse(decoder.decode(payload)));
      } catch { /* not JSON: not ours */ }
    },
    onStatus: (s) => {
      const i = link.waiting.findIndex((w) => w.id === s.id);
      if (i >= 0) link.waiting.splice(i, 1)[0].resolve(s);
    },
    onClose: () => {
      link.ready = false;
      link.session = 0;  // the session was the connection's
      for (const w of link.waiting.splice(0)) w.resolve({ level: 2, message: "the connection to pneu-dash closed" });
      setTimeout(connect, 1000);
    },
  });
  link.client = client;
  client.connect();
}

// Publishes `obj` on `channel` and waits for the server's status with `id`.
function ask(channel, id, obj) {
  return new Promise((resolve) => {
    const waiter = { id, resolve };
    link.waiting.push(waiter);
    if (!link.client.publish(channel, encoder.encode(JSON.stringify(obj)))) {
      link.waiting.splice(link.waiting.indexOf(waiter), 1);
      resolve({ level: 2, message: "not connected to pneu-dash" });
    }
    setTimeout(() => {
      const i = link.waiting.indexOf(waiter);
      if (i >= 0) {
        link.waiting.splice(i, 1);
        resolve({ level: 2, message: "no answer from pneu-dash" });
      }
    }, VERDICT_TIMEOUT_MS);
  });
}

async function login(token) {
  const s = await ask(link.loginChannel, LOGIN_TOPIC, { token });
  if (s.level !== 0) {
    link.session = 0;
    link.token = null;
    return s.message;
  }
  link.session = numberAfter("session", s.message);
  link.token = token;
  window.pneuDash.state.commandSession = link.session;
  return "";
}

// sendCommand's implementation: (kind, value, token) -> Promise<{accepted, text}>.
async function send(kind, value, token) {
  if (!link.ready) return { accepted: false, text: "not connected", by: "pneu-dash" };
  if (!token) return { accepted: false, text: "enter the token first", by: "pneu-dash" };
  if (kind === "hold") kind = value ? "hold_on" : "hold_off";
  if (!link.session || link.token !== token) {
    const refused = await login(token);
    if (refused) return { accepted: false, text: refused, by: "pneu-dash" };
  }
  const command = value === undefined || typeof value === "boolean" ? { kind } : { kind, value };
  const s = await ask(link.commandChannel, COMMAND_TOPIC, command);
  if (s.level !== 0) return { accepted: false, text: s.message, by: "pneu-dash" };
  const seq = numberAfter("seq", s.message);
  if (link.early.has(seq)) {
    const v = link.early.get(seq);
    link.early.delete(seq);
    return v;
  }
  return new Promise((resolve) => {
    link.verdicts.set(seq, resolve);
    setTimeout(() => {
      if (link.verdicts.delete(seq))
        resolve({ accepted: false, by: "pneu-dash", text: `sent (seq ${seq}), but no verdict from pneud within ${VERDICT_TIMEOUT_MS / 1000} s: ` +
                                          "is pneud running, on this LCM URL, with commands enabled?" });
    }, VERDICT_TIMEOUT_MS);
  });
}

connect();

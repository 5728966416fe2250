// An independent client of pneu-dash: the Foxglove WebSocket protocol's own client
// (@foxglove/ws-protocol's FoxgloveClient, on the `ws` package). Receives serverInfo and advertise,
// subscribes to every channel, and validates each message against the JSON Schema its channel
// advertised (ajv, draft 2020-12). Fails when a required topic brings fewer messages than asked,
// when any message does not follow its schema, or when a schema would not catch a missing field.
//
// usage: node foxglove_client.mjs URL SECONDS TOPIC:MIN [TOPIC:MIN ...]
import WebSocket from "ws";
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS: its exports as the default
import ajvModule from "ajv/dist/2020.js";

const { FoxgloveClient } = wsProtocol;
const Ajv2020 = ajvModule.default ?? ajvModule;
const [url, secondsText, ...wanted] = process.argv.slice(2);
if (!url || !secondsText) {
  console.error("usage: node foxglove_client.mjs URL SECONDS TOPIC:MIN ...");
  process.exit(2);
}
const minimum = new Map(wanted.map((w) => [w.split(":")[0], Number(w.split(":")[1])]));
const failures = [];
const fail = (text) => {
  if (failures.length < 20) console.log(`FAIL: ${text}`);
  failures.push(text);
};

const ajv = new Ajv2020({ allErrors: true, strict: true });
ajv.addKeyword({ keyword: "unit", schemaType: "string" }); // the records' unit of a field, for people

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
let serverInfo = null;
const bySubscription = new Map(); // subscription id -> {channel, validate}
const counts = new Map(); // topic -> messages
const gaps = new Map(); // topic -> messages missing by its sequence field
const lastSeq = new Map();
const decoder = new TextDecoder();

client.on("serverInfo", (info) => {
  serverInfo = info;
  if (!(info.supportedEncodings ?? []).includes("json")) fail(`serverInfo: no json encoding: ${JSON.stringify(info)}`);
});
client.on("status", (s) => {
  console.log(`status (level ${s.level}): ${s.message}`);
  if (s.level === 2) fail(`an error status: ${s.message}`);
});
client.on("error", (e) => fail(`client error: ${e?.message ?? e}`));
client.on("advertise", (channels) => {
  for (const channel of channels) {
    if (channel.encoding !== "json") fail(`${channel.topic}: encoding ${channel.encoding}`);
    if (channel.schemaEncoding !== "jsonschema") fail(`${channel.topic}: schemaEncoding ${channel.schemaEncoding}`);
    let validate;
    try {
      validate = ajv.compile(JSON.parse(channel.schema));
    } catch (e) {
      fail(`${channel.topic}: its schema does not compile: ${e.message}`);
      continue;
    }
    if (validate({})) fail(`${channel.topic}: its schema takes an empty object (no required field)`);
    const id = client.subscribe(channel.id);
    bySubscription.set(id, { channel, validate, checkedMissing: false });
    counts.set(channel.topic, 0);
    gaps.set(channel.topic, 0);
    console.log(`advertised ${channel.topic} (${channel.schemaName}), subscribed as ${id}`);
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const sub = bySubscription.get(subscriptionId);
  if (!sub) return fail(`a message of unknown subscription ${subscriptionId}`);
  const topic = sub.channel.topic;
  let record;
  try {
    record = JSON.parse(decoder.decode(data));
  } catch (e) {
    return fail(`${topic}: a message that is not JSON: ${e.message}`);
  }
  if (!sub.validate(record)) {
    return fail(`${topic}: ${ajv.errorsText(sub.validate.errors)} in ${JSON.stringify(record).slice(0, 300)}`);
  }
  // The validation fails when a field is missing: the first message without each of its fields.
  if (!sub.checkedMissing) {
    sub.checkedMissing = true;
    for (const key of Object.keys(record)) {
      const without = { ...record };
      delete without[key];
      const required = JSON.parse(sub.channel.schema).required ?? [];
      if (required.includes(key) && sub.validate(without)) fail(`${topic}: the schema takes a message without ${key}`);
    }
  }
  counts.set(topic, counts.get(topic) + 1);
  const field = sub.channel.sequenceField;
  if (field && typeof record[field] === "number") {
    if (lastSeq.has(topic) && record[field] > lastSeq.get(topic) + 1)
      gaps.set(topic, gaps.get(topic) + record[field] - lastSeq.get(topic) - 1);
    lastSeq.set(topic, record[field]);
  }
});

const done = () => [...minimum].every(([topic, min]) => (counts.get(topic) ?? 0) >= min);
const started = Date.now();
const timer = setInterval(() => {
  if (!done() && Date.now() - started < Number(secondsText) * 1000 && failures.length === 0) return;
  clearInterval(timer);
  if (!serverInfo) fail("no serverInfo");
  for (const [topic, min] of minimum)
    if ((counts.get(topic) ?? 0) < min) fail(`${topic}: ${counts.get(topic) ?? 0} messages, fewer than ${min}`);
  for (const [topic, n] of counts)
    console.log(`${topic}: ${n} messages valid${gaps.get(topic) ? `, ${gaps.get(topic)} missing by its sequence` : ""}`);
  client.close();
  if (failures.length > 0) {
    console.log(`FAIL: ${failures.length} failure(s)`);
    process.exit(1);
  }
  console.log("PASSED");
  process.exit(0);
}, 100);

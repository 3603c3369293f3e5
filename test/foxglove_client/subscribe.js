// Foxglove's own protocol client as an independent consumer of fmm_ros's Foxglove server.
//
//   node subscribe.js URL SECONDS TOPIC=COUNT [TOPIC=COUNT ...]
//
// Connects with @foxglove/ws-protocol, subscribes to each TOPIC as the server advertises it,
// decodes every message with Foxglove's ROS 2 decoder (@foxglove/rosmsg parses the channel's
// ros2msg schema, @foxglove/rosmsg2-serialization reads the CDR) and prints one JSON line a
// message: {topic, schemaName, logTimeNs, message}, number arrays as {length, min, max, first},
// times in nanoseconds as decimal strings. It stops once every TOPIC has given COUNT messages
// (exit 0) or after SECONDS (exit 1, naming what is missing). The last line is
// {"time": [server times seen]}.
"use strict";

const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const WebSocket = require("ws");

const [url, seconds, ...wanted] = process.argv.slice(2);
const counts = new Map(
  wanted.map((item) => {
    const at = item.lastIndexOf("=");
    return [item.slice(0, at), Number(item.slice(at + 1))];
  }),
);
const received = new Map([...counts.keys()].map((topic) => [topic, 0]));
const subscriptions = new Map(); // subscription id -> {topic, schemaName, reader}
const times = [];
const lines = []; // printed at the end: process.exit may cut a pipe's pending writes

function summarize(value) {
  if (typeof value === "bigint") {
    return Number(value);
  }
  if (ArrayBuffer.isView(value) && !(value instanceof DataView)) {
    const values = Array.from(value, Number);
    return {
      length: values.length,
      min: values.length ? Math.min(...values) : null,
      max: values.length ? Math.max(...values) : null,
      first: values.length ? values[0] : null,
    };
  }
  if (Array.isArray(value)) {
    return value.map(summarize);
  }
  if (value && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, summarize(v)]));
  }
  return value;
}

function finish(code, reason) {
  client.close();
  lines.push(JSON.stringify({ time: times }));
  if (reason) {
    console.error(reason);
  }
  process.stdout.write(lines.join("\n") + "\n", () => process.exit(code));
}

// The SDK's server speaks the ws-protocol spec under the subprotocol name foxglove.sdk.v1
// (foxglove_bridge: foxglove.websocket.v1); the client offers both, as the Foxglove app does.
const client = new FoxgloveClient({
  ws: new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]),
});
client.on("error", (error) => finish(2, `connection error: ${error}`));
client.on("advertise", (channels) => {
  for (const channel of channels) {
    if (!counts.has(channel.topic)) {
      continue;
    }
    if (channel.encoding !== "cdr" || channel.schemaEncoding !== "ros2msg") {
      finish(3, `${channel.topic}: ${channel.encoding}/${channel.schemaEncoding}, not cdr/ros2msg`);
    }
    const reader = new MessageReader(parse(channel.schema, { ros2: true }));
    const id = client.subscribe(channel.id);
    subscriptions.set(id, { topic: channel.topic, schemaName: channel.schemaName, reader });
  }
});
client.on("time", (event) => times.push(event.timestamp.toString()));
let finished = false;
client.on("message", (event) => {
  if (finished) {
    return;
  }
  const channel = subscriptions.get(event.subscriptionId);
  const bytes = new Uint8Array(event.data.buffer, event.data.byteOffset, event.data.byteLength);
  const message = channel.reader.readMessage(bytes);
  received.set(channel.topic, received.get(channel.topic) + 1);
  lines.push(
    JSON.stringify({
      topic: channel.topic,
      schemaName: channel.schemaName,
      logTimeNs: event.timestamp.toString(), // nanoseconds exceed a double's 53 bits
      message: summarize(message),
    }),
  );
  if ([...counts].every(([topic, count]) => received.get(topic) >= count)) {
    finished = true;
    finish(0);
  }
});
setTimeout(() => {
  const missing = [...counts].filter(([topic, count]) => received.get(topic) < count);
  finish(1, `after ${seconds} s: ${missing.map(([t, c]) => `${t} ${received.get(t)}/${c}`)}`);
}, Number(seconds) * 1000);

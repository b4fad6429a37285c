// A viewer as Foxglove and Lichtblick are: their WebSocket client library
// (@foxglove/ws-protocol) and their ROS 2 message decoding (@foxglove/rosmsg,
// @foxglove/rosmsg2-serialization), none of it ours. tests/test_gui_foxglove.py runs it
// against debug_gui's Foxglove endpoint, so the endpoint is held to what those apps do,
// not to our reading of the spec.
//
//   node viewer.mjs URL TOPIC PARAM VALUE SERVICE
//
// Subscribes to TOPIC and decodes its first message from the advertised schema alone, gets
// PARAM, sets it to VALUE (a JSON number), calls SERVICE (an UnloadComponent: unique_id 7)
// and decodes the response; each step prints one JSON line ({"step": ..., ...}). Exits 0
// when every step is done, 1 with {"step": "error", ...} on a failure or after 60 s.
import rosmsg from "@foxglove/rosmsg";
import serialization from "@foxglove/rosmsg2-serialization";
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

// The libraries are CommonJS: their names come off the default export.
const { parse } = rosmsg;
const { MessageReader, MessageWriter } = serialization;
const { FoxgloveClient } = wsProtocol;

const [url, topic, paramName, paramValue, serviceName] = process.argv.slice(2);
if (!serviceName) {
  console.error("usage: node viewer.mjs URL TOPIC PARAM VALUE SERVICE");
  process.exit(2);
}

const say = (record) => console.log(JSON.stringify(record, (_k, v) =>
  typeof v === "bigint" ? Number(v) : v));
const fail = (message) => {
  say({ step: "error", message });
  process.exit(1);
};
setTimeout(() => fail("not done within 60 s"), 60_000).unref();

const client = new FoxgloveClient({
  ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]),
});
let subscription;
let decoder; // the subscribed channel's, from its advertised schema
let serviceCalled = false;
const pending = new Set(["serverInfo", "message", "get", "set", "service"]);
const done = (step) => {
  pending.delete(step);
  if (pending.size === 0) {
    client.close();
    process.exit(0);
  }
};

client.on("error", (error) => fail(`connection: ${error?.message ?? error}`));
client.on("serverInfo", (info) => {
  say({ step: "serverInfo", name: info.name, capabilities: info.capabilities });
  done("serverInfo");
  client.getParameters([paramName], "get");
});
client.on("status", (status) => say({ step: "status", level: status.level,
                                      message: status.message }));
client.on("advertise", (channels) => {
  for (const channel of channels) {
    if (channel.topic !== topic || subscription !== undefined) continue;
    if (channel.encoding !== "cdr" || channel.schemaEncoding !== "ros2msg") {
      fail(`channel ${topic}: ${channel.encoding}/${channel.schemaEncoding}`);
    }
    decoder = new MessageReader(parse(channel.schema, { ros2: true }));
    subscription = client.subscribe(channel.id);
  }
});
client.on("message", ({ subscriptionId, data }) => {
  if (subscriptionId !== subscription || !pending.has("message")) return;
  const decoded = decoder.readMessage(data);
  say({ step: "message", topic, decoded });
  client.unsubscribe(subscription);
  done("message");
});
client.on("parameterValues", ({ parameters, id }) => {
  say({ step: id, parameters });
  if (id === "get") {
    client.setParameters([{ name: paramName, value: JSON.parse(paramValue) }], "set");
  }
  if (id === "get" || id === "set") done(id);
});
client.on("advertiseServices", (services) => {
  const service = services.find((s) => s.name === serviceName);
  if (!service || serviceCalled) return;
  serviceCalled = true;
  const request = new MessageWriter(parse(service.request.schema, { ros2: true }));
  const reader = new MessageReader(parse(service.response.schema, { ros2: true }));
  client.on("serviceCallResponse", (response) => {
    if (response.serviceId !== service.id) return;
    say({ step: "service", type: service.type, response: reader.readMessage(response.data) });
    done("service");
  });
  client.on("serviceCallFailure", (failure) => fail(`service call: ${failure.message}`));
  client.sendServiceCallRequest({
    serviceId: service.id, callId: 1, encoding: "cdr",
    data: new DataView(request.writeMessage({ unique_id: 7n }).buffer),
  });
});

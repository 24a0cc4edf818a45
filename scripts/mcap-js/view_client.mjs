// CI check: `servo view` driven by the official Foxglove WebSocket client
// (`@foxglove/ws-protocol`'s FoxgloveClient over the `ws` package), offering the protocol's own
// subprotocol `foxglove.websocket.v1`: connect, subscribe to /overview, read the parameters,
// set gain_scale to a value the loop can take (applied) and to one it cannot (refused: the
// parameter keeps the applied value), call the stop service (the run ends), and see the view
// close the connection.
//
//   node view_client.mjs ws://127.0.0.1:PORT
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const url = process.argv[2];
const fail = (why) => {
  console.error(`view_client: ${why}`);
  process.exit(1);
};
setTimeout(() => fail("timed out after 120 s"), 120_000).unref();

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
let overview = 0;
let stopService;
let step = "connect";
const seen = {};

client.on("error", (e) => fail(`error: ${e}`));
client.on("serverInfo", (info) => {
  if (ws.protocol !== "foxglove.websocket.v1") fail(`negotiated ${ws.protocol}`);
  if (!info.capabilities.includes("parameters")) fail(`capabilities ${info.capabilities}`);
});
client.on("advertise", (channels) => {
  const ch = channels.find((c) => c.topic === "/overview");
  if (!ch || ch.encoding !== "json") fail(`advertised ${JSON.stringify(channels)}`);
  client.subscribe(ch.id);
});
client.on("advertiseServices", (services) => {
  stopService = services.find((s) => s.name === "stop");
});
client.on("message", () => {
  overview += 1;
  if (overview === 50 && step === "connect") {
    step = "get";
    client.getParameters([], "all");
  }
});
client.on("parameterValues", ({ parameters, id }) => {
  const gain = parameters.find((p) => p.name === "gain_scale");
  seen[id] = gain && gain.value;
  if (id === "all") {
    if (gain.value !== 1) fail(`gain_scale ${gain.value}`);
    if (!parameters.some((p) => p.name === "run.id")) fail("no run.id");
    client.setParameters([{ name: "gain_scale", value: 1.2, type: "float64" }], "gain");
  } else if (id === "gain") {
    if (gain.value !== 1.2) fail(`gain 1.2 not applied: ${gain.value}`);
    client.setParameters([{ name: "gain_scale", value: 50, type: "float64" }], "wild");
  } else if (id === "wild") {
    if (gain.value !== 1.2) fail(`gain 50 applied: ${gain.value}`);
    if (!stopService) fail("no stop service");
    step = "stop";
    client.sendServiceCallRequest({
      serviceId: stopService.id,
      callId: 1,
      encoding: "json",
      data: new TextEncoder().encode("{}"),
    });
  }
});
client.on("serviceCallFailure", (f) => fail(`stop failed: ${f.message}`));
client.on("serviceCallResponse", (r) => {
  const answer = JSON.parse(new TextDecoder().decode(r.data));
  console.log(
    `view_client: ${overview} /overview samples, gain_scale 1.2 applied and 50 refused, stopped at tick ${answer.stopped_at_tick}`,
  );
  step = "stopped";
});
client.on("close", () => {
  if (step !== "stopped") fail(`closed during ${step}`);
  process.exit(0);
});

// Soak check (scripts/soak.py): one visit of the official Foxglove WebSocket client
// (`@foxglove/ws-protocol`'s FoxgloveClient over the `ws` package) to a `servo view` served
// over TLS, the way a careful user connects: the view's certificate fetched, its SHA-256
// fingerprint compared with the one the view printed, then trusted alone (no host-name check:
// the fingerprint is its identity); connect with the token in the URL, subscribe to
// /overview, read MESSAGES samples and the parameters, leave.
//
//   node soak_client.mjs wss://HOST:PORT/?token=… FINGERPRINT [MESSAGES]
import tls from "node:tls";
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, pin, wanted = "20"] = process.argv.slice(2);
const fail = (why) => {
  console.error(`soak_client: ${why}`);
  process.exit(1);
};
setTimeout(() => fail("timed out after 60 s"), 60_000).unref();

const at = new URL(url);
const host = at.hostname === "0.0.0.0" ? "127.0.0.1" : at.hostname;
const hex = (s) => s.replaceAll(":", "").toLowerCase();

// The certificate, fetched but not yet trusted.
const probe = tls.connect({ host, port: Number(at.port), rejectUnauthorized: false }, () => {
  const cert = probe.getPeerCertificate();
  probe.end();
  if (hex(cert.fingerprint256) !== hex(pin)) fail(`not the view's certificate: ${cert.fingerprint256}`);
  const b64 = cert.raw.toString("base64").match(/.{1,64}/g).join("\n");
  visit(`-----BEGIN CERTIFICATE-----\n${b64}\n-----END CERTIFICATE-----\n`);
});
probe.on("error", (e) => fail(`TLS probe: ${e.message}`));

function visit(pem) {
  at.hostname = host;
  const ws = new WebSocket(at.toString(), [FoxgloveClient.SUPPORTED_SUBPROTOCOL], {
    ca: pem,
    checkServerIdentity: () => undefined,
  });
  const client = new FoxgloveClient({ ws });
  let overview = 0;
  let done = false;
  client.on("error", (e) => fail(`error: ${e}`));
  client.on("advertise", (channels) => {
    const ch = channels.find((c) => c.topic === "/overview");
    if (!ch) fail(`advertised ${JSON.stringify(channels)}`);
    client.subscribe(ch.id);
  });
  client.on("message", () => {
    overview += 1;
    if (overview === Number(wanted)) client.getParameters([], "all");
  });
  client.on("parameterValues", ({ parameters }) => {
    if (!parameters.some((p) => p.name === "run.id")) fail("no run.id");
    done = true;
    console.log(`soak_client: ${overview} /overview samples, ${parameters.length} parameters`);
    client.close();
  });
  client.on("close", () => {
    if (!done) fail(`closed after ${overview} samples`);
    process.exit(0);
  });
}

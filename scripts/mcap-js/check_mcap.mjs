// Reads an fts-servo recording with the TypeScript MCAP library the Foxglove app is built on
// (@mcap/core), decoding every ros2msg payload with @foxglove/rosmsg2-serialization:
//  - finished files: McapIndexedReader reads every message through the summary and the
//    message indexes (CRCs validated), and a /overview-only read touches only its chunks;
//  - every file (finished, interrupted, unfinished): McapStreamReader with CRC validation
//    reads every record up to where the file ends.
// Usage: node check_mcap.mjs FILE [--ticks N] [--unfinished]
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { decompress } from "fzstd";
import { readFile } from "node:fs/promises";

const [file, ...flags] = process.argv.slice(2);
const ticks = flags.includes("--ticks") ? Number(flags[flags.indexOf("--ticks") + 1]) : undefined;
const unfinished = flags.includes("--unfinished");
const bytes = new Uint8Array(await readFile(file));
const decompressHandlers = {
  zstd: (buffer, size) => decompress(buffer, new Uint8Array(Number(size))),
};

function check(condition, message) {
  if (!condition) {
    console.error(`${file}: ${message}`);
    process.exit(1);
  }
}

/** Decoders by schema id, built from the schema records' ros2msg text. */
function decoders(schemas) {
  const out = new Map();
  for (const [id, s] of schemas) {
    check(s.encoding === "ros2msg", `schema ${s.name} is ${s.encoding}`);
    const text = new TextDecoder().decode(s.data);
    out.set(id, new MessageReader(parse(text, { ros2: true })));
  }
  return out;
}

/** Decodes one message and checks the fields the viewer plots. */
function decode(readers, channel, data, counts) {
  const m = readers.get(channel.schemaId).readMessage(data);
  counts[channel.topic] = (counts[channel.topic] ?? 0) + 1;
  if (channel.topic === "/telemetry") check(Number.isFinite(m.following_error_m), "telemetry");
  if (channel.topic === "/truth") check(Number.isFinite(m.tool_m), "truth");
  if (channel.topic === "/overview") {
    check(m.ticks > 0 && m.min.following_error_m <= m.max.following_error_m, "overview");
  }
}

let summary = "";
if (!unfinished) {
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  check(reader.header.profile === "ros2", `profile ${reader.header.profile}`);
  check(reader.chunkIndexes.length > 0, "no chunk indexes");
  const readers = decoders(reader.schemasById);
  const counts = {};
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    decode(readers, reader.channelsById.get(m.channelId), m.data, counts);
  }
  if (ticks !== undefined) {
    check(counts["/telemetry"] === ticks && counts["/truth"] === ticks, JSON.stringify(counts));
  }
  const overview = {};
  for await (const m of reader.readMessages({ topics: ["/overview"], validateCrcs: true })) {
    decode(readers, reader.channelsById.get(m.channelId), m.data, overview);
  }
  check(overview["/overview"] === counts["/overview"], "overview read alone differs");
  const end = [];
  for await (const m of reader.readMetadata({ name: "end" })) end.push(m.metadata.get("reason"));
  check(end.length === 1, "no end record");
  summary = `indexed reader: ${JSON.stringify(counts)}, ended ${end[0]}; `;
}

const stream = new McapStreamReader({ validateCrcs: true, decompressHandlers });
stream.append(bytes);
const schemas = new Map();
const channels = new Map();
const counts = {};
let footer = false;
let readers;
for (let r; (r = stream.nextRecord()); ) {
  if (r.type === "Schema") schemas.set(r.id, r);
  if (r.type === "Channel") channels.set(r.id, r);
  if (r.type === "Message") {
    readers ??= decoders(schemas);
    decode(readers, channels.get(r.channelId), r.data, counts);
  }
  if (r.type === "Footer") footer = true;
}
check(footer === !unfinished, footer ? "finished, not unfinished" : "no footer");
check((counts["/telemetry"] ?? 0) > 0, "no telemetry read");
if (ticks !== undefined) check(counts["/telemetry"] === ticks, JSON.stringify(counts));
console.log(`${file}: @mcap/core ${summary}stream reader (CRCs validated): ${JSON.stringify(counts)}`);

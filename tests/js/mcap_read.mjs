// Reads an MCAP file back with the MCAP project's own reader (npm @mcap/core), twice: the
// indexed reader (summary, chunk indexes and message indexes, every CRC checked) and the stream
// reader (every record in file order, CRCs checked). Prints one JSON object:
//   {"topics": {topic: messages}, "schemas": {topic: schema name}, "encodings": {topic: message
//    encoding}, "statistics": {"message_count", "channel_message_counts": {topic: n}},
//    "stream_topics": {topic: messages}, "not_json": n, "out_of_order": n,
//    "invalid": {topic: messages not valid against Foxglove's own JSON schema of the channel's
//    schema name (npm @foxglove/schemas, checked with ajv)}, "errors": [the first few, as text],
//    "samples": {topic: first message, parsed}}
// Exit status 1 with the reason on stderr when the file cannot be read.
// Usage: node tests/js/mcap_read.mjs FILE.mcap   (after `npm ci` in tests/js)
import { open, readFile } from "node:fs/promises";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import foxglove from "@foxglove/schemas/jsonschema.js";
import Ajv from "ajv";

const ajv = new Ajv({ strict: false, allErrors: false });
const validators = new Map();  // schema name -> ajv validator of Foxglove's schema, or null
function validatorOf(name) {
  if (!validators.has(name)) {
    const schema = name?.startsWith("foxglove.") ? foxglove[name.slice("foxglove.".length)] : undefined;
    validators.set(name, schema ? ajv.compile(schema) : null);
  }
  return validators.get(name);
}

const path = process.argv[2];
if (!path || path === "--help") {
  console.log("usage: node mcap_read.mjs FILE.mcap");
  process.exit(path ? 0 : 2);
}

try {
  const handle = await open(path, "r");
  const size = (await handle.stat()).size;
  const readable = {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const buffer = new Uint8Array(Number(length));
      await handle.read(buffer, 0, Number(length), Number(offset));
      return buffer;
    },
  };
  const reader = await McapIndexedReader.Initialize({ readable });
  const topicOf = (id) => reader.channelsById.get(id).topic;
  const out = { topics: {}, schemas: {}, encodings: {}, statistics: null, stream_topics: {}, not_json: 0,
                out_of_order: 0, invalid: {}, errors: [], samples: {} };
  for (const ch of reader.channelsById.values()) {
    out.topics[ch.topic] = 0;
    out.schemas[ch.topic] = reader.schemasById.get(ch.schemaId)?.name ?? null;
    out.encodings[ch.topic] = ch.messageEncoding;
  }
  const decoder = new TextDecoder();
  let last = -1n;
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const topic = topicOf(m.channelId);
    out.topics[topic] += 1;
    if (m.logTime < last) out.out_of_order += 1;
    last = m.logTime;
    try {
      const value = JSON.parse(decoder.decode(m.data));
      if (!(topic in out.samples)) out.samples[topic] = value;
      const validate = validatorOf(out.schemas[topic]);
      if (!validate) {
        out.invalid[topic] = (out.invalid[topic] ?? 0) + 1;
        if (out.errors.length < 5) out.errors.push(`${topic}: no Foxglove schema named ${out.schemas[topic]}`);
      } else if (!validate(value)) {
        out.invalid[topic] = (out.invalid[topic] ?? 0) + 1;
        if (out.errors.length < 5) out.errors.push(`${topic}: ${ajv.errorsText(validate.errors)}`);
      }
    } catch {
      out.not_json += 1;
    }
  }
  if (reader.statistics) {
    const counts = {};
    for (const [id, n] of reader.statistics.channelMessageCounts) counts[topicOf(id)] = Number(n);
    out.statistics = { message_count: Number(reader.statistics.messageCount), channel_message_counts: counts };
  }
  await handle.close();

  const stream = new McapStreamReader({ validateCrcs: true });
  stream.append(await readFile(path));
  const channels = new Map();
  for (let record; (record = stream.nextRecord()); ) {
    if (record.type === "Channel") channels.set(record.id, record.topic);
    if (record.type === "Message") {
      const topic = channels.get(record.channelId);
      out.stream_topics[topic] = (out.stream_topics[topic] ?? 0) + 1;
    }
  }
  if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");
  console.log(JSON.stringify(out));
} catch (e) {
  console.error(`mcap_read: ${path}: ${e.message}`);
  process.exit(1);
}

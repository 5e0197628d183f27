// Read an MCAP bag with Foxglove's libraries and print a JSON summary:
//   node read_bag.mjs BAG.mcap
// Decodes every message with the schema stored in the file (ros2msg + CDR), so a schema or
// CDR layout Foxglove cannot parse fails here.
import { readFile } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { decompress } from "fzstd";

const path = process.argv[2];
const bytes = new Uint8Array(await readFile(path));
const readable = {
  size: async () => BigInt(bytes.length),
  read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
};
const reader = await McapIndexedReader.Initialize({
  readable,
  decompressHandlers: { zstd: (data, size) => decompress(data, new Uint8Array(Number(size))) },
});
const readers = new Map();
const summary = { topics: {}, first: {} };
for await (const msg of reader.readMessages()) {
  const channel = reader.channelsById.get(msg.channelId);
  const schema = reader.schemasById.get(channel.schemaId);
  if (!readers.has(channel.id)) {
    const defs = parse(new TextDecoder().decode(schema.data), { ros2: true });
    readers.set(channel.id, new MessageReader(defs));
  }
  const decoded = readers.get(channel.id).readMessage(msg.data);
  const t = summary.topics[channel.topic] ?? { type: schema.name, count: 0 };
  t.count += 1;
  summary.topics[channel.topic] = t;
  if (!(channel.topic in summary.first)) summary.first[channel.topic] = decoded;
}
summary.metadata = {};
for await (const m of reader.readMetadata()) summary.metadata[m.name] = Object.fromEntries(m.metadata);
process.stdout.write(JSON.stringify(summary, (k, v) => (typeof v === "bigint" ? v.toString() : ArrayBuffer.isView(v) ? Array.from(v) : v)));

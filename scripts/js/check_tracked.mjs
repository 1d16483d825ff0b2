#!/usr/bin/env node
// Reads a tracked MCAP with the libraries the Foxglove app uses: @mcap/core (McapIndexedReader
// and McapStreamReader), the chunk decompressors of @mcap/support, and protobufjs decoding with
// the FileDescriptorSet embedded in each schema record (as Foxglove does for protobuf channels).
//
// Prints one JSON object on stdout:
//   {"channels": [{topic, schema, messages}], "indexed_messages": N, "stream_messages": N,
//    "log_time_backwards": K,          // stream order: messages whose log_time < the previous
//    "frames": [{topic, log_time, stamp, frame_id, ids: [...], centers: [[x,y,z]...],
//                deletions: [...]}]}    // every probmot.Tracks3D and foxglove.SceneUpdate message
// A SceneUpdate frame has the entity ids ("track/<id>") with the cube centres; a Tracks3D frame
// the track ids (as decimal strings, uint64) with the box centres. Exits 1 with a message on
// stderr when a message does not decode or the two readers disagree.
//
// Usage: node scripts/js/check_tracked.mjs FILE.mcap
// Set up once: (cd scripts/js && npm ci)

import { open, readFile } from "node:fs/promises";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";

const DECODED = new Set(["probmot.Tracks3D", "foxglove.SceneUpdate"]);

function fail(msg) {
  process.stderr.write(`check_tracked.mjs: ${msg}\n`);
  process.exit(1);
}

/** The protobufjs type of a schema record, from its embedded FileDescriptorSet. */
function protobufType(schema) {
  if (schema.encoding !== "protobuf") {
    fail(`schema ${schema.name}: encoding ${schema.encoding}, expected protobuf`);
  }
  const set = descriptor.FileDescriptorSet.decode(schema.data);
  const root = protobuf.Root.fromDescriptor(set);
  root.resolveAll();
  return root.lookupType(schema.name);
}

/** A google.protobuf.Timestamp (seconds as a decimal string) in nanoseconds, as a string. */
function ns(ts) {
  return ts ? (BigInt(ts.seconds) * 1_000_000_000n + BigInt(ts.nanos)).toString() : null;
}

/** The summary of one decoded message (see the header comment). */
function frameOf(schemaName, topic, logTime, obj) {
  if (schemaName === "probmot.Tracks3D") {
    return {
      topic,
      log_time: logTime.toString(),
      stamp: String(obj.stamp),
      frame_id: obj.frame_id,
      ids: obj.tracks.map((t) => String(t.id)),
      centers: obj.tracks.map((t) => [t.center.x, t.center.y, t.center.z]),
      deletions: [],
    };
  }
  const stamps = new Set(obj.entities.map((e) => ns(e.timestamp)));
  const frameIds = new Set(obj.entities.map((e) => e.frame_id));
  return {
    topic,
    log_time: logTime.toString(),
    stamp: stamps.size === 1 ? [...stamps][0] : null,
    frame_id: frameIds.size === 1 ? [...frameIds][0] : null,
    ids: obj.entities.map((e) => e.id),
    centers: obj.entities.map((e) => {
      const p = e.cubes[0].pose.position;
      return [p.x, p.y, p.z];
    }),
    deletions: obj.deletions.map((d) => d.id),
  };
}

const toObjectOptions = { longs: String, defaults: true };

async function indexed(path, decompressHandlers) {
  const handle = await open(path, "r");
  try {
    const readable = {
      size: async () => BigInt((await handle.stat()).size),
      read: async (offset, length) => {
        const buf = new Uint8Array(Number(length));
        await handle.read(buf, 0, buf.length, Number(offset));
        return buf;
      },
    };
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    const types = new Map();
    const channels = [];
    for (const [id, ch] of reader.channelsById) {
      const schema = reader.schemasById.get(ch.schemaId);
      const name = schema ? schema.name : "";
      if (DECODED.has(name)) types.set(id, { name, type: protobufType(schema) });
      const messages = reader.statistics?.channelMessageCounts.get(id) ?? 0n;
      channels.push({ topic: ch.topic, schema: name, messages: Number(messages) });
    }
    const frames = [];
    let count = 0;
    for await (const m of reader.readMessages()) {
      count += 1;
      const t = types.get(m.channelId);
      if (!t) continue;
      const topic = reader.channelsById.get(m.channelId).topic;
      let obj;
      try {
        obj = t.type.toObject(t.type.decode(m.data), toObjectOptions);
      } catch (e) {
        fail(`${topic} message at log_time ${m.logTime}: ${e.message}`);
      }
      frames.push(frameOf(t.name, topic, m.logTime, obj));
    }
    return { channels, frames, count };
  } finally {
    await handle.close();
  }
}

/** File order as a pipe sees it: number of messages and how often log_time went back. */
async function streamed(path, decompressHandlers) {
  const reader = new McapStreamReader({ decompressHandlers });
  reader.append(await readFile(path));
  let count = 0;
  let backwards = 0;
  let last = -1n;
  for (let rec; (rec = reader.nextRecord()); ) {
    if (rec.type !== "Message") continue;
    count += 1;
    if (rec.logTime < last) backwards += 1;
    last = rec.logTime;
  }
  if (!reader.done()) fail("the stream reader did not reach the end of the file");
  return { count, backwards };
}

async function main() {
  const path = process.argv[2];
  if (!path || process.argv.length > 3) fail("usage: node check_tracked.mjs FILE.mcap");
  const decompressHandlers = await loadDecompressHandlers();
  const a = await indexed(path, decompressHandlers);
  const s = await streamed(path, decompressHandlers);
  if (a.count !== s.count) {
    fail(`indexed reader saw ${a.count} messages, stream reader ${s.count}`);
  }
  const out = {
    channels: a.channels,
    indexed_messages: a.count,
    stream_messages: s.count,
    log_time_backwards: s.backwards,
    frames: a.frames,
  };
  process.stdout.write(`${JSON.stringify(out)}\n`);
}

main().catch((e) => fail(e.stack ?? String(e)));

// Writes the seed corpora of the mcap_reader and cdr_reader fuzz targets (fuzz/corpus/) with
// Foxglove's libraries, from 40 points of the real street scan: small MCAPs (chunks none, lz4,
// zstd; unchunked; without summary) and the CDR of a PointCloud2 (two layouts) and a TFMessage,
// each prefixed with the target's selector byte (0: PointCloud2, 1: TFMessage).
//   node write_fuzz_seeds.mjs <shared-data-dir> <fuzz/corpus>
import { McapWriter, TempBuffer } from "@mcap/core";
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import { schemaText, writerFor } from "./ros_msgs.mjs";

const [dataDir, corpus] = process.argv.slice(2);
const bin = fs.readFileSync(path.join(dataDir, "ouster_os1_128_street/velodyne/000000.bin"));
const xyzi = new Float32Array(bin.buffer.slice(bin.byteOffset, bin.byteOffset + 40 * 16));
const stamp = { sec: 1700000000, nanosec: 5 };
const F = (name, offset, datatype) => ({ name, offset, datatype, count: 1 });
const cloud = {
  header: { stamp, frame_id: "os_sensor" }, height: 1, width: 40,
  fields: [F("x", 0, 7), F("y", 4, 7), F("z", 8, 7), F("intensity", 12, 7)],
  is_bigendian: false, point_step: 16, row_step: 640, data: new Uint8Array(xyzi.buffer), is_dense: true,
};
const wide = new Uint8Array(40 * 24);
const view = new DataView(wide.buffer);
for (let k = 0; k < 40; ++k) for (let a = 0; a < 3; ++a) view.setFloat64(k * 24 + 8 * a, xyzi[4 * k + a], false);
const cloud64 = { ...cloud, height: 2, width: 20, fields: [F("x", 0, 8), F("y", 8, 8), F("z", 16, 8)],
  is_bigendian: true, point_step: 24, row_step: 480, data: wide };
const tf = { transforms: [
  { header: { stamp, frame_id: "map" }, child_frame_id: "odom", transform: { translation: { x: 1, y: 2, z: 0 }, rotation: { x: 0, y: 0, z: 0.1986693308, w: 0.9800665778 } } },
  { header: { stamp, frame_id: "odom" }, child_frame_id: "os_sensor", transform: { translation: { x: 0, y: 0, z: 2 }, rotation: { x: 0, y: 0, z: 0, w: 1 } } },
] };
const pc2 = writerFor("sensor_msgs/msg/PointCloud2"), tfw = writerFor("tf2_msgs/msg/TFMessage");
const write = (target, name, bytes) => {
  fs.mkdirSync(path.join(corpus, target), { recursive: true });
  fs.writeFileSync(path.join(corpus, target, name), bytes);
};
const tagged = (tag, bytes) => Buffer.concat([Buffer.from([tag]), bytes]);
write("cdr_reader", "pointcloud2_float32", tagged(0, pc2.writeMessage(cloud)));
write("cdr_reader", "pointcloud2_float64_be", tagged(0, pc2.writeMessage(cloud64)));
write("cdr_reader", "tfmessage_chain", tagged(1, tfw.writeMessage(tf)));

const compress = (tool, name) => (bytes) => ({ compression: name,
  compressedData: new Uint8Array(execFileSync(tool, ["-c", "-q"], { input: bytes })) });
const variants = {
  none: { useChunks: true },
  lz4: { useChunks: true, compressChunk: compress("lz4", "lz4") },
  zstd: { useChunks: true, compressChunk: compress("zstd", "zstd") },
  unchunked: { useChunks: false },
  no_summary: { useChunks: true, useStatistics: false, useSummaryOffsets: false, useChunkIndex: false,
    useMessageIndex: false, repeatSchemas: false, repeatChannels: false },
};
for (const [name, options] of Object.entries(variants)) {
  const buffer = new TempBuffer();
  const w = new McapWriter({ writable: buffer, ...options });
  await w.start({ profile: "ros2", library: "seed" });
  const enc = new TextEncoder();
  const s1 = await w.registerSchema({ name: "sensor_msgs/msg/PointCloud2", encoding: "ros2msg", data: enc.encode(schemaText("sensor_msgs/msg/PointCloud2")) });
  const s2 = await w.registerSchema({ name: "tf2_msgs/msg/TFMessage", encoding: "ros2msg", data: enc.encode(schemaText("tf2_msgs/msg/TFMessage")) });
  const c1 = await w.registerChannel({ topic: "/points", schemaId: s1, messageEncoding: "cdr", metadata: new Map() });
  const c2 = await w.registerChannel({ topic: "/tf", schemaId: s2, messageEncoding: "cdr", metadata: new Map() });
  const t = 1700000000000000005n;
  await w.addMessage({ channelId: c2, sequence: 0, logTime: t, publishTime: t, data: tfw.writeMessage(tf) });
  await w.addMessage({ channelId: c1, sequence: 0, logTime: t, publishTime: t, data: pc2.writeMessage(cloud) });
  await w.end();
  write("mcap_reader", `street40_${name}.mcap`, buffer.get());
}

// Writes the ROS 2 recordings the C++ reader tests read, with Foxglove's own libraries: MCAP by
// @mcap/core, messages serialized by @foxglove/rosmsg2-serialization, from the real Ouster
// street scans of the shared data (KITTI-like: velodyne/*.bin in the sensor frame, poses.txt).
//   node write_recordings.mjs <shared-data-dir> <out-dir>
// Each recording varies what a reader must cope with (docs/ros2.md lists them):
//   direct_none.mcap   x,y,z,intensity float32 (the .bin layout), chunks uncompressed, full
//                      summary, /tf map -> os_sensor at each cloud's stamp
//   chain_lz4.mcap     x,y,z float64 big-endian at offsets 8/16/24 in a 40-byte point,
//                      organized 2 rows with row padding and a NaN point, lz4 chunks; TF chain
//                      map -> odom (/tf_static), odom -> base_link (/tf, samples 20 ms before
//                      and 30 ms after each cloud: interpolated), base_link -> os_sensor
//                      (/tf_static)
//   partial_zstd.mcap  the .bin layout, zstd chunks, no summary or indexes; TF only for the
//                      first two clouds (the third is skipped)
//   no_z.mcap          a cloud without a z field (refused)
//   unchunked.mcap     the .bin layout, no chunks at all
//   street.bag         a ROS 1 bag (ros1_bag.mjs; messages by @foxglove/rosmsg-serialization):
//                      the .bin layout, tf2_msgs/TFMessage on /tf map -> os_sensor
import { McapWriter, TempBuffer } from "@mcap/core";
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import { Ros1BagWriter } from "./ros1_bag.mjs";
import { schemaText, writerFor } from "./ros_msgs.mjs";

// Or one recording of any KITTI-like sequence (the benchmark's): the .bin layout, direct TF.
//   node write_recordings.mjs --sequence <sequence-dir> <out.mcap> <none|lz4|zstd>
const sequenceMode = process.argv[2] === "--sequence";
const [dataDir, outDir, compressionName] = process.argv.slice(sequenceMode ? 3 : 2);
if (!dataDir || !outDir) {
  console.error("usage: node write_recordings.mjs <shared-data-dir> <out-dir>\n" +
    "       node write_recordings.mjs --sequence <sequence-dir> <out.mcap> <none|lz4|zstd>");
  process.exit(2);
}
const seqDir = sequenceMode ? dataDir : path.join(dataDir, "ouster_os1_128_street");
const T0 = 1700000000n * 1000000000n; // first cloud's stamp, ns
const PERIOD = 100000000n;            // 10 Hz

// The KITTI-like scans: points {x,y,z,i} float32 and row-major 3x4 poses.
function readScans(dir) {
  const poses = fs.readFileSync(path.join(dir, "poses.txt"), "utf8").trim().split("\n")
    .map((l) => l.trim().split(/\s+/).map(Number));
  const files = fs.readdirSync(path.join(dir, "velodyne")).filter((f) => f.endsWith(".bin")).sort();
  return files.map((f, k) => {
    const buf = fs.readFileSync(path.join(dir, "velodyne", f));
    return { xyzi: new Float32Array(buf.buffer, buf.byteOffset, buf.length / 4), pose: poses[k] };
  });
}

// Rotation matrix (row-major 3x3 inside a 3x4) to a unit quaternion (Shepperd's method).
function quat(p) {
  const m = (r, c) => p[4 * r + c];
  const tr = m(0, 0) + m(1, 1) + m(2, 2);
  let x, y, z, w;
  if (tr > 0) {
    const s = Math.sqrt(tr + 1) * 2;
    w = s / 4; x = (m(2, 1) - m(1, 2)) / s; y = (m(0, 2) - m(2, 0)) / s; z = (m(1, 0) - m(0, 1)) / s;
  } else if (m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2)) {
    const s = Math.sqrt(1 + m(0, 0) - m(1, 1) - m(2, 2)) * 2;
    w = (m(2, 1) - m(1, 2)) / s; x = s / 4; y = (m(0, 1) + m(1, 0)) / s; z = (m(0, 2) + m(2, 0)) / s;
  } else if (m(1, 1) > m(2, 2)) {
    const s = Math.sqrt(1 + m(1, 1) - m(0, 0) - m(2, 2)) * 2;
    w = (m(0, 2) - m(2, 0)) / s; x = (m(0, 1) + m(1, 0)) / s; y = s / 4; z = (m(1, 2) + m(2, 1)) / s;
  } else {
    const s = Math.sqrt(1 + m(2, 2) - m(0, 0) - m(1, 1)) * 2;
    w = (m(1, 0) - m(0, 1)) / s; x = (m(0, 2) + m(2, 0)) / s; y = (m(1, 2) + m(2, 1)) / s; z = s / 4;
  }
  const n = Math.hypot(x, y, z, w);
  return { x: x / n, y: y / n, z: z / n, w: w / n };
}

const qmul = (a, b) => ({
  w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
  x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
  y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
  z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
});
const qz = (angle) => ({ x: 0, y: 0, z: Math.sin(angle / 2), w: Math.cos(angle / 2) });
const qrot = (q, v) => {
  const r = qmul(qmul(q, { w: 0, x: v.x, y: v.y, z: v.z }), { w: q.w, x: -q.x, y: -q.y, z: -q.z });
  return { x: r.x, y: r.y, z: r.z };
};
const qinv = (q) => ({ x: -q.x, y: -q.y, z: -q.z, w: q.w });

const stamp = (ns) => ({ sec: Number(ns / 1000000000n), nanosec: Number(ns % 1000000000n) });
const tfm = (ns, parent, child, t, q) => ({
  header: { stamp: stamp(ns), frame_id: parent }, child_frame_id: child,
  transform: { translation: t, rotation: q },
});

// Point layouts: each returns {fields, point_step, row_step, height, width, data, is_bigendian}.
const FIELD = (name, offset, datatype) => ({ name, offset, datatype, count: 1 });
function layoutBin(xyzi, { dropZ = false } = {}) {
  const n = xyzi.length / 4;
  const fields = [FIELD("x", 0, 7), FIELD("y", 4, 7), FIELD("intensity", 12, 7)];
  if (!dropZ) fields.splice(2, 0, FIELD("z", 8, 7));
  const data = new Uint8Array(xyzi.buffer.slice(xyzi.byteOffset, xyzi.byteOffset + n * 16));
  return { fields, point_step: 16, row_step: 16 * n, height: 1, width: n, data, is_bigendian: false };
}
function layoutWideBigEndian(xyzi) {
  const n = xyzi.length / 4;
  const width = Math.ceil((n + 1) / 2); // one NaN point, then padding with NaN to fill 2 rows
  const step = 40, rowStep = width * step + 24;
  const data = new Uint8Array(rowStep * 2);
  const view = new DataView(data.buffer);
  for (let k = 0; k < 2 * width; ++k) {
    const at = Math.floor(k / width) * rowStep + (k % width) * step;
    const src = k - 1; // point 0 is NaN
    const ok = src >= 0 && src < n;
    view.setUint32(at, k, false); // "ring"
    view.setFloat64(at + 8, ok ? xyzi[4 * src] : NaN, false);
    view.setFloat64(at + 16, ok ? xyzi[4 * src + 1] : NaN, false);
    view.setFloat64(at + 24, ok ? xyzi[4 * src + 2] : NaN, false);
    view.setFloat32(at + 32, ok ? xyzi[4 * src + 3] : 0, false);
  }
  const fields = [FIELD("ring", 0, 6), FIELD("x", 8, 8), FIELD("y", 16, 8), FIELD("z", 24, 8),
    FIELD("intensity", 32, 7)];
  return { fields, point_step: step, row_step: rowStep, height: 2, width, data, is_bigendian: true };
}

function cloudMessage(ns, frame, layout) {
  return { header: { stamp: stamp(ns), frame_id: frame }, ...layout, is_dense: false };
}

const lz4 = (bytes) => ({
  compression: "lz4",
  compressedData: new Uint8Array(execFileSync("lz4", ["-c", "-q", "-z"], { input: bytes, maxBuffer: 1 << 30 })),
});
const zstd = (bytes) => ({
  compression: "zstd",
  compressedData: new Uint8Array(execFileSync("zstd", ["-c", "-q"], { input: bytes, maxBuffer: 1 << 30 })),
});

async function writeMcap(file, options, fill) {  // file: relative to outDir, or absolute
  const buffer = new TempBuffer();
  const writer = new McapWriter({ writable: buffer, ...options });
  await writer.start({ profile: "ros2", library: "@mcap/core (bgkmap tests)" });
  const channels = {};
  const channel = async (topic, type) => {
    if (!channels[topic]) {
      const schemaId = await writer.registerSchema({
        name: type, encoding: "ros2msg", data: new TextEncoder().encode(schemaText(type)),
      });
      channels[topic] = { id: await writer.registerChannel({ topic, schemaId, messageEncoding: "cdr", metadata: new Map() }), writer: writerFor(type), seq: 0 };
    }
    return channels[topic];
  };
  const add = async (topic, type, ns, message) => {
    const c = await channel(topic, type);
    await writer.addMessage({ channelId: c.id, sequence: c.seq++, logTime: ns, publishTime: ns,
      data: c.writer.writeMessage(message) });
  };
  await fill(add);
  await writer.end();
  fs.writeFileSync(path.resolve(outDir, file), buffer.get());
}

const PC2 = "sensor_msgs/msg/PointCloud2", TF = "tf2_msgs/msg/TFMessage";
const translation = (p) => ({ x: p[3], y: p[7], z: p[11] });

// /tf map -> os_sensor at each cloud's stamp, then the cloud.
async function directScans(add, scans, layout, tfCount = scans.length) {
  for (let k = 0; k < scans.length; ++k) {
    const ns = T0 + BigInt(k) * PERIOD;
    if (k < tfCount) {
      await add("/tf", TF, ns, { transforms: [tfm(ns, "map", "os_sensor", translation(scans[k].pose), quat(scans[k].pose))] });
    }
    await add("/points", PC2, ns, cloudMessage(ns, "os_sensor", layout(scans[k].xyzi)));
  }
}

// map -> odom and base_link -> os_sensor static; odom -> base_link dynamic, sampled 20 ms before
// and 30 ms after each cloud so that interpolation at the cloud's stamp gives its pose.
async function chainScans(add, scans) {
  const odom = { t: { x: 1.5, y: -2.0, z: 0.1 }, q: qz(0.3) };
  const mount = { t: { x: 0.2, y: 0.0, z: 1.2 }, q: qz(-0.1) };
  const ns0 = T0 - PERIOD;
  await add("/tf_static", TF, ns0, { transforms: [tfm(ns0, "map", "odom", odom.t, odom.q),
    tfm(ns0, "base_link", "os_sensor", mount.t, mount.q)] });
  const spin = 0.5, vel = { x: 2.0, y: -1.0, z: 0.2 }; // rad/s and m/s around each pose
  for (let k = 0; k < scans.length; ++k) {
    const ns = T0 + BigInt(k) * PERIOD;
    // T_odom_base = T_map_odom^-1 * T_map_sensor * T_base_sensor^-1
    const qSensor = quat(scans[k].pose), tSensor = translation(scans[k].pose);
    const qBase = qmul(qmul(qinv(odom.q), qSensor), qinv(mount.q));
    const tMapBase = (() => {
      const m = qrot(qmul(qSensor, qinv(mount.q)), mount.t);
      return { x: tSensor.x - m.x, y: tSensor.y - m.y, z: tSensor.z - m.z };
    })();
    const d = { x: tMapBase.x - odom.t.x, y: tMapBase.y - odom.t.y, z: tMapBase.z - odom.t.z };
    const tBase = qrot(qinv(odom.q), d);
    for (const dt of [-0.02, 0.03]) {
      const at = ns + BigInt(Math.round(dt * 1e9));
      const t = { x: tBase.x + vel.x * dt, y: tBase.y + vel.y * dt, z: tBase.z + vel.z * dt };
      await add("/tf", TF, at, { transforms: [tfm(at, "odom", "base_link", t, qmul(qBase, qz(spin * dt)))] });
    }
    await add("/points", PC2, ns, cloudMessage(ns, "os_sensor", layoutWideBigEndian(scans[k].xyzi)));
  }
}

const scans = readScans(seqDir);
if (sequenceMode) {
  const compressChunk = { none: undefined, lz4, zstd }[compressionName];
  await writeMcap(path.resolve(outDir), { useChunks: true, chunkSize: 1 << 20, compressChunk },
    (add) => directScans(add, scans, layoutBin));
  console.log(`wrote ${scans.length} scans to ${outDir}`);
  process.exit(0);
}
fs.mkdirSync(outDir, { recursive: true });
const full = { useChunks: true, chunkSize: 1 << 20 };
const bare = { useChunks: true, useStatistics: false, useSummaryOffsets: false, useChunkIndex: false,
  useMessageIndex: false, useAttachmentIndex: false, useMetadataIndex: false, repeatSchemas: false,
  repeatChannels: false };
await writeMcap("direct_none.mcap", full, (add) => directScans(add, scans, layoutBin));
await writeMcap("chain_lz4.mcap", { ...full, compressChunk: lz4 }, (add) => chainScans(add, scans));
await writeMcap("partial_zstd.mcap", { ...bare, compressChunk: zstd },
  (add) => directScans(add, scans, layoutBin, 2));
await writeMcap("no_z.mcap", full, (add) => directScans(add, scans.slice(0, 1), (x) => layoutBin(x, { dropZ: true })));
await writeMcap("unchunked.mcap", { useChunks: false }, (add) => directScans(add, scans, layoutBin));
// ROS 1: the header has a seq, time is {sec, nsec}.
const bag = new Ros1BagWriter();
for (let k = 0; k < scans.length; ++k) {
  const ns = T0 + BigInt(k) * PERIOD;
  const t = { sec: Number(ns / 1000000000n), nsec: Number(ns % 1000000000n) };
  bag.add("/tf", "tf2_msgs/TFMessage", ns, { transforms: [{ header: { seq: k, stamp: t, frame_id: "map" },
    child_frame_id: "os_sensor", transform: { translation: translation(scans[k].pose), rotation: quat(scans[k].pose) } }] });
  bag.add("/points", "sensor_msgs/PointCloud2", ns, { header: { seq: k, stamp: t, frame_id: "os_sensor" },
    ...layoutBin(scans[k].xyzi), is_dense: true });
}
fs.writeFileSync(path.join(outDir, "street.bag"), bag.bytes());
console.log(`wrote 6 recordings of ${scans.length} scans to ${outDir}`);

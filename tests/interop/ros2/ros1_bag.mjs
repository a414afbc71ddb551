// A ROS 1 bag writer (format 2.0, http://wiki.ros.org/Bags/Format/2.0: one uncompressed chunk,
// its index data, then the connection and chunk info records the bag header points to), and the
// ROS 1 message definitions of the clouds and TF, serialized by @foxglove/rosmsg-serialization.
// Only for writing test recordings: the reader under test is ROS's own rosbag_storage.
import { parse, md5 } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg-serialization";

const SEP = "\n================================================================================\nMSG: ";
const HEADER = "std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id";
const DEFS = {
  "sensor_msgs/PointCloud2": "Header header\nuint32 height\nuint32 width\nPointField[] fields\n" +
    "bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense" + SEP + HEADER +
    SEP + "sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\n" +
    "uint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\n" +
    "uint8 datatype\nuint32 count",
  "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms" + SEP +
    "geometry_msgs/TransformStamped\nHeader header\nstring child_frame_id\nTransform transform" + SEP + HEADER +
    SEP + "geometry_msgs/Transform\nVector3 translation\nQuaternion rotation" +
    SEP + "geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z" +
    SEP + "geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w",
};

const u32 = (v) => { const b = Buffer.alloc(4); b.writeUInt32LE(v); return b; };
const u64 = (v) => { const b = Buffer.alloc(8); b.writeBigUInt64LE(BigInt(v)); return b; };
const time = (ns) => Buffer.concat([u32(Number(ns / 1000000000n)), u32(Number(ns % 1000000000n))]);

// A record: its header's fields (name=value, each length-prefixed), then its data.
function record(fields, data) {
  const parts = Object.entries(fields).map(([k, v]) => {
    const f = Buffer.concat([Buffer.from(k + "="), Buffer.isBuffer(v) ? v : Buffer.from(v)]);
    return Buffer.concat([u32(f.length), f]);
  });
  const header = Buffer.concat(parts);
  return Buffer.concat([u32(header.length), header, u32(data.length), data]);
}
const op = (n) => Buffer.from([n]);

export class Ros1BagWriter {
  #connections = new Map(); // topic -> {id, type, writer}
  #messages = []; // {conn, ns, data}

  add(topic, type, ns, message) {
    if (!this.#connections.has(topic)) {
      const definitions = parse(DEFS[type]);
      this.#connections.set(topic, { id: this.#connections.size, type, writer: new MessageWriter(definitions),
        md5: md5(definitions), text: DEFS[type] });
    }
    const c = this.#connections.get(topic);
    this.#messages.push({ conn: c.id, ns, data: Buffer.from(c.writer.writeMessage(message)) });
  }

  bytes() {
    // The connection record's data is the connection header: fields without the outer lengths.
    const connData = [...this.#connections.entries()].map(([topic, c]) => {
      const inner = record({ topic, type: c.type, md5sum: c.md5, message_definition: c.text }, Buffer.alloc(0));
      return record({ op: op(0x07), conn: u32(c.id), topic }, inner.subarray(4, inner.length - 4));
    });
    const chunkParts = [...connData], offsets = new Map();
    let at = connData.reduce((n, b) => n + b.length, 0);
    for (const m of this.#messages) {
      if (!offsets.has(m.conn)) offsets.set(m.conn, []);
      offsets.get(m.conn).push({ ns: m.ns, at });
      const r = record({ op: op(0x02), conn: u32(m.conn), time: time(m.ns) }, m.data);
      chunkParts.push(r);
      at += r.length;
    }
    const chunkData = Buffer.concat(chunkParts);
    const magic = Buffer.from("#ROSBAG V2.0\n");
    const headerSize = 4096;
    const chunkPos = magic.length + headerSize;
    const chunk = record({ op: op(0x05), compression: "none", size: u32(chunkData.length) }, chunkData);
    const indexes = [...offsets.entries()].map(([conn, list]) => record(
      { op: op(0x04), ver: u32(1), conn: u32(conn), count: u32(list.length) },
      Buffer.concat(list.map((e) => Buffer.concat([time(e.ns), u32(e.at)])))));
    const times = this.#messages.map((m) => m.ns);
    const start = times.reduce((a, b) => (a < b ? a : b)), end = times.reduce((a, b) => (a > b ? a : b));
    const info = record({ op: op(0x06), ver: u32(1), chunk_pos: u64(chunkPos), start_time: time(start),
      end_time: time(end), count: u32(offsets.size) },
    Buffer.concat([...offsets.entries()].map(([conn, list]) => Buffer.concat([u32(conn), u32(list.length)]))));
    const indexPos = chunkPos + chunk.length + indexes.reduce((n, b) => n + b.length, 0);
    // The bag header record, padded with spaces to 4096 bytes so it can be rewritten in place.
    const fields = { op: op(0x03), index_pos: u64(indexPos), conn_count: u32(this.#connections.size), chunk_count: u32(1) };
    const bare = record(fields, Buffer.alloc(0));
    const header = record(fields, Buffer.alloc(headerSize - bare.length, 0x20));
    return Buffer.concat([magic, header, chunk, ...indexes, ...connData, info]);
  }
}

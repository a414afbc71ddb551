// Maps out as ROS messages (issue 26, item 2), checked with Foxglove's own code: bgkmapd is fed a
// recording written by @mcap/core (write_recordings.mjs, the real street scans), `bgkmap query
// --out X.mcap` and `--out map.yaml` write the region, and @mcap/core reads the MCAP back (the
// indexed reader through the summary, and the streaming reader), @foxglove/rosmsg2-serialization
// decodes every message with the schema the file carries. The cells are checked against
// `bgkmap points` at their metric centres, so grid_map's and Nav2's index conventions are
// tested against the server's own answer, not against our writer.
// Env: BGKMAPD, BGKMAP_CLI, BGKMAP_SHARED_DATA (set by CTest: tests/interop/CMakeLists.txt).
import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { spawn, execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { McapIndexedReader, McapStreamReader, TempBuffer } from "@mcap/core";
import * as zstd from "@foxglove/wasm-zstd";
import { readerForSchema } from "./ros_msgs.mjs";

const here = path.dirname(fileURLToPath(import.meta.url));
const { BGKMAPD: bgkmapd, BGKMAP_CLI: cli, BGKMAP_SHARED_DATA: data } = process.env;
const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "bgkmap-ros2-out-"));
const ROBOT_RADIUS = 0.6;
let server, grpc;

async function startServer() {
  server = spawn(bgkmapd, ["--listen", "127.0.0.1:0"], { stdio: ["ignore", "pipe", "pipe"] });
  process.on("exit", () => { if (server.exitCode === null) server.kill("SIGKILL"); });
  let log = "";
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error("bgkmapd did not start:\n" + log)), 30000);
    const onData = (chunk) => {
      log += chunk;
      const m = /event=listening .*port=(\d+)/.exec(log);
      if (m) { clearTimeout(timer); resolve(`127.0.0.1:${m[1]}`); }
    };
    server.stdout.on("data", onData);
    server.stderr.on("data", onData);
    server.on("exit", (code) => reject(new Error(`bgkmapd exited ${code}:\n${log}`)));
  });
}

const run = (...args) => execFileSync(cli, [...args, "--server", grpc], { encoding: "utf8" });

before(async () => {
  execFileSync("node", [path.join(here, "write_recordings.mjs"), data, tmp]);
  grpc = await startServer();
  // The lz4 recording with the TF chain, streamed as a robot would be.
  run("insert", path.join(tmp, "chain_lz4.mcap"), "--topic", "/points", "--robot", "r1");
  run("query", "--bbox", "-12,-10,18,10", "--out", path.join(tmp, "map.mcap"),
    "--robot-radius", String(ROBOT_RADIUS));
  run("query", "--bbox", "-12,-10,18,10", "--out", path.join(tmp, "map.yaml"));
  await zstd.isLoaded;
});

after(() => {
  if (server && server.exitCode === null) server.kill("SIGTERM");
  fs.rmSync(tmp, { recursive: true, force: true });
});

const decompressHandlers = { zstd: (buf, size) => zstd.decompress(buf, Number(size)) };

// Every message of the file, decoded with the schema it carries: {topic: {schema, message}}.
async function readIndexed(bytes) {
  const reader = await McapIndexedReader.Initialize({ readable: new TempBuffer(bytes), decompressHandlers });
  const out = {};
  for await (const m of reader.readMessages()) {
    const channel = reader.channelsById.get(m.channelId);
    const schema = reader.schemasById.get(channel.schemaId);
    out[channel.topic] = { schema: schema.name, message: readerForSchema(schema.data).readMessage(m.data) };
  }
  return out;
}

function readStreamed(bytes) {
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(bytes);
  const schemas = new Map(), channels = new Map(), out = {};
  for (let r; (r = reader.nextRecord()); ) {
    if (r.type === "Schema") schemas.set(r.id, r);
    if (r.type === "Channel") channels.set(r.id, r);
    if (r.type === "Message") {
      const c = channels.get(r.channelId), s = schemas.get(c.schemaId);
      out[c.topic] = { schema: s.name, message: readerForSchema(s.data).readMessage(r.data) };
    }
  }
  assert.ok(reader.done(), "the streaming reader reached the end magic");
  return out;
}

// `bgkmap points` at metric positions: [{x, y, elevation, ..., state}].
function points(xy) {
  const out = [];
  for (let i = 0; i < xy.length; i += 200) {
    const args = xy.slice(i, i + 200).map(([x, y]) => `${x},${y}`);
    out.push(...JSON.parse(run("points", ...args)).points);
  }
  return out;
}

const every = (n, k) => Array.from({ length: Math.ceil(n / k) }, (_, i) => i * k);

test("the MCAP reads back with @mcap/core, indexed and streamed, and decodes with the file's schemas", async () => {
  const bytes = fs.readFileSync(path.join(tmp, "map.mcap"));
  const indexed = await readIndexed(bytes);
  const streamed = readStreamed(bytes);
  assert.deepEqual(Object.keys(indexed).sort(), ["/costmap", "/grid_map", "/map"]);
  assert.equal(indexed["/grid_map"].schema, "grid_map_msgs/msg/GridMap");
  assert.equal(indexed["/map"].schema, "nav_msgs/msg/OccupancyGrid");
  assert.equal(indexed["/costmap"].schema, "nav2_msgs/msg/Costmap");
  assert.deepEqual(streamed["/map"].message.data, indexed["/map"].message.data);
  assert.deepEqual(streamed["/grid_map"].message.info, indexed["/grid_map"].message.info);
});

test("GridMap: grid_map's layers, storage order and index conventions, cell by cell against bgkmap points", async () => {
  const { message: g } = (await readIndexed(fs.readFileSync(path.join(tmp, "map.mcap"))))["/grid_map"];
  assert.equal(g.header.frame_id, "map");
  assert.deepEqual(g.layers, ["elevation", "elevation_variance", "traversability", "traversability_variance", "state",
    "disagreement", "block_reason"]);
  assert.deepEqual(g.basic_layers, ["elevation"]);
  const res = g.info.resolution;
  const sizeX = Math.round(g.info.length_x / res), sizeY = Math.round(g.info.length_y / res);
  for (const d of g.data) {
    assert.deepEqual(d.layout.dim.map((x) => [x.label, x.size, x.stride]),
      [["column_index", sizeY, sizeX * sizeY], ["row_index", sizeX, sizeX]]);
    assert.equal(d.data.length, sizeX * sizeY);
  }
  // Cell (i, j) sits at pose + (length/2 - (index + 0.5) * res): index 0 is the largest x, y.
  const cells = [];
  for (const j of every(sizeY, 7)) for (const i of every(sizeX, 11)) cells.push([i, j]);
  const at = cells.map(([i, j]) => [g.info.pose.position.x + g.info.length_x / 2 - (i + 0.5) * res,
    g.info.pose.position.y + g.info.length_y / 2 - (j + 0.5) * res]);
  const truth = points(at);
  let known = 0;
  cells.forEach(([i, j], k) => {
    for (const [l, name] of g.layers.entries()) {
      const v = g.data[l].data[j * sizeX + i];
      const want = truth[k][name];
      if (name === "state") continue; // unknown is NaN here, 0 in `points`
      if (want === null) assert.ok(Number.isNaN(v), `${name} (${i},${j}) should be unknown, is ${v}`);
      else assert.equal(v, Math.fround(want), `${name} at (${i},${j})`);
    }
    if (truth[k].elevation !== null) ++known;
  });
  assert.ok(known > 100, `${known} known cells checked`);
});

// Nav2's scales from the state and traversability `bgkmap points` reports at each cell centre.
const occupancyOf = (p) => p.state === 2 ? 100
  : p.state === 1 ? Math.min(99, Math.round(100 * (p.traversability ?? 0))) : -1;

test("OccupancyGrid and Nav2 Costmap: row-major from the south-west origin, -1/0..100 and 255/254/253/0..252", async () => {
  const all = await readIndexed(fs.readFileSync(path.join(tmp, "map.mcap")));
  const occ = all["/map"].message, cost = all["/costmap"].message;
  const { width, height, resolution: res, origin } = occ.info;
  assert.equal(cost.metadata.size_x, width);
  assert.equal(cost.metadata.size_y, height);
  assert.equal(occ.data.length, width * height);
  const cells = [];
  for (const r of every(height, 5)) for (const c of every(width, 9)) cells.push([c, r]);
  const truth = points(cells.map(([c, r]) => [origin.position.x + (c + 0.5) * res, origin.position.y + (r + 0.5) * res]));
  const seen = { unknown: 0, free: 0, lethal: 0 };
  cells.forEach(([c, r], k) => {
    const want = occupancyOf(truth[k]);
    const o = occ.data[r * width + c], v = cost.data[r * width + c];
    assert.equal(o, want, `occupancy at (${c},${r}): ${JSON.stringify(truth[k])}`);
    if (want === -1) { assert.equal(v, 255); ++seen.unknown; }
    else if (want === 100) { assert.equal(v, 254); ++seen.lethal; }
    else { assert.ok(v === 253 || v === Math.round(252 * truth[k].traversability), `cost ${v} at (${c},${r})`); ++seen.free; }
  });
  assert.ok(seen.unknown > 0 && seen.free > 0 && seen.lethal > 0, JSON.stringify(seen));
  // Inscribed cells (253) are exactly the non-lethal known cells within the robot radius of a
  // lethal one.
  const reach = ROBOT_RADIUS / res, r = Math.floor(reach);
  let inscribed = 0;
  for (let i = 0; i < cost.data.length; ++i) {
    const v = cost.data[i];
    if (v === 254 || v === 255) continue;
    const x = i % width, y = Math.floor(i / width);
    let near = false;
    for (let dy = -r; dy <= r && !near; ++dy) {
      for (let dx = -r; dx <= r && !near; ++dx) {
        const nx = x + dx, ny = y + dy;
        near = nx >= 0 && ny >= 0 && nx < width && ny < height && dx * dx + dy * dy <= reach * reach &&
          cost.data[ny * width + nx] === 254;
      }
    }
    assert.equal(v === 253, near, `cell (${x},${y}) cost ${v}`);
    if (near) ++inscribed;
  }
  assert.ok(inscribed > 0);
});

test("Nav2 map_server YAML + PGM: trinary, rows north to south, the origin at the south-west corner", async () => {
  const yaml = fs.readFileSync(path.join(tmp, "map.yaml"), "utf8");
  const field = (k) => new RegExp(`^${k}: (.*)$`, "m").exec(yaml)[1];
  assert.equal(field("image"), "map.pgm");
  assert.equal(field("mode"), "trinary");
  const res = Number(field("resolution"));
  const [ox, oy] = JSON.parse(field("origin"));
  const pgm = fs.readFileSync(path.join(tmp, "map.pgm"));
  const header = /^P5\n(\d+) (\d+)\n255\n/.exec(pgm.toString("latin1", 0, 40));
  const [w, h] = [Number(header[1]), Number(header[2])];
  const pixels = pgm.subarray(header[0].length);
  assert.equal(pixels.length, w * h);
  const occ = (await readIndexed(fs.readFileSync(path.join(tmp, "map.mcap"))))["/map"].message;
  assert.equal(w, occ.info.width);
  assert.equal(h, occ.info.height);
  assert.equal(ox, occ.info.origin.position.x);
  assert.equal(oy, occ.info.origin.position.y);
  assert.equal(Math.fround(res), occ.info.resolution);
  // Image row 0 is the north edge: occupancy row height-1.
  for (let r = 0; r < h; ++r) {
    for (let c = 0; c < w; ++c) {
      const o = occ.data[(h - 1 - r) * w + c];
      const want = o === -1 ? 205 : o === 100 ? 0 : 254;
      assert.equal(pixels[r * w + c], want, `pixel (${c},${r})`);
    }
  }
});

// The ROS 2 message definitions the tests write and read, as rosbag2 stores them in an MCAP
// schema (encoding "ros2msg": the type, then each dependency after a line of '=' and "MSG: ").
// The fields are the public definitions of sensor_msgs, tf2_msgs, geometry_msgs, nav_msgs,
// grid_map_msgs and nav2_msgs; @foxglove/rosmsg parses them and
// @foxglove/rosmsg2-serialization serializes and deserializes messages with them.
import { parse } from "@foxglove/rosmsg";
import { MessageReader, MessageWriter } from "@foxglove/rosmsg2-serialization";

const SEP = "\n================================================================================\nMSG: ";

const DEPS = {
  "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
  "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
  "sensor_msgs/PointField":
    "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\n" +
    "uint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count",
  "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
  "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
  "geometry_msgs/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w",
  "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
  "geometry_msgs/Transform":
    "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
  "geometry_msgs/TransformStamped":
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform",
  "std_msgs/MultiArrayDimension": "string label\nuint32 size\nuint32 stride",
  "std_msgs/MultiArrayLayout": "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset",
  "std_msgs/Float32MultiArray": "std_msgs/MultiArrayLayout layout\nfloat32[] data",
  "grid_map_msgs/GridMapInfo": "float64 resolution\nfloat64 length_x\nfloat64 length_y\ngeometry_msgs/Pose pose",
  "nav_msgs/MapMetaData":
    "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n" +
    "geometry_msgs/Pose origin",
  "nav2_msgs/CostmapMetaData":
    "builtin_interfaces/Time map_load_time\nbuiltin_interfaces/Time update_time\n" +
    "string layer\nfloat32 resolution\nuint32 size_x\nuint32 size_y\ngeometry_msgs/Pose origin",
};

const TYPES = {
  "sensor_msgs/msg/PointCloud2": {
    text:
      "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\n" +
      "bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense",
    deps: ["std_msgs/Header", "builtin_interfaces/Time", "sensor_msgs/PointField"],
  },
  "tf2_msgs/msg/TFMessage": {
    text: "geometry_msgs/TransformStamped[] transforms",
    deps: ["geometry_msgs/TransformStamped", "std_msgs/Header", "builtin_interfaces/Time",
      "geometry_msgs/Transform", "geometry_msgs/Vector3", "geometry_msgs/Quaternion"],
  },
  "grid_map_msgs/msg/GridMap": {
    text:
      "std_msgs/Header header\ngrid_map_msgs/GridMapInfo info\nstring[] layers\n" +
      "string[] basic_layers\nstd_msgs/Float32MultiArray[] data\nuint16 outer_start_index\n" +
      "uint16 inner_start_index",
    deps: ["std_msgs/Header", "builtin_interfaces/Time", "grid_map_msgs/GridMapInfo",
      "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion",
      "std_msgs/Float32MultiArray", "std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension"],
  },
  "nav_msgs/msg/OccupancyGrid": {
    text: "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data",
    deps: ["std_msgs/Header", "builtin_interfaces/Time", "nav_msgs/MapMetaData",
      "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion"],
  },
  "nav2_msgs/msg/Costmap": {
    text: "std_msgs/Header header\nnav2_msgs/CostmapMetaData metadata\nuint8[] data",
    deps: ["std_msgs/Header", "builtin_interfaces/Time", "nav2_msgs/CostmapMetaData",
      "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion"],
  },
};

// The "ros2msg" schema text of a type, as rosbag2 writes it into an MCAP.
export function schemaText(type) {
  const t = TYPES[type];
  if (!t) throw new Error(`no definition for ${type}`);
  return t.text + t.deps.map((d) => SEP + d + "\n" + DEPS[d]).join("");
}

function definitions(text) {
  return parse(text, { ros2: true });
}

export function writerFor(type) {
  return new MessageWriter(definitions(schemaText(type)));
}

// A reader built from the schema text a file carries (not from ours): what a ROS 2 tool does.
export function readerForSchema(schemaData) {
  return new MessageReader(definitions(new TextDecoder().decode(schemaData)));
}

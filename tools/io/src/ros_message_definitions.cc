// The message definitions an MCAP carries as "ros2msg" schemas: the type's fields, then each
// type it uses after a line of '=' and "MSG: <type>", as rosbag2 writes them. The fields are the
// public definitions of nav_msgs, nav2_msgs, grid_map_msgs, std_msgs and geometry_msgs.
#include <map>
#include <string>
#include <vector>

#include "bgkmap/io/ros_map_messages.h"

namespace bgkmap::io {
namespace {

const std::map<std::string, std::string>& Dependencies() {
  static const std::map<std::string, std::string> deps = {
      {"builtin_interfaces/Time", "int32 sec\nuint32 nanosec"},
      {"std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"},
      {"geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z"},
      {"geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w"},
      {"geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation"},
      {"std_msgs/MultiArrayDimension", "string label\nuint32 size\nuint32 stride"},
      {"std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset"},
      {"std_msgs/Float32MultiArray", "std_msgs/MultiArrayLayout layout\nfloat32[] data"},
      {"grid_map_msgs/GridMapInfo",
       "float64 resolution\nfloat64 length_x\nfloat64 length_y\ngeometry_msgs/Pose pose"},
      {"nav_msgs/MapMetaData",
       "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n"
       "geometry_msgs/Pose origin"},
      {"nav2_msgs/CostmapMetaData",
       "builtin_interfaces/Time map_load_time\nbuiltin_interfaces/Time update_time\nstring "
       "layer\nfloat32 resolution\nuint32 size_x\nuint32 size_y\ngeometry_msgs/Pose origin"},
  };
  return deps;
}

struct Definition {
  std::string fields;
  std::vector<std::string> uses;
};

const std::map<std::string, Definition>& Types() {
  static const std::vector<std::string> pose = {"geometry_msgs/Pose", "geometry_msgs/Point",
                                                "geometry_msgs/Quaternion"};
  const auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  static const std::map<std::string, Definition> types = {
      {kGridMapSchema,
       {"std_msgs/Header header\ngrid_map_msgs/GridMapInfo info\nstring[] layers\n"
        "string[] basic_layers\nstd_msgs/Float32MultiArray[] data\nuint16 outer_start_index\n"
        "uint16 inner_start_index",
        with({"std_msgs/Header", "builtin_interfaces/Time", "grid_map_msgs/GridMapInfo"},
             with(pose, {"std_msgs/Float32MultiArray", "std_msgs/MultiArrayLayout",
                         "std_msgs/MultiArrayDimension"}))}},
      {kOccupancyGridSchema,
       {"std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data",
        with({"std_msgs/Header", "builtin_interfaces/Time", "nav_msgs/MapMetaData"}, pose)}},
      {kCostmapSchema,
       {"std_msgs/Header header\nnav2_msgs/CostmapMetaData metadata\nuint8[] data",
        with({"std_msgs/Header", "builtin_interfaces/Time", "nav2_msgs/CostmapMetaData"}, pose)}},
  };
  return types;
}

}  // namespace

std::string RosMapSchemaText(const std::string& type) {
  const Definition& d = Types().at(type);
  std::string text = d.fields;
  for (const std::string& dep : d.uses) {
    text += "\n" + std::string(80, '=') + "\nMSG: " + dep + "\n" + Dependencies().at(dep);
  }
  return text;
}

}  // namespace bgkmap::io

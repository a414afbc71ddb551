#include "bgkmap/io/ros1_bag.h"

#include <fmt/format.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <exception>
#include <filesystem>

namespace bgkmap::io {

std::string Ros2TypeName(const std::string& ros1_type) {
  if (ros1_type == "tf/tfMessage") return "tf2_msgs/msg/TFMessage";
  const size_t slash = ros1_type.find('/');
  if (slash == std::string::npos) return ros1_type;
  return ros1_type.substr(0, slash) + "/msg" + ros1_type.substr(slash);
}

Result<std::vector<RecordedMessage>> ReadRos1Bag(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return Status::IoError(path + ": no such file");
  std::vector<RecordedMessage> out;
  try {
    rosbag::Bag bag;
    bag.open(path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    for (const rosbag::MessageInstance& m : view) {
      RecordedMessage r{m.getTopic(), Ros2TypeName(m.getDataType()), "ros1", {}};
      r.data.resize(m.size());
      ros::serialization::OStream stream(reinterpret_cast<uint8_t*>(r.data.data()),
                                         static_cast<uint32_t>(r.data.size()));
      m.write(stream);
      out.push_back(std::move(r));
    }
  } catch (const std::exception& e) {
    // rosbag's BagException and ros::Exception (a short read, a bad header) both land here.
    return Status::DataLoss(fmt::format("{}: not a readable ROS 1 bag ({})", path, e.what()));
  }
  return out;
}

}  // namespace bgkmap::io

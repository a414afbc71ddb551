// ROS 1 `.bag` files (format 2.0: chunks uncompressed, bz2 or lz4), read with ROS's own
// rosbag_storage library as Debian packages it (librosbag-storage-dev). Messages come out in
// ROS 1's serialization (encoding "ros1"), their types renamed to ROS 2's names
// ("sensor_msgs/PointCloud2" -> "sensor_msgs/msg/PointCloud2", "tf/tfMessage" ->
// "tf2_msgs/msg/TFMessage"), so ros_recording.h treats both generations alike.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/io/ros_recording.h"

namespace bgkmap::io {

// Every message of the bag in time order; DataLoss naming the file for what the library refuses.
Result<std::vector<RecordedMessage>> ReadRos1Bag(const std::string& path);

// "pkg/Type" -> "pkg/msg/Type" (the TF message of the old tf package to tf2_msgs').
std::string Ros2TypeName(const std::string& ros1_type);

}  // namespace bgkmap::io

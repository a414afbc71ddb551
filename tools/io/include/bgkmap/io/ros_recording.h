// Posed scans out of a ROS 2 recording: the sensor_msgs/msg/PointCloud2 messages of one topic,
// each placed in the map frame through the recording's TF tree (tf2_msgs/msg/TFMessage on /tf
// and /tf_static) at the cloud's header stamp. A cloud whose frame has no transform in reach at
// its stamp is skipped and counted, never guessed.
//
// Recordings: an MCAP file (`.mcap`, rosbag2's default storage) or a rosbag2 SQLite file
// (`.db3`), or a rosbag2 folder (`metadata.yaml` beside its storage files), or a ROS 1 bag
// (`.bag`, ros1_bag.h: the same clouds and TF in ROS 1's serialization). The whole recording is
// read and every cloud decoded before anything is returned: a bad recording yields one error
// line and no scans.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

// One message of a recording, its bytes in the recording's serialization (CDR for ROS 2).
struct RecordedMessage {
  std::string topic;
  std::string type;      // e.g. "sensor_msgs/msg/PointCloud2"
  std::string encoding;  // "cdr" (ROS 2) or "ros1"
  std::string data;
};

struct RecordingOptions {
  std::string topic;              // the clouds' topic; empty: the recording's only cloud topic
  std::string map_frame = "map";  // the frame scans are posed in
};

struct RecordingScan {
  std::vector<Point3f> points;  // in the cloud's frame
  Pose pose;                    // T_map_cloudframe at the cloud's stamp
  int64_t stamp_ns = 0;         // the cloud's header stamp
};

struct RecordingScans {
  std::string topic;
  std::vector<RecordingScan> scans;  // in recording order
  size_t skipped = 0;                // clouds with no transform to the map frame
  std::string first_skip;            // why the first skipped cloud was skipped
};

// True if `path` names a recording this reader opens (by extension or a metadata.yaml inside).
bool IsRosRecording(const std::string& path);

// Reads the messages of a recording file or folder, in recording order.
Result<std::vector<RecordedMessage>> ReadRecordedMessages(const std::string& path);

// Decodes the clouds and the TF tree of `messages`. `name` prefixes errors. Unknown topics are
// ignored; the clouds' topic must hold PointCloud2 in CDR ("unknown schema" otherwise), and
// every TF message must decode.
Result<RecordingScans> ExtractScans(std::span<const RecordedMessage> messages,
                                    const RecordingOptions& options, const std::string& name);

}  // namespace bgkmap::io

#include "bgkmap/io/ros_recording.h"

#include <fmt/format.h>

#include <filesystem>
#include <set>

#include "bgkmap/io/mcap_reader.h"
#include "bgkmap/io/point_cloud2.h"
#include "bgkmap/io/ros1_bag.h"
#include "bgkmap/io/rosbag2_sqlite.h"
#include "bgkmap/io/tf_buffer.h"

namespace bgkmap::io {
namespace {

namespace fs = std::filesystem;

std::span<const uint8_t> AsBytes(const std::string& s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

RosEncoding EncodingOf(const RecordedMessage& m) {
  return m.encoding == "ros1" ? RosEncoding::kRos1 : RosEncoding::kCdr;
}

std::string Extension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

Result<std::vector<RecordedMessage>> FromMcap(const std::string& path) {
  Result<McapContents> mcap = ReadMcapFile(path);
  if (!mcap.ok()) return mcap.status();
  std::vector<RecordedMessage> out;
  out.reserve(mcap->messages.size());
  for (McapMessage& m : mcap->messages) {
    const McapChannel& channel = mcap->channels.at(m.channel_id);
    auto schema = mcap->schemas.find(channel.schema_id);
    out.push_back({channel.topic, schema == mcap->schemas.end() ? "" : schema->second.name,
                   channel.message_encoding, std::move(m.data)});
  }
  return out;
}

// The storage files of a rosbag2 folder, in name order (split bags: _0, _1, ...).
Result<std::vector<std::string>> BagFiles(const fs::path& dir) {
  if (!fs::exists(dir / "metadata.yaml")) {
    return Status::InvalidArgument(dir.string() + ": not a rosbag2 folder (no metadata.yaml)");
  }
  std::set<std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string ext = Extension(entry.path());
    if (ext == ".mcap" || ext == ".db3") files.insert(entry.path().string());
  }
  if (files.empty()) {
    return Status::InvalidArgument(dir.string() + ": rosbag2 folder without .mcap or .db3 files");
  }
  return std::vector<std::string>(files.begin(), files.end());
}

// The TF tree of the whole recording (transforms may arrive after the clouds they place).
Result<TfBuffer> CollectTransforms(std::span<const RecordedMessage> messages,
                                   const std::string& name) {
  TfBuffer tf;
  for (size_t i = 0; i < messages.size(); ++i) {
    const RecordedMessage& m = messages[i];
    const bool is_static = m.topic == "/tf_static";
    if ((m.topic != "/tf" && !is_static) || m.type != kTfMessageSchema) continue;
    Result<std::vector<StampedTransform>> ts = DecodeTfMessage(AsBytes(m.data), EncodingOf(m));
    Status s = ts.status();
    for (size_t k = 0; s.ok() && k < ts->size(); ++k) s = tf.Add((*ts)[k], is_static);
    if (!s.ok()) {
      return Status::DataLoss(
          fmt::format("{}: message {} on {}: {}", name, i, m.topic, s.message()));
    }
  }
  return tf;
}

Result<std::string> PickTopic(std::span<const RecordedMessage> messages,
                              const RecordingOptions& options, const std::string& name) {
  std::set<std::string> clouds, all;
  for (const RecordedMessage& m : messages) {
    all.insert(m.topic);
    if (m.type == kPointCloud2Schema) clouds.insert(m.topic);
  }
  const auto list = [](const std::set<std::string>& s) {
    return s.empty() ? std::string("none") : fmt::format("{}", fmt::join(s, ", "));
  };
  if (!options.topic.empty()) {
    if (!all.contains(options.topic)) {
      return Status::InvalidArgument(fmt::format("{}: no messages on topic {} (its {} topics: {})",
                                                 name, options.topic, kPointCloud2Schema,
                                                 list(clouds)));
    }
    return options.topic;
  }
  if (clouds.size() != 1) {
    return Status::InvalidArgument(
        fmt::format("{}: pass --topic: the recording's {} topics are: {}", name, kPointCloud2Schema,
                    list(clouds)));
  }
  return *clouds.begin();
}

}  // namespace

bool IsRosRecording(const std::string& path) {
  const fs::path p(path);
  std::error_code ec;
  if (fs::is_directory(p, ec)) return fs::exists(p / "metadata.yaml", ec);
  const std::string ext = Extension(p);
  return ext == ".mcap" || ext == ".db3" || ext == ".bag";
}

Result<std::vector<RecordedMessage>> ReadRecordedMessages(const std::string& path) {
  std::vector<std::string> files = {path};
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    Result<std::vector<std::string>> listed = BagFiles(path);
    if (!listed.ok()) return listed.status();
    files = std::move(listed).value();
  }
  std::vector<RecordedMessage> all;
  for (const std::string& file : files) {
    const std::string ext = Extension(file);
    Result<std::vector<RecordedMessage>> part = ext == ".db3"   ? ReadRosbag2Sqlite(file)
                                                : ext == ".bag" ? ReadRos1Bag(file)
                                                                : FromMcap(file);
    if (!part.ok()) return part.status();
    if (all.empty()) {
      all = std::move(part).value();
    } else {
      for (RecordedMessage& m : *part) all.push_back(std::move(m));
    }
  }
  return all;
}

Result<RecordingScans> ExtractScans(std::span<const RecordedMessage> messages,
                                    const RecordingOptions& options, const std::string& name) {
  Result<std::string> topic = PickTopic(messages, options, name);
  if (!topic.ok()) return topic.status();
  Result<TfBuffer> tf = CollectTransforms(messages, name);
  if (!tf.ok()) return tf.status();
  RecordingScans out;
  out.topic = *topic;
  for (size_t i = 0; i < messages.size(); ++i) {
    const RecordedMessage& m = messages[i];
    if (m.topic != out.topic) continue;
    if (m.type != kPointCloud2Schema || (m.encoding != "cdr" && m.encoding != "ros1")) {
      return Status::InvalidArgument(fmt::format(
          "{}: message {} on {}: unknown schema '{}' in encoding '{}' (expected {} in cdr)", name,
          i, m.topic, m.type, m.encoding, kPointCloud2Schema));
    }
    Result<PointCloud2> cloud = DecodePointCloud2(AsBytes(m.data), EncodingOf(m));
    if (!cloud.ok()) {
      return Status::DataLoss(
          fmt::format("{}: message {} on {}: {}", name, i, m.topic, cloud.status().message()));
    }
    Result<Pose> pose =
        tf->Lookup(options.map_frame, cloud->header.frame_id, cloud->header.stamp_ns);
    if (!pose.ok()) {
      if (out.skipped++ == 0) {
        out.first_skip = fmt::format("message {}: {}", i, pose.status().message());
      }
      continue;
    }
    out.scans.push_back({std::move(cloud->points), *pose, cloud->header.stamp_ns});
  }
  return out;
}

}  // namespace bgkmap::io

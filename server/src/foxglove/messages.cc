#include "foxglove/messages.h"

#include <google/protobuf/descriptor.pb.h>
#include <openssl/evp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

#include "bgkmap/core/cell_estimate.h"
#include "foxglove/schemas.pb.h"

namespace bgkmap::foxglove {
namespace {

namespace pb = google::protobuf;

void AddFileWithImports(const pb::FileDescriptor* file, std::set<std::string>* seen,
                        pb::FileDescriptorSet* set) {
  if (!seen->insert(file->name()).second) return;
  for (int i = 0; i < file->dependency_count(); ++i) {
    AddFileWithImports(file->dependency(i), seen, set);  // imports first
  }
  file->CopyTo(set->add_file());
}

std::string Base64(const std::string& bytes) {
  std::string out(4 * ((bytes.size() + 2) / 3) + 1, '\0');
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                reinterpret_cast<const unsigned char*>(bytes.data()),
                                static_cast<int>(bytes.size()));
  out.resize(static_cast<size_t>(n));
  return out;
}

Channel ChannelOf(uint32_t id, const char* topic, const pb::Descriptor* schema) {
  pb::FileDescriptorSet set;
  std::set<std::string> seen;
  AddFileWithImports(schema->file(), &seen, &set);
  return {id, topic, std::string(schema->full_name()), Base64(set.SerializeAsString())};
}

void SetTime(uint64_t ns, pb::Timestamp* out) {
  out->set_seconds(static_cast<int64_t>(ns / 1'000'000'000));
  out->set_nanos(static_cast<int32_t>(ns % 1'000'000'000));
}

void SetPose(const Pose& pose, ::foxglove::Pose* out) {
  out->mutable_position()->set_x(pose.translation.x());
  out->mutable_position()->set_y(pose.translation.y());
  out->mutable_position()->set_z(pose.translation.z());
  const Eigen::Quaterniond q(pose.rotation);
  out->mutable_orientation()->set_x(q.x());
  out->mutable_orientation()->set_y(q.y());
  out->mutable_orientation()->set_z(q.z());
  out->mutable_orientation()->set_w(q.w());
}

void AddField(const std::string& name, uint32_t offset,
              google::protobuf::RepeatedPtrField<::foxglove::PackedElementField>* fields) {
  ::foxglove::PackedElementField* f = fields->Add();
  f->set_name(name);
  f->set_offset(offset);
  f->set_type(::foxglove::PackedElementField::FLOAT32);
}

}  // namespace

std::vector<Channel> Channels() {
  return {ChannelOf(kGridChannel, "/map", ::foxglove::Grid::descriptor()),
          ChannelOf(kTransformsChannel, "/tf", ::foxglove::FrameTransforms::descriptor()),
          ChannelOf(kScansChannel, "/scans", ::foxglove::PointCloud::descriptor())};
}

CellBox RegionCells(const GridGeometry& geometry, double x0, double y0, double x1, double y1) {
  constexpr double kSnap = 1e-6;  // a millionth of a cell, as the region query snaps
  const double res = geometry.resolution();
  const auto lo = [&](double v) { return static_cast<int>(std::floor(v / res + kSnap)); };
  const auto hi = [&](double v) { return static_cast<int>(std::ceil(v / res - kSnap)) - 1; };
  const int cx0 = lo(x0), cy0 = lo(y0);
  return {{cx0, cy0}, {std::max(cx0, hi(x1)), std::max(cy0, hi(y1))}};
}

uint64_t StampNs(const Stamp& stamp) {
  if (stamp.seconds < 0 || stamp.nanos < 0 || stamp.seconds > 9'000'000'000) return 0;
  return static_cast<uint64_t>(stamp.seconds) * 1'000'000'000 + static_cast<uint64_t>(stamp.nanos);
}

std::string EncodeGrid(const Raster& raster, uint64_t time_ns) {
  ::foxglove::Grid grid;
  SetTime(time_ns, grid.mutable_timestamp());
  grid.set_frame_id(kMapFrame);
  // The corner of cell (0, 0): the raster's south-west corner.
  ::foxglove::Pose* pose = grid.mutable_pose();
  pose->mutable_position()->set_x(raster.x0);
  pose->mutable_position()->set_y(raster.y1 - static_cast<double>(raster.rows) * raster.resolution);
  pose->mutable_orientation()->set_w(1.0);
  grid.set_column_count(static_cast<uint32_t>(raster.cols));
  grid.mutable_cell_size()->set_x(raster.resolution);
  grid.mutable_cell_size()->set_y(raster.resolution);
  const size_t layers = raster.layers.size();
  const size_t cell_stride = layers * sizeof(float);
  grid.set_cell_stride(static_cast<uint32_t>(cell_stride));
  grid.set_row_stride(static_cast<uint32_t>(cell_stride * static_cast<size_t>(raster.cols)));
  for (size_t l = 0; l < layers; ++l) {
    AddField(std::string(LayerName(raster.layers[l])), static_cast<uint32_t>(l * sizeof(float)),
             grid.mutable_fields());
  }
  std::string* data = grid.mutable_data();
  const size_t cols = static_cast<size_t>(raster.cols), rows = static_cast<size_t>(raster.rows);
  data->resize(rows * cols * cell_stride);
  for (size_t r = 0; r < rows; ++r) {
    const size_t raster_row = rows - 1 - r;  // the Grid's row 0 is the southernmost
    for (size_t c = 0; c < cols; ++c) {
      char* cell = data->data() + (r * cols + c) * cell_stride;
      for (size_t l = 0; l < layers; ++l) {
        std::memcpy(cell + l * sizeof(float), &raster.data[l][raster_row * cols + c],
                    sizeof(float));
      }
    }
  }
  return grid.SerializeAsString();
}

std::string EncodeTransforms(const std::vector<std::shared_ptr<const RobotScan>>& robots) {
  ::foxglove::FrameTransforms transforms;
  for (const auto& robot : robots) {
    ::foxglove::FrameTransform* t = transforms.add_transforms();
    SetTime(StampNs(robot->stamp), t->mutable_timestamp());
    t->set_parent_frame_id(kMapFrame);
    t->set_child_frame_id(robot->robot_id);
    ::foxglove::Pose pose;
    SetPose(robot->pose, &pose);
    *t->mutable_translation() = pose.position();
    *t->mutable_rotation() = pose.orientation();
  }
  return transforms.SerializeAsString();
}

std::string EncodeScan(const RobotScan& scan) {
  ::foxglove::PointCloud cloud;
  SetTime(StampNs(scan.stamp), cloud.mutable_timestamp());
  cloud.set_frame_id(scan.robot_id);
  cloud.mutable_pose()->mutable_orientation()->set_w(1.0);
  cloud.set_point_stride(sizeof(Point3f));
  AddField("x", 0, cloud.mutable_fields());
  AddField("y", 4, cloud.mutable_fields());
  AddField("z", 8, cloud.mutable_fields());
  static_assert(sizeof(Point3f) == 12);
  cloud.mutable_data()->assign(reinterpret_cast<const char*>(scan.points.data()),
                               scan.points.size() * sizeof(Point3f));
  return cloud.SerializeAsString();
}

}  // namespace bgkmap::foxglove

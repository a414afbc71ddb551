#include "rpc/proto_convert.h"

#include <bit>
#include <cstring>

namespace bgkmap {

static_assert(std::endian::native == std::endian::little,
              "packed float32 payloads are little-endian; add byte swapping for this host");

grpc::Status ToGrpcStatus(const Status& status) {
  switch (status.code()) {
    case Status::Code::kOk:
      return grpc::Status::OK;
    case Status::Code::kInvalidArgument:
      return {grpc::StatusCode::INVALID_ARGUMENT, status.message()};
    case Status::Code::kOutOfRange:
      return {grpc::StatusCode::OUT_OF_RANGE, status.message()};
    case Status::Code::kFailedPrecondition:
      return {grpc::StatusCode::FAILED_PRECONDITION, status.message()};
    case Status::Code::kDataLoss:
      return {grpc::StatusCode::DATA_LOSS, status.message()};
    case Status::Code::kIoError:
      return {grpc::StatusCode::INTERNAL, status.message()};
  }
  return {grpc::StatusCode::UNKNOWN, status.message()};
}

v1::Layer ToProto(Layer layer) { return static_cast<v1::Layer>(static_cast<int>(layer) + 1); }

grpc::Status LayersFromProto(const google::protobuf::RepeatedField<int>& layers,
                             const std::string& field, std::vector<Layer>* out) {
  out->clear();
  if (layers.empty()) {
    for (int i = 0; i < kLayerCount; ++i) out->push_back(static_cast<Layer>(i));
    return grpc::Status::OK;
  }
  for (int i = 0; i < layers.size(); ++i) {
    const int v = layers.Get(i);
    if (v < 1 || v > kLayerCount) {
      return {grpc::StatusCode::INVALID_ARGUMENT,
              field + "[" + std::to_string(i) + "]: " + std::to_string(v) + " is not a layer (1.." +
                  std::to_string(kLayerCount) + ")"};
    }
    out->push_back(static_cast<Layer>(v - 1));
  }
  return grpc::Status::OK;
}

void ToProto(TileKey key, v1::TileKey* out) {
  out->set_x(key.x);
  out->set_y(key.y);
}

void ToProto(const CellBox& box, v1::CellBox* out) {
  out->set_min_x(box.min.x);
  out->set_min_y(box.min.y);
  out->set_max_x(box.max.x);
  out->set_max_y(box.max.y);
}

void ToProto(const ScanPointCounts& c, v1::PointCounts* out) {
  out->set_input(c.input);
  out->set_kept(c.kept);
  out->set_dropped_nonfinite(c.dropped_nonfinite);
  out->set_dropped_range(c.dropped_range);
  out->set_dropped_height(c.dropped_height);
  out->set_dropped_out_of_bounds(c.dropped_out_of_bounds);
}

void ToProto(const MapParams& p, v1::MapParameters* out) {
  out->set_resolution(p.resolution);
  out->set_kernel_length(p.kernel_length);
  out->set_lambda(p.lambda);
  out->set_prior_mean(p.prior_mean);
  out->set_sigma2(p.sigma2);
  out->set_alpha0(p.alpha0);
  out->set_beta0(p.beta0);
  out->set_robot_radius(p.robot_radius);
  out->set_step_crit(p.step_crit);
  out->set_slope_crit_deg(p.slope_crit_deg);
  out->set_roughness_crit(p.roughness_crit);
  out->clear_weights();
  for (double w : p.weights) out->add_weights(w);
  out->set_trav_threshold(p.trav_threshold);
  out->set_variance_threshold(p.variance_threshold);
  out->set_min_range(p.min_range);
  out->set_max_range(p.max_range);
  out->set_max_height_above_sensor(p.max_height_above_sensor);
  out->set_observation(std::string(ObservationName(p.observation)));
  out->set_tile_size(p.tile_size);
  out->set_method(std::string(MethodName(p.method)));
}

std::string PackFloats(const float* values, size_t count) {
  std::string bytes(count * sizeof(float), '\0');
  if (count > 0) std::memcpy(bytes.data(), values, bytes.size());
  return bytes;
}

void AppendRows(const Raster& raster, int64_t row_begin, int64_t row_end,
                google::protobuf::RepeatedPtrField<v1::LayerValues>* out) {
  for (size_t i = 0; i < raster.layers.size(); ++i) {
    v1::LayerValues* lv = out->Add();
    lv->set_layer(ToProto(raster.layers[i]));
    const size_t begin = static_cast<size_t>(row_begin * raster.cols);
    const size_t count = static_cast<size_t>((row_end - row_begin) * raster.cols);
    lv->set_values(PackFloats(raster.data[i].data() + begin, count));
  }
}

}  // namespace bgkmap

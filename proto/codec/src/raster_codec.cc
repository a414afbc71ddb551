#include "bgkmap/proto/raster_codec.h"

#include <bit>
#include <cstring>

#include "bgkmap/proto/grid_codec.h"
#include "bgkmap/proto/layer_codec.h"

namespace bgkmap {

static_assert(std::endian::native == std::endian::little,
              "packed float32 payloads are little-endian; add byte swapping for this host");

std::string PackFloats(const float* values, size_t count) {
  std::string bytes(count * sizeof(float), '\0');
  if (count > 0) std::memcpy(bytes.data(), values, bytes.size());
  return bytes;
}

bool UnpackFloats(const std::string& bytes, std::vector<float>* out) {
  if (bytes.size() % sizeof(float) != 0) return false;
  out->resize(bytes.size() / sizeof(float));
  if (!bytes.empty()) std::memcpy(out->data(), bytes.data(), bytes.size());
  return true;
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

bool CopyRows(const google::protobuf::RepeatedPtrField<v1::LayerValues>& in, int64_t row_begin,
              int64_t row_count, Raster* raster) {
  if (in.size() != static_cast<int>(raster->layers.size()) || row_begin < 0 || row_count < 0 ||
      row_begin + row_count > raster->rows) {
    return false;
  }
  const size_t expect = static_cast<size_t>(row_count * raster->cols) * sizeof(float);
  for (int i = 0; i < in.size(); ++i) {
    const std::string& bytes = in.Get(i).values();
    if (bytes.size() != expect) return false;
    if (expect > 0) {
      std::memcpy(raster->data[i].data() + row_begin * raster->cols, bytes.data(), expect);
    }
  }
  return true;
}

void ToProto(const Raster& raster, v1::RasterHeader* out) {
  ToProto(raster.box, out->mutable_cells());
  out->set_stride(static_cast<uint32_t>(raster.stride));
  out->set_cols(static_cast<uint32_t>(raster.cols));
  out->set_rows(static_cast<uint32_t>(raster.rows));
  out->set_resolution(raster.resolution);
  out->set_x0(raster.x0);
  out->set_y1(raster.y1);
  out->clear_layers();
  for (Layer l : raster.layers) out->add_layers(ToProto(l));
}

Raster GeometryFromProto(const v1::RasterHeader& h) {
  Raster raster;
  raster.box = FromProto(h.cells());
  raster.stride = static_cast<int>(h.stride());
  raster.cols = h.cols();
  raster.rows = h.rows();
  raster.resolution = h.resolution();
  raster.x0 = h.x0();
  raster.y1 = h.y1();
  for (int l : h.layers()) raster.layers.push_back(FromProto(static_cast<v1::Layer>(l)));
  return raster;
}

Raster FromProto(const v1::RasterHeader& h) {
  Raster raster = GeometryFromProto(h);
  raster.data.assign(raster.layers.size(),
                     std::vector<float>(static_cast<size_t>(raster.rows * raster.cols)));
  return raster;
}

Raster TileRasterFromProto(const v1::TileUpdate& update) {
  Raster r;
  r.box = FromProto(update.cells());
  r.stride = 1;
  r.cols = r.box.width();
  r.rows = r.box.height();
  r.resolution = update.resolution();
  r.x0 = r.box.min.x * r.resolution;
  r.y1 = (static_cast<double>(r.box.max.y) + 1.0) * r.resolution;
  for (const v1::LayerValues& lv : update.layers()) {
    r.layers.push_back(FromProto(lv.layer()));
    r.data.emplace_back();
    UnpackFloats(lv.values(), &r.data.back());
  }
  return r;
}

}  // namespace bgkmap

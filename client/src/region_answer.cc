#include "region_answer.h"

#include "bgkmap/proto/grid_codec.h"
#include "bgkmap/proto/layer_codec.h"
#include "bgkmap/proto/raster_codec.h"
#include "bgkmap/proto/region_delta_codec.h"

namespace bgkmap {
namespace {

bool SameGeometry(const Raster& a, const Raster& b) {
  return a.box.min == b.box.min && a.box.max == b.box.max && a.stride == b.stride &&
         a.rows == b.rows && a.cols == b.cols && a.layers == b.layers;
}

RegionPatch FromProto(const v1::TilePatch& p, const std::vector<Layer>& layers) {
  RegionPatch out;
  out.key = {p.key().x(), p.key().y()};
  out.row_start = p.row_start();
  out.col_start = p.col_start();
  out.rows = p.rows();
  out.cols = p.cols();
  out.tombstone = p.tombstone();
  // (checked against the geometry by ApplyPatch in Add)
  for (size_t i = 0; i < layers.size() && !p.tombstone(); ++i) {
    UnpackFloats(p.layers(static_cast<int>(i)).values(), &out.values.emplace_back());
  }
  return out;
}

// The patch as the codec reads it.
v1::TilePatch ToProto(const RegionPatch& p, const std::vector<Layer>& layers) {
  v1::TilePatch out;
  out.set_row_start(static_cast<uint32_t>(p.row_start));
  out.set_col_start(static_cast<uint32_t>(p.col_start));
  out.set_rows(static_cast<uint32_t>(p.rows));
  out.set_cols(static_cast<uint32_t>(p.cols));
  out.set_tombstone(p.tombstone);
  for (size_t i = 0; i < p.values.size() && i < layers.size(); ++i) {
    v1::LayerValues* lv = out.add_layers();
    lv->set_layer(bgkmap::ToProto(layers[i]));
    lv->set_values(PackFloats(p.values[i].data(), p.values[i].size()));
  }
  return out;
}

}  // namespace

Status RegionAnswerReader::Add(const v1::RegionChunk& chunk) {
  out_.wire_bytes += chunk.ByteSizeLong();
  if (chunk.has_header()) {
    if (have_header_) return Status::InvalidArgument("region answer with two headers");
    const v1::RasterHeader& h = chunk.header();
    have_header_ = true;
    out_.full = h.answer() != v1::REGION_ANSWER_DELTA;
    out_.resync_reason = h.resync_reason();
    out_.map_version = h.map_version();
    out_.history_id = h.history_id();
    // A delta carries no rows: its geometry only, not a whole region's zeroed layers.
    out_.raster = out_.full ? bgkmap::FromProto(h) : GeometryFromProto(h);
  }
  if (!have_header_) return Status::InvalidArgument("region chunk before the header");
  Raster& r = out_.raster;
  if (!out_.full) {
    if (chunk.row_count() != 0 || chunk.layers_size() != 0) {
      return Status::InvalidArgument("region delta with rows");
    }
    // A patch must fit in the region and carry every layer at its size (a tombstone none).
    for (const v1::TilePatch& p : chunk.patches()) {
      if (p.row_start() + static_cast<int64_t>(p.rows()) > r.rows ||
          p.col_start() + static_cast<int64_t>(p.cols()) > r.cols) {
        return Status::InvalidArgument("region patch outside the region");
      }
      const size_t n = static_cast<size_t>(p.rows()) * p.cols() * sizeof(float);
      if (p.tombstone() ? p.layers_size() != 0
                        : p.layers_size() != static_cast<int>(r.layers.size())) {
        return Status::InvalidArgument("region patch with the wrong layers");
      }
      for (int i = 0; i < p.layers_size(); ++i) {
        if (p.layers(i).values().size() != n) {
          return Status::InvalidArgument("region patch of the wrong size");
        }
      }
      out_.patches.push_back(FromProto(p, r.layers));
    }
    return Status::Ok();
  }
  if (chunk.patches_size() != 0) return Status::InvalidArgument("region rows with patches");
  if (chunk.row_start() != next_row_ || chunk.layers_size() != static_cast<int>(r.layers.size()) ||
      next_row_ + chunk.row_count() > r.rows) {
    return Status::InvalidArgument("region chunk out of order");
  }
  if (!CopyRows(chunk.layers(), next_row_, chunk.row_count(), &r)) {
    return Status::InvalidArgument("region chunk of the wrong size");
  }
  next_row_ += chunk.row_count();
  return Status::Ok();
}

Result<RegionDelta> RegionAnswerReader::Finish() && {
  if (!have_header_ || (out_.full && next_row_ != out_.raster.rows)) {
    return Status::InvalidArgument("region stream incomplete");
  }
  return std::move(out_);
}

Status ApplyDelta(const RegionDelta& delta, Raster* copy) {
  if (delta.full) {
    *copy = delta.raster;
    return Status::Ok();
  }
  if (!SameGeometry(delta.raster, *copy) || copy->data.size() != copy->layers.size()) {
    return Status::InvalidArgument(
        "the delta's region (cells, stride, layers) is not the copy's: query the same region");
  }
  // Checked first, so a bad patch leaves the copy unchanged.
  Raster probe = *copy;
  for (const RegionPatch& p : delta.patches) {
    if (!ApplyPatch(ToProto(p, copy->layers), &probe)) {
      return Status::InvalidArgument("a region patch does not fit the copy");
    }
  }
  *copy = std::move(probe);
  return Status::Ok();
}

}  // namespace bgkmap

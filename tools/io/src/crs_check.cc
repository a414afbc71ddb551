#include "bgkmap/io/crs_check.h"

#include <cpl_error.h>
#include <ogr_spatialref.h>

namespace bgkmap::io {

Status CheckCrsUse(const CrsUse& use) {
  const std::string named = use.option + " " + use.crs;
  OGRSpatialReference srs;
  CPLPushErrorHandler(CPLQuietErrorHandler);
  const OGRErr parsed = srs.SetFromUserInput(use.crs.c_str());
  CPLPopErrorHandler();
  if (parsed != OGRERR_NONE) {
    return Status::InvalidArgument(named +
                                   ": not a coordinate system GDAL knows (EPSG:code, WKT or PROJ)");
  }
  if (srs.IsGeographic()) {
    return Status::InvalidArgument(named +
                                   " is geographic (degrees) but the map is in metres: use a "
                                   "projected CRS, e.g. the UTM zone's EPSG:326NN");
  }
  if (!srs.IsProjected() && !srs.IsLocal()) {
    return Status::InvalidArgument(named + " is not a projected coordinate system");
  }
  if (srs.IsProjected() && use.frame_is_local && !use.has_origin) {
    return Status::InvalidArgument(
        named +
        ": the map frame is local, so its coordinates are not this CRS's; pass --origin "
        "E,N[,H] (where the map frame's origin lies in it)");
  }
  return Status::Ok();
}

}  // namespace bgkmap::io

// GDAL plumbing shared by the GeoTIFF reader and writer (private to bgkmap_io): drivers registered
// once with GDAL's stderr output silenced, datasets closed by RAII, GDAL's last error as a Status.
#pragma once

#include <gdal_priv.h>

#include <memory>
#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

// Registers GDAL's drivers once (thread-safe) and silences its stderr; the message of the last
// error is still kept per thread for GdalError.
void InitGdal();

// IoError "path: what: <GDAL's last error message>".
Status GdalError(const std::string& path, const std::string& what);

struct DatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(GDALDataset::ToHandle(ds)); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

// Closes `ds`. Closing flushes the compressed blocks, so a failure there is a failed write;
// GDALClose returns void in GDAL 3.6, so the error state it leaves is checked.
Status CloseDataset(DatasetPtr& ds, const std::string& path);

}  // namespace bgkmap::io

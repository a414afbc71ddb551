#include "gdal_dataset.h"

#include <cpl_error.h>

#include <mutex>

namespace bgkmap::io {
namespace {

void QuietGdalErrors(CPLErr, CPLErrorNum, const char*) {}

}  // namespace

void InitGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(QuietGdalErrors);
  });
}

Status GdalError(const std::string& path, const std::string& what) {
  const char* msg = CPLGetLastErrorMsg();
  return Status::IoError(path + ": " + what + (msg && *msg ? std::string(": ") + msg : ""));
}

Status CloseDataset(DatasetPtr& ds, const std::string& path) {
  CPLErrorReset();
  ds.reset();
  if (CPLGetLastErrorType() >= CE_Failure) return GdalError(path, "cannot finish file");
  return Status::Ok();
}

}  // namespace bgkmap::io

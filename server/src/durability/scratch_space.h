// Where an import spools its upload (Durability's sixth concern), within the free-space reserve
// the store relies on.
#pragma once

#include <cstdint>
#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap {

class ScratchSpace {
 public:
  // `exclusive`: only this server writes there, so files a crash left behind may be removed.
  struct ScratchDirectory {
    std::string path;
    bool exclusive = false;
  };
  virtual ScratchDirectory scratch_directory() const = 0;
  // OK if `bytes` more may be written to scratch_directory() without eating into the
  // free-space reserve.
  virtual Status AdmitScratch(uint64_t /*bytes*/) { return Status::Ok(); }

 protected:
  ~ScratchSpace() = default;
};

}  // namespace bgkmap

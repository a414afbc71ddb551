// Where the map frame sits in a coordinate reference system (Durability's fifth concern): a
// store keeps the first georeference it is given (docs/storage.md, "Georeference"); a map in
// memory has the configured one.
#pragma once

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

class MapFrame {
 public:
  // Empty: a local frame.
  virtual Georeference georeference() const = 0;
  // Ties a map in a local frame to `georeference` (an import of a georeferenced archive): OK at
  // once if it is empty or already the map's; FailedPrecondition naming the key if the map has
  // another; a store's write error otherwise.
  virtual Status AdoptGeoreference(const Georeference& georeference) = 0;

 protected:
  ~MapFrame() = default;
};

}  // namespace bgkmap

// Every conversion between engine types and bgkmap.v1 messages; shared by bgkmapd and the client.
#pragma once

#include "bgkmap/proto/grid_codec.h"    // IWYU pragma: export
#include "bgkmap/proto/layer_codec.h"   // IWYU pragma: export
#include "bgkmap/proto/params_codec.h"  // IWYU pragma: export
#include "bgkmap/proto/raster_codec.h"  // IWYU pragma: export
#include "bgkmap/proto/scan_codec.h"    // IWYU pragma: export

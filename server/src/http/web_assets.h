// The web map's static files (web/src and Leaflet from web/node_modules), embedded in bgkmapd at
// build time by web/embed_assets.cmake, so the page needs no files beside the binary and no
// network but the server's.
#pragma once

#include <string_view>

namespace bgkmap {

struct WebAsset {
  std::string_view path;  // "/static/leaflet/leaflet.js"
  std::string_view content_type;
  std::string_view bytes;
};

// The asset served at `path`, or null.
const WebAsset* FindWebAsset(std::string_view path);

}  // namespace bgkmap

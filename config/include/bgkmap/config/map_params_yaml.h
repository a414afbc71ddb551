// YAML adapter for MapParams: the engine stays free of file formats. Keys, kinds and order come
// from MapParamTable(); this file only knows how each kind is spelled in YAML.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/map_params.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

// Reads engine keys from the top level of `root`, starting from `base` (defaults when omitted).
// Keys listed in `other_sections` (e.g. "server", "storage") are left for their owners; any other
// unknown key, a value of the wrong type and a value that fails MapParams::Validate() is an
// error whose message is one line naming the key.
Result<MapParams> MapParamsFromYaml(const YAML::Node& root,
                                    const std::vector<std::string_view>& other_sections = {},
                                    const MapParams& base = MapParams{});

// Parses a YAML file (or fails with "<path>: <reason>").
Result<YAML::Node> LoadYamlFile(const std::string& path);

// Convenience: LoadYamlFile + MapParamsFromYaml.
Result<MapParams> LoadMapParamsFile(const std::string& path,
                                    const std::vector<std::string_view>& other_sections = {});

// An optional config file, as command-line tools take it: the built-in defaults when `path` is
// empty, otherwise LoadMapParamsFile(path).
Result<MapParams> LoadMapParamsFileOrDefaults(const std::string& path);

// Every engine key with its value, in MapParamTable() order (what --print-config shows).
YAML::Node MapParamsToYaml(const MapParams& params);

}  // namespace bgkmap

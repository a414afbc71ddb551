// Parsing shared by the subcommands that talk to bgkmapd: the server address, boxes, layers,
// and the one-line failure convention.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/core/status.h"

namespace bgkmap::cli {

inline constexpr const char* kDefaultServer = "127.0.0.1:50051";

// Adds --server (host:port of bgkmapd) to `cmd`; default $BGKMAP_SERVER, else kDefaultServer.
void AddServerOption(CLI::App* cmd, std::string& server);

// "xmin,ymin,xmax,ymax" already split by CLI11 into 4 numbers.
Result<MetricBox> ParseBox(const std::vector<double>& v, const std::string& option);

// Layer names ("elevation,state"); empty gives `fallback`.
Result<std::vector<Layer>> ParseLayers(const std::vector<std::string>& names,
                                       const std::vector<Layer>& fallback);

// Prints "bgkmap <command>: <message>" to stderr; returns kExitFailure (1).
int Fail(const std::string& command, const std::string& message);
// The same for a bad command line; returns kExitUsage (2).
int Usage(const std::string& command, const std::string& message);

// The GeoTIFF band contract shared by `bgkmap build` and `bgkmap query`.
const std::vector<Layer>& GeoTiffBands();

}  // namespace bgkmap::cli

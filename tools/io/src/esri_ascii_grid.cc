#include "bgkmap/io/esri_ascii_grid.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

namespace bgkmap::io {
namespace {

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

float EsriAsciiGrid::At(double x, double y) const {
  const double c = std::floor((x - x0) / cellsize);
  const double r = std::floor((y0 + rows * cellsize - y) / cellsize);
  if (!(c >= 0 && c < cols && r >= 0 && r < rows)) return std::numeric_limits<float>::quiet_NaN();
  return values[static_cast<size_t>(r) * cols + static_cast<size_t>(c)];
}

Result<EsriAsciiGrid> ReadEsriAsciiGrid(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot open");
  auto bad = [&](const std::string& why) { return Status::DataLoss(path + ": " + why); };

  // Header: "key value" lines until the first line that starts with a number.
  std::map<std::string, double> header;
  std::string line;
  std::streampos body = in.tellg();
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    const char k0 = key[0];
    if (std::isdigit(static_cast<unsigned char>(k0)) || k0 == '-' || k0 == '+' || k0 == '.') break;
    double v = 0;
    if (!(ls >> v)) return bad("header line '" + line + "' has no numeric value");
    header[Lower(key)] = v;
    body = in.tellg();
  }
  for (const char* k : {"ncols", "nrows", "cellsize"}) {
    if (!header.count(k)) return bad(std::string("header lacks ") + k);
  }
  EsriAsciiGrid g;
  g.cols = static_cast<int64_t>(header["ncols"]);
  g.rows = static_cast<int64_t>(header["nrows"]);
  g.cellsize = header["cellsize"];
  if (g.cols <= 0 || g.rows <= 0 || g.cols * g.rows > 400'000'000 || !(g.cellsize > 0)) {
    return bad("ncols, nrows must be positive (at most 4e8 cells) and cellsize > 0");
  }
  const double half = 0.5 * g.cellsize;
  if (header.count("xllcorner")) {
    g.x0 = header["xllcorner"];
  } else if (header.count("xllcenter")) {
    g.x0 = header["xllcenter"] - half;
  } else {
    return bad("header lacks xllcorner/xllcenter");
  }
  if (header.count("yllcorner")) {
    g.y0 = header["yllcorner"];
  } else if (header.count("yllcenter")) {
    g.y0 = header["yllcenter"] - half;
  } else {
    return bad("header lacks yllcorner/yllcenter");
  }
  const bool has_nodata = header.count("nodata_value") > 0;
  const double nodata = has_nodata ? header["nodata_value"] : 0.0;

  in.clear();
  in.seekg(body);
  const size_t n = static_cast<size_t>(g.cols * g.rows);
  g.values.resize(n);
  std::string tok;
  for (size_t i = 0; i < n; ++i) {
    if (!(in >> tok)) {
      return bad("body ends after " + std::to_string(i) + " of " + std::to_string(n) + " values");
    }
    double v = 0;
    const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc() || p != tok.data() + tok.size()) {
      return bad("value " + std::to_string(i) + " '" + tok + "' is not a number");
    }
    g.values[i] = (has_nodata && v == nodata) ? std::numeric_limits<float>::quiet_NaN()
                                              : static_cast<float>(v);
  }
  return g;
}

}  // namespace bgkmap::io

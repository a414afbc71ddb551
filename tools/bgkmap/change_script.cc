#include "change_script.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace bgkmap::cli {
namespace {

std::string Where(const YAML::Node& node) {
  const YAML::Mark m = node.Mark();
  if (m.line < 0) return "";
  return " (line " + std::to_string(m.line + 1) + ")";
}

Status Bad(const std::string& what, const YAML::Node& node, const std::string& msg) {
  std::string s = what;
  s += Where(node);
  s += ": ";
  s += msg;
  return Status::InvalidArgument(s);
}

Result<double> Number(const std::string& what, const YAML::Node& node) {
  if (node.IsScalar()) {
    try {
      const double v = node.as<double>();
      if (std::isfinite(v)) return v;
    } catch (const YAML::Exception&) {
    }
  }
  return Bad(what, node, "expected a finite number");
}

Result<std::pair<double, double>> Pair(const std::string& what, const YAML::Node& node) {
  if (!node.IsSequence() || node.size() != 2) return Bad(what, node, "expected [x, y]");
  Result<double> x = Number(what, node[0]);
  if (!x.ok()) return x.status();
  Result<double> y = Number(what, node[1]);
  if (!y.ok()) return y.status();
  return std::make_pair(*x, *y);
}

Result<int> ScanIndex(const std::string& what, const YAML::Node& node, int scans) {
  int k = -1;
  bool is_int = false;
  if (node.IsScalar()) {
    try {
      k = node.as<int>();
      is_int = true;
    } catch (const YAML::Exception&) {
    }
  }
  if (!is_int) return Bad(what, node, "expected a scan index (an integer)");
  if (k < 1 || k > scans - 1) {
    return Bad(what, node,
               "scan " + std::to_string(k) + " is outside 1.." + std::to_string(scans - 1) +
                   " (a change needs a scan before it and one after; the sequence has " +
                   std::to_string(scans) + " scans)");
  }
  return k;
}

Result<sim::ScriptedObject> ParseObject(const YAML::Node& node, size_t index, int scans) {
  sim::ScriptedObject o;
  std::string what = "object ";
  what += std::to_string(index + 1);
  if (!node.IsMap()) return Bad(what, node, "expected a map (center, size, height, ...)");
  bool has_center = false, has_size = false, has_height = false, has_appear = false,
       has_disappear = false;
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    const YAML::Node& v = kv.second;
    std::string field = what;
    field += ".";
    field += key;
    if (key == "name") {
      if (!v.IsScalar()) return Bad(field, v, "expected a string");
      o.name = v.Scalar();
    } else if (key == "center") {
      Result<std::pair<double, double>> c = Pair(field, v);
      if (!c.ok()) return c.status();
      o.center_x = c->first;
      o.center_y = c->second;
      has_center = true;
    } else if (key == "size") {
      Result<std::pair<double, double>> s = Pair(field, v);
      if (!s.ok()) return s.status();
      if (!(s->first > 0 && s->second > 0)) return Bad(field, v, "both sizes must be > 0");
      o.size_x = s->first;
      o.size_y = s->second;
      has_size = true;
    } else if (key == "height") {
      Result<double> h = Number(field, v);
      if (!h.ok()) return h.status();
      if (!(*h > 0)) return Bad(field, v, "must be > 0");
      o.height = *h;
      has_height = true;
    } else if (key == "appear") {
      Result<int> k = ScanIndex(field, v, scans);
      if (!k.ok()) return k.status();
      o.appear = *k;
      has_appear = true;
    } else if (key == "velocity") {
      Result<std::pair<double, double>> v2 = Pair(field, v);
      if (!v2.ok()) return v2.status();
      o.velocity_x = v2->first;
      o.velocity_y = v2->second;
    } else if (key == "disappear") {
      Result<int> k = ScanIndex(field, v, scans);
      if (!k.ok()) return k.status();
      o.disappear = *k;
      has_disappear = true;
    } else {
      return Bad(what, kv.first,
                 "unknown key '" + key +
                     "' (known: name, center, size, height, appear, disappear, velocity)");
    }
  }
  if (!has_center || !has_size || !has_height) {
    return Bad(what, node, "needs center, size and height");
  }
  if (has_appear && has_disappear && !o.Moves()) {
    return Bad(what, node,
               "give appear or disappear, not both (script a second object for a second change)");
  }
  if (has_appear && has_disappear && o.disappear <= o.appear) {
    return Bad(what, node, "disappear must come after appear");
  }
  if (o.name.empty()) o.name = what;
  return o;
}

}  // namespace

Result<std::vector<sim::ScriptedObject>> ParseChangeScript(const std::string& text, int scans) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument("line " + std::to_string(e.mark.line + 1) + ", column " +
                                   std::to_string(e.mark.column + 1) + ": " + e.msg);
  }
  if (!root.IsMap() || !root["objects"] || !root["objects"].IsSequence()) {
    return Status::InvalidArgument("expected a map with an 'objects' list");
  }
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (key != "objects") return Bad("top level", kv.first, "unknown key '" + key + "'");
  }
  const YAML::Node list = root["objects"];
  if (list.size() == 0) return Status::InvalidArgument("'objects' is empty");
  std::vector<sim::ScriptedObject> objects;
  for (size_t i = 0; i < list.size(); ++i) {
    Result<sim::ScriptedObject> o = ParseObject(list[i], i, scans);
    if (!o.ok()) return o.status();
    objects.push_back(std::move(o).value());
  }
  return objects;
}

Result<std::vector<sim::ScriptedObject>> LoadChangeScript(const std::string& path, int scans) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot read");
  std::ostringstream text;
  text << in.rdbuf();
  Result<std::vector<sim::ScriptedObject>> objects = ParseChangeScript(text.str(), scans);
  if (!objects.ok()) {
    std::string msg = path;
    msg += ": ";
    msg += objects.status().message();
    return Status::InvalidArgument(msg);
  }
  return objects;
}

}  // namespace bgkmap::cli

// What the map itself does not keep, for live views (the Foxglove port, docs/foxglove.md): each
// robot's latest applied scan, its pose and a thinned copy of its points.
//
// Memory is bounded: at most `max_robots` robots (a new one evicts the robot updated longest
// ago) and `max_points` points per robot (every k-th point of a larger scan, in sensor order).
// A scan replaces its robot's previous one whole; readers get immutable snapshots, so a reader
// never waits for a writer beyond a pointer swap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/server/robot_stats.h"

namespace bgkmap {

struct RobotScan {
  std::string robot_id;
  uint64_t sequence = 0;
  Stamp stamp;
  Pose pose;                    // T_map_sensor the scan was sent with
  std::vector<Point3f> points;  // in the sensor frame, thinned
  size_t points_sent = 0;       // before thinning
};

class LatestScans {
 public:
  // Called (with the lock held: it must only schedule work) after a robot's scan is recorded.
  using Listener = std::function<void(const std::string& robot_id)>;

  LatestScans(size_t max_robots, size_t max_points);

  // Records an applied scan of `robot_id`; an older sequence than the one kept is ignored.
  void Record(const std::string& robot_id, uint64_t sequence, Stamp stamp, const Pose& pose,
              std::span<const Point3f> points);

  // Every robot's latest scan, sorted by robot id.
  std::vector<std::shared_ptr<const RobotScan>> All() const;
  // One robot's latest scan, or null.
  std::shared_ptr<const RobotScan> Find(const std::string& robot_id) const;

  uint64_t Listen(Listener listener);
  // After this returns, the listener is never called again.
  void Unlisten(uint64_t id);

  size_t max_points() const { return max_points_; }

 private:
  struct Entry {
    std::shared_ptr<const RobotScan> scan;
    uint64_t updated = 0;  // order of the last update
  };
  const size_t max_robots_;
  const size_t max_points_;
  mutable std::mutex mu_;
  std::map<std::string, Entry> robots_;
  uint64_t updates_ = 0;
  uint64_t next_listener_ = 1;
  std::map<uint64_t, Listener> listeners_;
};

// Every k-th point of `points`, k the smallest step that keeps at most `max_points`.
std::vector<Point3f> ThinPoints(std::span<const Point3f> points, size_t max_points);

}  // namespace bgkmap

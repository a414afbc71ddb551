// The change script of `bgkmap simulate --change FILE`: boxes that appear or disappear at given
// scans. YAML (or JSON, which YAML reads too):
//
//   objects:
//     - name: crate          # optional; default "object N"
//       center: [5.0, 0.0]   # world frame, metres
//       size: [2.0, 2.0]     # x and y extent, metres
//       height: 1.0          # flat top this far above the surface at the centre, metres
//       disappear: 10        # first scan without it; or appear: K, the first scan with it
//       velocity: [0, 10]    # optional, m/s (10 Hz scans): a vehicle, at `center` at its first
//                            # scan, driving on in a straight line
//
// A standing object has at most one event (appear or disappear); one with neither stands
// throughout. A moving one may have both (it enters and leaves the scene).
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/sim/scripted_objects.h"

namespace bgkmap::cli {

// Parses a script for a sequence of `scans` scans; an event must fall on a scan 1 .. scans - 1
// (a change needs a scan before it and one after). Errors are one line naming the object.
Result<std::vector<sim::ScriptedObject>> ParseChangeScript(const std::string& text, int scans);
// The same on a file; errors start with the path.
Result<std::vector<sim::ScriptedObject>> LoadChangeScript(const std::string& path, int scans);

}  // namespace bgkmap::cli

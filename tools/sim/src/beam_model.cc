#include "bgkmap/sim/beam_model.h"

namespace bgkmap::sim {

BeamModel Vlp16() {
  BeamModel m{"VLP-16", {}, 1800, 0.5, 100.0, 0.015};
  for (int i = 0; i < 16; ++i) m.elevation_deg.push_back(-15.0 + 2.0 * i);
  return m;
}

BeamModel Hdl32e() {
  BeamModel m{"HDL-32E", {}, 2250, 1.0, 100.0, 0.02};
  for (int i = 0; i < 32; ++i) m.elevation_deg.push_back(-30.67 + i * (41.34 / 31.0));
  return m;
}

BeamModel Os1_128() {
  BeamModel m{"OS1-128", {}, 1024, 0.3, 120.0, 0.015};
  for (int i = 0; i < 128; ++i) m.elevation_deg.push_back(-22.5 + i * (45.0 / 127.0));
  return m;
}

}  // namespace bgkmap::sim

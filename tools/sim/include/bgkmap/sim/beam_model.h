// Spinning-lidar beam models: the elevation angle of every laser and the azimuth sampling.
#pragma once

#include <string>
#include <vector>

namespace bgkmap::sim {

struct BeamModel {
  std::string name;
  std::vector<double> elevation_deg;  // one per laser, any order
  int azimuth_steps = 0;              // firings per revolution
  double min_range = 0.0;             // metres: closer returns are not reported
  double max_range = 0.0;             // metres: farther surfaces give no return
  double range_noise_std = 0.0;       // metres, Gaussian along the beam

  int points_per_revolution() const {
    return static_cast<int>(elevation_deg.size()) * azimuth_steps;
  }
};

// Velodyne VLP-16: 16 lasers from -15 to +15 deg every 2 deg, 0.2 deg azimuth (28,800 beams).
BeamModel Vlp16();
// Velodyne HDL-32E: 32 lasers from -30.67 to +10.67 deg, 0.16 deg azimuth (72,000 beams).
BeamModel Hdl32e();
// Ouster OS1-128: 128 lasers over +-22.5 deg, 1024 columns (131,072 beams).
BeamModel Os1_128();

}  // namespace bgkmap::sim

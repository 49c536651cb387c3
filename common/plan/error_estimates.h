#pragma once
// What an Accumulator estimates of the error of its image against the converged one (RMS over
// pixels, in luminance), and what the stop rules (stop_targets.h) and the job status read.

namespace pf {

struct ErrorEstimates {
  // Accumulator::EstimatedNoiseRms: the spread of the per-map pixel means (every plan but the
  // hierarchical), unclamped: the pixels on a visible light's border weigh most.
  double noise = -1;
  // The progressive plan's, display-referred (progressive_bias.h: luminance clamped to [0, 1]):
  double display_noise = -1;  // ProgressiveBias::NoiseRms
  double bias = -1;           // ProgressiveBias::BiasRms
  double error = -1;          // ProgressiveBias::ErrorRms: √(display_noise² + bias²)
};

}  // namespace pf

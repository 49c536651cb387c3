#pragma once
// Which part of a camera path's radiance an integrator returns. The photon-map shader's radiance
// is a sum of a part read from the photon maps (the global and caustic estimates, the local pass)
// and a part that does not depend on the map: emission seen along the camera path's singular
// chain and the separately computed direct light (Wald 1999, §4.2: Monte Carlo shadow rays).
// The hierarchical plan (§4.5) with HierarchyPart::kIndirect renders the map part through the
// hierarchy, whose details cancel the map's low-frequency error, and the other part per pixel,
// where it is white noise that a detail (three evaluations) would only add up
// (docs/renderer.md, "Hierarchical plan"). Each part is an unbiased estimate of its share and
// kAll is their sum.

namespace pf {

enum class RadiancePart {
  kAll,       // everything (every plan but the split hierarchy)
  kMapped,    // only the photon-map estimates (and local-pass gathers) along the camera path
  kUnmapped,  // only emission and separate direct light along the camera path
};

}  // namespace pf

#pragma once
// MGF colour (mgfdoc.tr §3 c/cxy/cspec/cct/cmix, §6.1.1): CIE 1931 chromaticities, spectra
// integrated against the 1931 2° colour-matching functions, and the spec's XYZ -> RGB matrix.
// The choices (what is clamped, what is rejected) are documented in mgf_loader.h.

#include <cstddef>

#include "common/core/math.h"

namespace pf::mgf {

// Luminous efficacy used to turn lumens into radiometric "watts" (Radiance's WHTEFFICACY).
inline constexpr double kLuminousEfficacy = 179.0;

// Chromaticities with y below this are outside the spectral locus (whose minimum y is about
// 0.004); their luminance-normalised colour would be absurdly large.
inline constexpr double kMinChromaY = 1e-4;

// Linear RGB of CIE (x, y, Y) with the §6.1.1 matrix; negative components clamped to 0.
Rgb CieToRgb(double x, double y, double Y);

// CIE (x, y) of a relative spectrum sampled evenly from lambda_min to lambda_max nanometres.
// Returns false if it has no positive luminance in 380-780 nm.
bool SpectrumToXy(double lambda_min, double lambda_max, const double* values, size_t count, double* x,
                  double* y);

// A colour context: chromaticity only; intensity comes with the material value (§3 c).
struct Chroma {
  double x = 1.0 / 3.0;  // the unnamed colour is neutral (equal-energy) grey
  double y = 1.0 / 3.0;
  Vec3d XyzPerLuminance() const { return {x / y, 1.0, (1.0 - x - y) / y}; }
};

// Chromaticity of a CIE XYZ colour. False if it has no positive luminance, is not finite, or
// its y is below kMinChromaY (*c is then unspecified).
bool XyzToChroma(const Vec3d& xyz, Chroma* c);

// Chromaticity of a black body at temperature t in kelvin (§3 cct), by Planck's law integrated
// against the colour-matching functions. False if it gives no visible light (*c is then
// unspecified).
bool BlackbodyToChroma(double t, Chroma* c);

// Linear RGB of a chromaticity at luminance Y = 1.
Rgb ChromaRgb(const Chroma& c);

}  // namespace pf::mgf

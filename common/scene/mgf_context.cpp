// The context entities of MGF (mgfdoc.tr §2.1 named contexts; §3 c, cxy, cspec, cct, cmix, m,
// sides, rd, td, ed, rs, ts, ir, v, p, n) and the conversion of the current material into a
// SceneDescription material (the colour and material rules of mgf_loader.h, §6.1.1).

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "common/scene/mgf_color.h"
#include "common/scene/mgf_reader.h"
#include "common/scene/polygon_triangulation.h"

namespace pf::mgf {
namespace {

constexpr double kPiD = std::numbers::pi;

}  // namespace

template <typename T>
void MgfReader::SelectContext(ContextTable<T>& table, const Args& a, const char* what, bool* defined) {
  *defined = false;
  if (a.size() == 1) {
    table.unnamed = T{};  // re-establishing the unnamed context restores its defaults
    table.current = &table.unnamed;
    return;
  }
  if (a.size() == 2) {
    const auto it = table.named.find(a[1]);
    if (it == table.named.end()) Fail(std::string("undefined ") + what + " " + Quote(a[1]));
    table.current = &it->second;
    return;
  }
  if ((a.size() == 3 || a.size() == 4) && a[2] == "=") {
    T value{};
    if (a.size() == 4) {
      const auto it = table.named.find(a[3]);
      if (it == table.named.end()) Fail(std::string("undefined ") + what + " " + Quote(a[3]));
      value = it->second;  // by-value copy: later changes to the template do not propagate
    }
    auto [it, inserted] = table.named.try_emplace(std::string(a[1]));
    it->second = std::move(value);
    table.current = &it->second;
    *defined = true;
    return;
  }
  Fail(std::string(a.keyword()) + ": expected [id [= [template]]]");
}

void MgfReader::ContextEntity(Kind kind, const Args& a) {
  switch (kind) {
    case Kind::kColor: {
      bool defined;
      SelectContext(colors_, a, "colour", &defined);
      return;
    }
    case Kind::kCxy: {
      ExpectCount(a, 2, 2, "2 arguments (x y)");
      const double x = Number(a, 1), y = Number(a, 2);
      // §3 cxy wants x, y > 0 and x + y < 1; like mgflib we reject only negative values and
      // x + y > 1 (the hospital scene has "cxy 0 .38" and "cxy .4 0").
      if (x < 0.0 || y < 0.0 || x + y > 1.0) {
        Fail("cxy: chromaticity (" + std::string(a[1]) + ", " + std::string(a[2]) +
             ") is outside the CIE diagram (need x >= 0, y >= 0, x + y <= 1)");
      }
      if (y < kMinChromaY) {
        // (Almost) no luminance: the colour of a luminance-normalised value would be infinite.
        Warn("cxy: y = " + std::string(a[2]) + " is a colour without luminance; neutral grey used instead");
        *colors_.current = Chroma{};
        return;
      }
      *colors_.current = Chroma{x, y};
      return;
    }
    case Kind::kCspec: {
      if (a.size() < 5) Fail("cspec: expected l_min l_max and at least 2 values");
      const double lmin = Number(a, 1), lmax = Number(a, 2);
      if (!(lmin < lmax)) Fail("cspec: l_min must be less than l_max");
      std::vector<double> v;
      v.reserve(a.size() - 3);
      for (size_t i = 3; i < a.size(); ++i) v.push_back(Number(a, i));
      double x, y;
      if (!mgf::SpectrumToXy(lmin, lmax, v.data(), v.size(), &x, &y)) {
        Fail("cspec: the spectrum has no positive luminance in 380-780 nm");
      }
      *colors_.current = Chroma{x, y};
      return;
    }
    case Kind::kCct: {
      ExpectCount(a, 1, 1, "1 argument (temperature in K)");
      const double t = Number(a, 1);
      if (!(t > 0.0)) Fail("cct: temperature must be positive");
      Chroma c;
      if (!mgf::BlackbodyToChroma(t, &c)) Fail("cct: temperature " + Quote(a[1]) + " gives no visible light");
      *colors_.current = c;
      return;
    }
    case Kind::kCmix: {
      if (a.size() < 3 || (a.size() - 1) % 2 != 0) {
        Fail("cmix: expected pairs of weight and colour name");
      }
      // Weights are relative luminances (§3 cmix); summing per-unit-luminance XYZ is exactly
      // the spectral mix for spectral colours and needs no spectrum for (x,y) colours.
      Vec3d xyz;
      for (size_t i = 1; i + 1 < a.size(); i += 2) {
        const double w = Number(a, i);
        const auto it = colors_.named.find(a[i + 1]);
        if (it == colors_.named.end()) Fail("undefined colour " + Quote(a[i + 1]));
        xyz += it->second.XyzPerLuminance() * w;
      }
      Chroma c;
      if (!XyzToChroma(xyz, &c)) Fail("cmix: the mixture has no positive luminance");
      *colors_.current = c;
      return;
    }
    case Kind::kMaterial: {
      bool defined;
      SelectContext(materials_, a, "material", &defined);
      if (defined) materials_.current->name = std::string(a[1]);
      if (defined || a.size() == 1) materials_.current->cached = kNone;
      return;
    }
    case Kind::kSides: {
      ExpectCount(a, 1, 1, "1 argument (1 or 2)");
      const long s = Integer(a, 1);
      if (s != 1 && s != 2) Fail("sides: must be 1 or 2");
      Mat().sides = static_cast<int>(s);
      return;
    }
    case Kind::kRd:
    case Kind::kTd:
    case Kind::kEd:
    case Kind::kRs:
    case Kind::kTs:
      MaterialComponent(kind, a);
      return;
    case Kind::kIr: {
      ExpectCount(a, 2, 2, "2 arguments (n_real n_imag)");
      const double n = Number(a, 1), k = Number(a, 2);
      if (!(n > 0.0)) Fail("ir: the real index of refraction must be positive");
      if (n > kMaxMaterialValue) Fail("ir: the index of refraction is out of range");
      if (k != 0.0) {
        Warn("ir: imaginary part " + std::string(a[2]) + " ignored (metals are rendered as dielectrics)");
      }
      Mat().ir_n = n;
      Mat().ir_k = k;
      return;
    }
    case Kind::kVertex: {
      bool defined;
      SelectContext(vertices_, a, "vertex", &defined);
      return;
    }
    case Kind::kPoint:
      ExpectCount(a, 3, 3, "3 arguments (x y z)");
      vertices_.current->p = {Number(a, 1), Number(a, 2), Number(a, 3)};
      return;
    case Kind::kNormal:
      ExpectCount(a, 3, 3, "3 arguments (dx dy dz)");
      // §3 n: normalised; a zero vector means "no normal".
      vertices_.current->n = geometry::SafeNormalize({Number(a, 1), Number(a, 2), Number(a, 3)});
      return;
    default:  // not a context entity (Dispatch routes only c, cxy, ..., v, p, n here)
      return;
  }
}

// rd td ed rs ts (§3): a value (rs and ts also a roughness) and the colour in effect now, which
// the value keeps (§2.1).
void MgfReader::MaterialComponent(Kind kind, const Args& a) {
  struct Component {
    Kind kind;
    const char* usage;
    const char* what;
    double MaterialCtx::*value;
    double MaterialCtx::*alpha;  // the roughness, or null
    Chroma MaterialCtx::*color;
  };
  static constexpr Component kComponents[] = {
      {Kind::kRd, "1 argument (rho_d)", "reflectance", &MaterialCtx::rd, nullptr, &MaterialCtx::rd_c},
      {Kind::kTd, "1 argument (tau_d)", "transmittance", &MaterialCtx::td, nullptr, &MaterialCtx::td_c},
      {Kind::kEd, "1 argument (epsilon_d in lm/m^2)", "emittance", &MaterialCtx::ed, nullptr,
       &MaterialCtx::ed_c},
      {Kind::kRs, "2 arguments (rho_s alpha_r)", "reflectance", &MaterialCtx::rs, &MaterialCtx::rs_alpha,
       &MaterialCtx::rs_c},
      {Kind::kTs, "2 arguments (tau_s alpha_t)", "transmittance", &MaterialCtx::ts, &MaterialCtx::ts_alpha,
       &MaterialCtx::ts_c},
  };
  const Component& c = *std::find_if(std::begin(kComponents), std::end(kComponents),
                                     [kind](const Component& x) { return x.kind == kind; });
  const size_t count = c.alpha ? 2 : 1;
  ExpectCount(a, count, count, c.usage);
  // An emittance is unbounded (lm/m²); reflectances and transmittances are fractions.
  Mat().*c.value = kind == Kind::kEd ? NonNegative(a, 1, c.what) : Fraction(a, 1, c.what);
  if (c.alpha) Mat().*c.alpha = NonNegative(a, 2, "roughness");
  Mat().*c.color = CurrentColor();
}

const VertexCtx& MgfReader::NamedVertex(std::string_view name) const {
  const auto it = vertices_.named.find(name);
  if (it == vertices_.named.end()) Fail("undefined vertex " + Quote(name));
  return it->second;
}

MaterialCtx& MgfReader::Mat() {
  MaterialCtx& m = *materials_.current;
  m.cached = kNone;  // about to be modified
  return m;
}

uint32_t MgfReader::MaterialIndex() {
  MaterialCtx& m = *materials_.current;
  if (m.cached != kNone) return m.cached;
  Material out;
  out.name = m.name;
  out.diffuse_reflectance = ChromaRgb(m.rd_c) * static_cast<float>(m.rd);
  out.specular_reflectance = ChromaRgb(m.rs_c) * static_cast<float>(m.rs);
  out.specular_roughness = static_cast<float>(m.rs_alpha);
  out.diffuse_transmittance = ChromaRgb(m.td_c) * static_cast<float>(m.td);
  out.specular_transmittance = ChromaRgb(m.ts_c) * static_cast<float>(m.ts);
  out.transmission_roughness = static_cast<float>(m.ts_alpha);
  out.ior = static_cast<float>(m.ir_n);
  out.one_sided = m.sides == 1;
  // Luminous emittance (lm/m²) of a Lambertian emitter -> radiance in W/(m²·sr): divide by π
  // and by the luminous efficacy of white light; the colour has luminance Y = 1.
  out.emission = ChromaRgb(m.ed_c) * static_cast<float>(m.ed / (kPiD * mgf::kLuminousEfficacy));
  // Energy conservation (§3 m: "the sum ... must not be greater than one").
  // Saturated colours can push a channel above 1 even when the photometric values obey it.
  const Rgb sum = out.diffuse_reflectance + out.specular_reflectance + out.diffuse_transmittance +
                  out.specular_transmittance;
  const float max_sum = sum.Max();
  if (max_sum > 1.0f) {
    const float s = 1.0f / max_sum;
    out.diffuse_reflectance *= s;
    out.specular_reflectance *= s;
    out.diffuse_transmittance *= s;
    out.specular_transmittance *= s;
  }
  std::string key = out.name;
  key += '\0';
  auto put = [&key](const auto& v) { key.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  for (const Rgb* c : {&out.diffuse_reflectance, &out.specular_reflectance, &out.diffuse_transmittance,
                       &out.specular_transmittance, &out.emission}) {
    put(c->r);
    put(c->g);
    put(c->b);
  }
  put(out.specular_roughness);
  put(out.transmission_roughness);
  put(out.ior);
  put(out.one_sided);
  auto [it, inserted] =
      material_index_.try_emplace(std::move(key), static_cast<uint32_t>(scene_.materials.size()));
  if (inserted) {
    if (max_sum > 1.0001f) {  // rounding of "rd 1" with a near-white colour is not worth a word
      Warn("material " + Quote(m.name.empty() ? std::string_view("(unnamed)") : m.name) +
           ": rd+rs+td+ts reaches " + std::to_string(max_sum) + " in a colour channel; scaled down to 1");
    }
    scene_.materials.push_back(std::move(out));
  }
  m.cached = it->second;
  return m.cached;
}

}  // namespace pf::mgf

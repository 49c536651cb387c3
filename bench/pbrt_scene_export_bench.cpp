// A tool, not a timing benchmark: writes a pf scene as a pbrt-v3 scene file, so that pbrt-v3's
// SPPM integrator can render exactly the geometry, materials, lights and camera that pf renders
// (bench/sppm_compare.py, docs/results/sppm.md). It is named *_bench.cpp only so that
// bench/CMakeLists.txt builds it with the other tools that link pf_common.
//
// The scene is read with pf's own LoadScene (manifest, scale, material overrides, tessellation), so
// the triangles are the ones pf traces. What it writes, and why:
//  * Camera. pf's camera has a vertical field of view and image right = forward × up in a
//    right-handed world; pbrt's LookAt builds a left-handed camera frame and its "fov" spans the
//    shorter image axis. `Scale -1 1 1` before LookAt flips the camera's x so the image is not
//    mirrored, and for portrait images the fov is converted to the horizontal one.
//  * Geometry in pf's scene frame (SceneDescription::origin subtracted, the camera moved with it),
//    with an identity object transform, so pbrt's triangle normal is cross(p1 − p0, p2 − p0) —
//    pf's front face — and no handedness swap or ReverseOrientation flips it. Vertex normals are
//    written ("N") only for triangles whose three vertices have one (pf: a zero normal means
//    none), and never for emitters: with "N" pbrt turns the geometric normal towards the shading
//    normal, which would decide the emitting side instead of the winding.
//  * Materials by pf's lobes (common/materials/bsdf.cpp): Lambertian ρd → "matte" Kd (sigma 0);
//    mirror ρs → "mirror" Kr; Fresnel dielectric τs, ior → "glass" Kr 1 Kt τs eta ior (pf reflects
//    with F untinted and refracts with 1 − F tinted by τs: the same); thin transmission (ior 1) →
//    "glass" with eta 1 (F = 0, straight through, weight τs: the same); Lambertian + mirror →
//    "mix" of matte 2ρd and mirror 2ρs at 0.5 (pbrt scales each by the amount: exact). Everything
//    else (Ward glossy, diffuse transmission, GGX lobes, textures, alpha masks) is mapped to the
//    nearest of these and listed on stderr as approximated.
//  * Emitters: AreaLightSource "diffuse" "rgb L" = pf's Le, one-sided like pf's (front face only).
//    Point and directional lights are exact ("point" I, "distant" L = E⊥); spots get pbrt's cone
//    falloff (approximated); an environment is left out (warned).
//  * Integrator: "sppm" (iterations, photonsperiteration, radius, maxdepth) or "path" (to check an
//    export against the scene's path-traced reference). maxdepth defaults to 64: pbrt's default 5
//    would cut paths pf continues with Russian roulette and render darker.
//
//   build/bench/pbrt_scene_export_bench MANIFEST -o scene.pbrt --image out.exr [--res WxH]
//       [--integrator sppm|path] [--iterations N] [--photons-per-iteration N] [--radius R]
//       [--maxdepth D] [--spp N]
// Exit status 0 with warnings on stderr for each approximation; 2 for usage, 3 for a scene error.
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/scene/scene.h"
#include "common/scene/scene_loader.h"

using namespace pf;

namespace {

struct Options {
  std::string manifest, output, image = "pbrt.exr", integrator = "sppm";
  int width = 0, height = 0;  // 0: the camera's
  int iterations = 64, photons_per_iteration = -1, maxdepth = 64, spp = 64;
  double radius = 1.0;
};

std::string Num(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

std::string RgbParam(const char* name, const Rgb& c) {
  return std::string("\"rgb ") + name + "\" [" + Num(c.r) + " " + Num(c.g) + " " + Num(c.b) + "]";
}

Rgb Scaled(const Rgb& c, float s) {
  return Rgb(c.r * s, c.g * s, c.b * s);
}

// The pbrt Material statement nearest to pf's material; appends what it could not keep to *approx.
std::string PbrtMaterial(const Material& m, std::vector<std::string>* approx) {
  const auto note = [&](const std::string& what) { approx->push_back("material '" + m.name + "': " + what); };
  if (IsTextured(m)) note("textures ignored (base colour factors only)");
  if (m.HasAlphaMask()) note("alpha mask ignored (opaque)");
  if (m.microfacet == Material::Microfacet::kConductor)
    note("GGX conductor (Schlick F0 = rho_s) exported as an untinted-Fresnel mirror / matte");
  const bool transmits = !m.specular_transmittance.IsBlack();
  if (transmits) {
    if (!m.diffuse_reflectance.IsBlack() || !m.specular_reflectance.IsBlack() ||
        !m.diffuse_transmittance.IsBlack())
      note("rho_d, rho_s, tau_d of a transmitting material dropped (pf ignores them too for a dielectric)");
    const bool dielectric = std::fabs(m.ior - 1.0f) > 1e-4f && m.ior > 0.0f;
    std::string s = "Material \"glass\" \"rgb Kr\" [1 1 1] " + RgbParam("Kt", m.specular_transmittance) +
                    " \"float eta\" [" + Num(dielectric ? m.ior : 1.0) + "]";
    if (m.microfacet == Material::Microfacet::kDielectric && m.microfacet_roughness >= 0.0316f) {
      const double alpha = double(m.microfacet_roughness) * m.microfacet_roughness;
      s += " \"float uroughness\" [" + Num(alpha) + "] \"float vroughness\" [" + Num(alpha) +
           "] \"bool remaproughness\" \"false\"";
      note(
          "GGX rough dielectric exported as pbrt's rough glass (same alpha; different sampling/Fresnel "
          "details)");
    }
    if (m.transmission_roughness > 0.0f) note("transmission roughness ignored (pf renders it smooth too)");
    return s;
  }
  if (!m.diffuse_transmittance.IsBlack()) note("diffuse transmission tau_d dropped");
  const bool has_diffuse = !m.diffuse_reflectance.IsBlack();
  const bool has_specular = !m.specular_reflectance.IsBlack();
  const bool glossy = has_specular && m.specular_roughness >= 1e-4f;
  if (glossy) {
    note("Ward glossy lobe (alpha " + Num(m.specular_roughness) +
         ") exported as pbrt 'plastic' (Trowbridge-Reitz, dielectric Fresnel)");
    return "Material \"plastic\" " + RgbParam("Kd", m.diffuse_reflectance) + " " +
           RgbParam("Ks", m.specular_reflectance) + " \"float roughness\" [" + Num(m.specular_roughness) +
           "] \"bool remaproughness\" \"false\"";
  }
  if (has_specular && has_diffuse) {
    // MixMaterial scales its first material by `amount` and the second by 1 − amount.
    return "MakeNamedMaterial \"" + m.name + "-d\" \"string type\" \"matte\" " +
           RgbParam("Kd", Scaled(m.diffuse_reflectance, 2.0f)) + " \"float sigma\" [0]\n" +
           "MakeNamedMaterial \"" + m.name + "-s\" \"string type\" \"mirror\" " +
           RgbParam("Kr", Scaled(m.specular_reflectance, 2.0f)) + "\n" +
           "Material \"mix\" \"string namedmaterial1\" \"" + m.name + "-d\" \"string namedmaterial2\" \"" +
           m.name + "-s\" \"rgb amount\" [0.5 0.5 0.5]";
  }
  if (has_specular) return "Material \"mirror\" " + RgbParam("Kr", m.specular_reflectance);
  return "Material \"matte\" " + RgbParam("Kd", m.diffuse_reflectance) + " \"float sigma\" [0]";
}

bool HasNormal(const SceneDescription& s, uint32_t v) {
  return !s.normals.empty() && LengthSquared(s.normals[v]) > 0.0f;
}

// One pbrt trianglemesh of the given triangles (re-indexed to the vertices they use).
void WriteMesh(std::ostream& out, const SceneDescription& s, const std::vector<uint32_t>& tris,
               bool normals) {
  std::map<uint32_t, uint32_t> index;
  std::vector<uint32_t> verts;
  for (uint32_t t : tris)
    for (uint32_t v : s.triangles[t])
      if (index.emplace(v, uint32_t(verts.size())).second) verts.push_back(v);
  out << "  Shape \"trianglemesh\"\n    \"integer indices\" [";
  for (uint32_t t : tris)
    for (uint32_t v : s.triangles[t]) out << " " << index[v];
  out << " ]\n    \"point P\" [";
  for (uint32_t v : verts)
    out << " " << Num(s.positions[v].x) << " " << Num(s.positions[v].y) << " " << Num(s.positions[v].z);
  out << " ]\n";
  if (normals) {
    out << "    \"normal N\" [";
    for (uint32_t v : verts) {
      const Vec3 n = Normalize(s.normals[v]);
      out << " " << Num(n.x) << " " << Num(n.y) << " " << Num(n.z);
    }
    out << " ]\n";
  }
}

int Export(const Options& o) {
  SceneDescription scene = LoadScene(o.manifest);
  std::vector<std::string> approx;
  const CameraSpec cam = scene.cameras.empty() ? DefaultCamera(scene) : scene.cameras.front();
  if (scene.cameras.empty()) approx.push_back("no camera in the manifest: pf's DefaultCamera used");
  const int w = o.width > 0 ? o.width : cam.width, h = o.height > 0 ? o.height : cam.height;
  // pbrt's fov spans the shorter axis; pf's is vertical.
  double fov = cam.vfov_degrees;
  if (w < h)
    fov =
        2.0 * std::atan(std::tan(fov * std::numbers::pi / 360.0) * double(w) / h) * 180.0 / std::numbers::pi;
  const Vec3d eye = cam.eye - scene.origin, at = cam.look_at - scene.origin;

  std::ofstream out(o.output);
  if (!out) throw SystemError("cannot write " + o.output);
  out << "# pbrt-v3 scene exported by pbrt_scene_export_bench from " << o.manifest << "\n";
  out << "# camera '" << cam.name << "'; positions in pf's scene frame (origin " << Num(scene.origin.x) << " "
      << Num(scene.origin.y) << " " << Num(scene.origin.z) << " subtracted)\n";
  out << "Scale -1 1 1  # pbrt's LookAt frame is left-handed: flip x so the image is not mirrored\n";
  out << "LookAt " << Num(eye.x) << " " << Num(eye.y) << " " << Num(eye.z) << "  " << Num(at.x) << " "
      << Num(at.y) << " " << Num(at.z) << "  " << Num(cam.up.x) << " " << Num(cam.up.y) << " "
      << Num(cam.up.z) << "\n";
  out << "Camera \"perspective\" \"float fov\" [" << Num(fov) << "]\n";
  out << "Film \"image\" \"integer xresolution\" [" << w << "] \"integer yresolution\" [" << h
      << "] \"string filename\" \"" << o.image << "\"\n";
  out << "PixelFilter \"box\"\n";
  out << "Sampler \"halton\" \"integer pixelsamples\" [" << o.spp << "]\n";
  if (o.integrator == "sppm") {
    out << "Integrator \"sppm\" \"integer iterations\" [" << o.iterations << "] \"integer maxdepth\" ["
        << o.maxdepth << "] \"float radius\" [" << Num(o.radius) << "]";
    if (o.photons_per_iteration > 0)
      out << " \"integer photonsperiteration\" [" << o.photons_per_iteration << "]";
    out << "\n";
  } else {
    out << "Integrator \"path\" \"integer maxdepth\" [" << o.maxdepth << "]\n";
  }
  out << "WorldBegin\n";

  for (const PunctualLight& l : scene.punctual_lights) {
    const Vec3d p = l.position - scene.origin;
    if (l.kind == PunctualLight::Kind::kPoint) {
      out << "LightSource \"point\" " << RgbParam("I", l.intensity) << " \"point from\" [" << Num(p.x) << " "
          << Num(p.y) << " " << Num(p.z) << "]\n";
    } else if (l.kind == PunctualLight::Kind::kDirectional) {
      out << "LightSource \"distant\" " << RgbParam("L", l.intensity)
          << " \"point from\" [0 0 0] \"point to\" [" << Num(l.direction.x) << " " << Num(l.direction.y)
          << " " << Num(l.direction.z) << "]\n";
    } else {
      approx.push_back("spot light '" + l.name +
                       "': pbrt's smoothstep cone falloff instead of pf's quadratic");
      out << "LightSource \"spot\" " << RgbParam("I", l.intensity) << " \"point from\" [" << Num(p.x) << " "
          << Num(p.y) << " " << Num(p.z) << "] \"point to\" [" << Num(p.x + l.direction.x) << " "
          << Num(p.y + l.direction.y) << " " << Num(p.z + l.direction.z) << "] \"float coneangle\" ["
          << Num(l.outer_cone_deg) << "] \"float conedelta\" [" << Num(l.outer_cone_deg - l.inner_cone_deg)
          << "]\n";
    }
  }
  if (scene.environment) approx.push_back("environment light left out");

  // Triangles grouped by (material, light, has-normals); each light gets its own attribute block.
  struct Key {
    uint32_t material, light;
    bool normals;
    auto operator<=>(const Key&) const = default;
  };
  std::map<Key, std::vector<uint32_t>> groups;
  size_t flipped = 0, emitter_normals = 0;
  for (uint32_t t = 0; t < scene.triangles.size(); ++t) {
    const auto& tri = scene.triangles[t];
    const uint32_t light = scene.triangle_light.empty() ? kNoLight : scene.triangle_light[t];
    const uint32_t mat = scene.triangle_material[t];
    const bool emits = light != kNoLight && scene.materials[mat].IsEmissive();
    const Vec3 ng = Normalize(Cross(scene.positions[tri[1]] - scene.positions[tri[0]],
                                    scene.positions[tri[2]] - scene.positions[tri[0]]));
    bool normals = HasNormal(scene, tri[0]) && HasNormal(scene, tri[1]) && HasNormal(scene, tri[2]);
    if (normals && emits) {
      // Only worth a warning if the normals bend the shading (a flat light's equal its face normal).
      for (uint32_t v : tri)
        if (Dot(Normalize(scene.normals[v]), ng) < 0.9998f) {
          ++emitter_normals;
          break;
        }
      normals = false;
    }
    if (normals && Dot(ng, scene.normals[tri[0]] + scene.normals[tri[1]] + scene.normals[tri[2]]) < 0.0f)
      ++flipped;
    groups[Key{mat, emits ? light : kNoLight, normals}].push_back(t);
  }
  if (flipped > 0)
    approx.push_back(std::to_string(flipped) +
                     " triangles' vertex normals oppose their winding: pbrt turns their front face to the "
                     "normals, pf keeps the winding's");
  if (emitter_normals > 0)
    approx.push_back(std::to_string(emitter_normals) +
                     " emitting triangles with curved vertex normals written flat (pbrt would let the "
                     "normals pick the emitting side)");

  std::set<uint32_t> noted;
  for (const auto& [key, tris] : groups) {
    const Material& m = scene.materials[key.material];
    std::vector<std::string> notes;
    const std::string material = PbrtMaterial(m, &notes);
    if (noted.insert(key.material).second) approx.insert(approx.end(), notes.begin(), notes.end());
    out << "AttributeBegin  # material '" << m.name << "'" << (key.light != kNoLight ? ", light " : "")
        << (key.light != kNoLight ? std::to_string(key.light) : "") << ", " << tris.size() << " triangles\n";
    out << "  " << material << "\n";
    if (key.light != kNoLight) out << "  AreaLightSource \"diffuse\" " << RgbParam("L", m.emission) << "\n";
    WriteMesh(out, scene, tris, key.normals);
    out << "AttributeEnd\n";
  }
  out << "WorldEnd\n";
  if (!out) throw SystemError("error writing " + o.output);
  for (const std::string& a : approx) std::fprintf(stderr, "warning: approximated: %s\n", a.c_str());
  std::fprintf(stderr, "wrote %s: %zu triangles in %zu meshes, %zu approximation(s)\n", o.output.c_str(),
               scene.triangles.size(), groups.size(), approx.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  const char* usage =
      "usage: %s MANIFEST -o scene.pbrt [--image out.exr] [--res WxH] [--integrator sppm|path]\n"
      "          [--iterations N] [--photons-per-iteration N] [--radius R] [--maxdepth D] [--spp N]\n";
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "-o")
        o.output = next();
      else if (a == "--image")
        o.image = next();
      else if (a == "--res") {
        const std::string r = next();
        const size_t x = r.find('x');
        if (x == std::string::npos) throw std::invalid_argument("--res wants WxH");
        o.width = std::stoi(r.substr(0, x));
        o.height = std::stoi(r.substr(x + 1));
      } else if (a == "--integrator")
        o.integrator = next();
      else if (a == "--iterations")
        o.iterations = std::stoi(next());
      else if (a == "--photons-per-iteration")
        o.photons_per_iteration = std::stoi(next());
      else if (a == "--radius")
        o.radius = std::stod(next());
      else if (a == "--maxdepth")
        o.maxdepth = std::stoi(next());
      else if (a == "--spp")
        o.spp = std::stoi(next());
      else if (a == "-h" || a == "--help") {
        std::printf(usage, argv[0]);
        return 0;
      } else if (o.manifest.empty() && !a.starts_with("-"))
        o.manifest = a;
      else
        throw std::invalid_argument("unknown argument " + a);
    }
    if (o.manifest.empty() || o.output.empty() || (o.integrator != "sppm" && o.integrator != "path"))
      throw std::invalid_argument("need MANIFEST and -o; --integrator is sppm or path");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    std::fprintf(stderr, usage, argv[0]);
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  try {
    return Export(o);
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}

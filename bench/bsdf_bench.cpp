// The BSDF's cost per call (docs/renderer.md, "Microfacet lobes"): nanoseconds per Bsdf::Sample
// and per Bsdf::Eval + Pdf for Ward's lobes (Lambertian, Ward glossy, smooth dielectric) and the
// GGX ones (conductor, rough dielectric), measured side by side in one run: the materials
// alternate within every repeat, and the medians (and the ratio to the Ward glossy lobe) are
// printed as a table and JSON (docs/results/microfacet-bsdf.md).
//
//   build/bench/bsdf_bench [--repeats 9] [--calls 200000] [--json out.json] [--clock wall|cpu]
//
// Each call builds the Bsdf (as every hit does) from precomputed lobes, with a random wo over
// the upper hemisphere and random numbers from a table made before the clock starts.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_stats.h"
#include "common/core/rng.h"
#include "common/materials/bsdf.h"

namespace pf {
namespace {

struct Case {
  const char* name;
  Material material;
};

std::vector<Case> Cases() {
  Material diffuse{.diffuse_reflectance = Rgb(0.8f)};
  Material ward{.specular_reflectance = Rgb(0.8f), .specular_roughness = 0.2f};
  Material glass{.specular_transmittance = Rgb(1.0f), .ior = 1.5f};
  Material metal{.specular_reflectance = Rgb(0.9f, 0.6f, 0.3f),
                 .microfacet = Material::Microfacet::kConductor,
                 .microfacet_roughness = 0.45f};  // α 0.2, as the Ward lobe
  Material rough_glass{.specular_transmittance = Rgb(1.0f),
                       .ior = 1.5f,
                       .microfacet = Material::Microfacet::kDielectric,
                       .microfacet_roughness = 0.45f};
  return {{"lambertian", diffuse},
          {"ward_glossy", ward},
          {"smooth_dielectric", glass},
          {"ggx_conductor", metal},
          {"ggx_dielectric", rough_glass}};
}

struct Inputs {
  std::vector<Vec3> wo, wi;
  std::vector<float> u;  // 3 per call
};

Inputs MakeInputs(int calls) {
  Inputs in;
  Rng rng(42, 7);
  auto hemisphere = [&](bool upper) {
    const float z = std::max(1e-3f, rng.Uniform());
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = kTwoPi * rng.Uniform();
    return Vec3(r * std::cos(phi), r * std::sin(phi), upper ? z : -z);
  };
  for (int i = 0; i < calls; ++i) {
    in.wo.push_back(hemisphere(true));
    in.wi.push_back(hemisphere(i % 4 != 0));  // a quarter below: transmission for the dielectrics
    for (int k = 0; k < 3; ++k) in.u.push_back(rng.Uniform());
  }
  return in;
}

template <typename F>
double NsPerCall(bool cpu_clock, int calls, F&& f) {
  const double s = cpu_clock ? bench::CpuTimeIt(f) : bench::TimeIt(f);
  return s * 1e9 / calls;
}

int Run(int repeats, int calls, const std::string& json_path, bool cpu_clock) {
  const std::vector<Case> cases = Cases();
  std::vector<BsdfLobes> lobes;
  for (const Case& c : cases) lobes.push_back(BsdfLobes::Of(c.material));
  const Inputs in = MakeInputs(calls);
  const Vec3 n(0, 0, 1);
  std::vector<std::vector<double>> sample_ns(cases.size()), eval_ns(cases.size());
  double sink = 0;
  for (int r = 0; r < repeats; ++r) {
    for (size_t c = 0; c < cases.size(); ++c) {
      sample_ns[c].push_back(NsPerCall(cpu_clock, calls, [&] {
        for (int i = 0; i < calls; ++i) {
          const Bsdf bsdf(cases[c].material, lobes[c], n, n);
          const auto s = bsdf.Sample(in.wo[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2]);
          if (s) sink += s->weight.r;
        }
      }));
      eval_ns[c].push_back(NsPerCall(cpu_clock, calls, [&] {
        for (int i = 0; i < calls; ++i) {
          const Bsdf bsdf(cases[c].material, lobes[c], n, n);
          sink += bsdf.Eval(in.wo[i], in.wi[i]).r + bsdf.Pdf(in.wo[i], in.wi[i]);
        }
      }));
    }
  }
  nlohmann::json out;
  const double ward_sample = bench::Median(sample_ns[1]), ward_eval = bench::Median(eval_ns[1]);
  std::printf("BSDF cost per call, 1 thread, %d calls, median of %d (%s clock); ratio to ward_glossy\n",
              calls, repeats, cpu_clock ? "CPU" : "wall");
  std::printf("%-18s %12s %8s %16s %8s\n", "material", "Sample ns", "ratio", "Eval+Pdf ns", "ratio");
  for (size_t c = 0; c < cases.size(); ++c) {
    const double s = bench::Median(sample_ns[c]), e = bench::Median(eval_ns[c]);
    std::printf("%-18s %12.1f %8.2f %16.1f %8.2f\n", cases[c].name, s, s / ward_sample, e, e / ward_eval);
    out["materials"][cases[c].name] = {{"sample_ns", s},
                                       {"eval_pdf_ns", e},
                                       {"sample_ratio_to_ward", s / ward_sample},
                                       {"eval_pdf_ratio_to_ward", e / ward_eval}};
  }
  out["config"] = {
      {"repeats", repeats}, {"calls", calls}, {"clock", cpu_clock ? "cpu" : "wall"}, {"sink", sink}};
  const std::string text = out.dump(1);
  std::printf("\n%s\n", text.c_str());
  if (!json_path.empty()) {
    std::ofstream file(json_path);
    file << text << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  std::map<std::string, std::string> options{
      {"--repeats", "9"}, {"--calls", "200000"}, {"--json", ""}, {"--clock", "wall"}};
  for (int i = 1; i < argc; i += 2) {
    const auto it = options.find(argv[i]);
    if (it == options.end() || i + 1 >= argc) {
      std::fprintf(stderr, "usage: bsdf_bench [--repeats N] [--calls N] [--json FILE] [--clock wall|cpu]\n");
      return 2;
    }
    it->second = argv[i + 1];
  }
  return pf::Run(std::stoi(options["--repeats"]), std::stoi(options["--calls"]), options["--json"],
                 options["--clock"] == "cpu");
}

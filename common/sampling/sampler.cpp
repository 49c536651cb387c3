#include "common/sampling/sampler.h"

namespace pf {

const char* SamplerName(SamplerKind kind) {
  return kind == SamplerKind::kSobol ? "sobol" : "independent";
}

std::optional<SamplerKind> ParseSamplerKind(std::string_view name) {
  if (name == "sobol") return SamplerKind::kSobol;
  if (name == "independent") return SamplerKind::kIndependent;
  return std::nullopt;
}

}  // namespace pf

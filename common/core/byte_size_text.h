#pragma once
// Sizes as people type them on command lines: "500M", "2G", "64K", "1T" or plain bytes (binary
// units: K = 1024; pf-coordinator --maps-quota, docs/farm.md "The map store's quota").

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include "common/core/error.h"
#include "common/core/unit_text.h"

namespace pf {

// Bytes; InputError naming `what` (if not empty: a CLI11 check names the option itself) for anything
// else (negative, not finite, another unit, over 2^63).
inline uint64_t ParseByteSizeText(const std::string& text, const std::string& what) {
  constexpr double kK = 1024.0;
  const std::optional<double> bytes = ParseUnitText(text,
                                                    {{"K", kK},
                                                     {"KB", kK},
                                                     {"M", kK * kK},
                                                     {"MB", kK * kK},
                                                     {"G", kK * kK * kK},
                                                     {"GB", kK * kK * kK},
                                                     {"T", kK * kK * kK * kK},
                                                     {"TB", kK * kK * kK * kK}},
                                                    /*ignore_case=*/true);
  if (!bytes || *bytes >= 9.2e18)
    throw InputError((what.empty() ? "" : what + ": ") + "'" + text +
                     "' is not a size (bytes, or a number with K, M, G or T: 500M, 2G)");
  return uint64_t(std::llround(*bytes));
}

// "" if `text` is a size ParseByteSizeText accepts, else why not (CLI11's check()).
inline std::string ByteSizeTextProblem(const std::string& text) {
  return UnitTextProblem(text, ParseByteSizeText);
}

}  // namespace pf

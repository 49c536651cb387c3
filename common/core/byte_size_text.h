#pragma once
// Sizes as people type them on command lines: "500M", "2G", "64K", "1T" or plain bytes (binary
// units: K = 1024; pf-coordinator --maps-quota, docs/farm.md "The map store's quota").

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>

#include "common/core/error.h"

namespace pf {

// Bytes; InputError naming `what` (if not empty: a CLI11 check names the option itself) for anything
// else (negative, not finite, another unit, over 2^63).
inline uint64_t ParseByteSizeText(const std::string& text, const std::string& what) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  double unit = -1;
  if (ec == std::errc{} && ptr == end) {
    unit = 1;
  } else if (ec == std::errc{} && (ptr + 1 == end || (ptr + 2 == end && (ptr[1] == 'B' || ptr[1] == 'b')))) {
    switch (*ptr) {
      case 'K':
      case 'k':
        unit = 1024.0;
        break;
      case 'M':
      case 'm':
        unit = 1024.0 * 1024;
        break;
      case 'G':
      case 'g':
        unit = 1024.0 * 1024 * 1024;
        break;
      case 'T':
      case 't':
        unit = 1024.0 * 1024 * 1024 * 1024;
        break;
      default:
        break;
    }
  }
  const double bytes = value * unit;
  if (unit < 0 || !std::isfinite(value) || value < 0 || bytes >= 9.2e18)
    throw InputError((what.empty() ? "" : what + ": ") + "'" + text +
                     "' is not a size (bytes, or a number with K, M, G or T: 500M, 2G)");
  return uint64_t(std::llround(bytes));
}

// "" if `text` is a size ParseByteSizeText accepts, else why not: a command-line option's validator
// (CLI11's check()).
inline std::string ByteSizeTextProblem(const std::string& text) {
  try {
    ParseByteSizeText(text, "");
    return {};
  } catch (const InputError& e) {
    return e.what();
  }
}

}  // namespace pf

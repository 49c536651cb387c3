#pragma once
// Durations as people type them on command lines: "7d", "12h", "30m", "45s" or plain seconds
// (pf purge --older-than, pf-coordinator --retain-finished; docs/farm.md "Deleting jobs").

#include <charconv>
#include <cmath>
#include <string>

#include "common/core/error.h"

namespace pf {

// Seconds; InputError naming `what` (if not empty: a CLI11 check names the option itself) for
// anything else (negative, not finite, another unit).
inline double ParseDurationText(const std::string& text, const std::string& what) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  double unit = -1;
  if (ec == std::errc{} && ptr == end) {
    unit = 1;
  } else if (ec == std::errc{} && ptr + 1 == end) {
    unit = *ptr == 's' ? 1 : *ptr == 'm' ? 60 : *ptr == 'h' ? 3600 : *ptr == 'd' ? 86400 : -1;
  }
  if (unit < 0 || !std::isfinite(value) || value < 0)
    throw InputError((what.empty() ? "" : what + ": ") + "'" + text +
                     "' is not a duration (seconds, or a number with s, m, h or d: 7d, 12h)");
  return value * unit;
}

// "" if `text` is a duration ParseDurationText accepts, else why not: a command-line option's
// validator (CLI11's check()).
inline std::string DurationTextProblem(const std::string& text) {
  try {
    ParseDurationText(text, "");
    return {};
  } catch (const InputError& e) {
    return e.what();
  }
}

}  // namespace pf

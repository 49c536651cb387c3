#pragma once
// Durations as people type them on command lines: "7d", "12h", "30m", "45s" or plain seconds
// (pf purge --older-than, pf-coordinator --retain-finished; docs/farm.md "Deleting jobs").

#include <optional>
#include <string>

#include "common/core/error.h"
#include "common/core/unit_text.h"

namespace pf {

// Seconds; InputError naming `what` (if not empty: a CLI11 check names the option itself) for
// anything else (negative, not finite, another unit).
inline double ParseDurationText(const std::string& text, const std::string& what) {
  const std::optional<double> seconds =
      ParseUnitText(text, {{"s", 1.0}, {"m", 60.0}, {"h", 3600.0}, {"d", 86400.0}});
  if (!seconds)
    throw InputError((what.empty() ? "" : what + ": ") + "'" + text +
                     "' is not a duration (seconds, or a number with s, m, h or d: 7d, 12h)");
  return *seconds;
}

// "" if `text` is a duration ParseDurationText accepts, else why not (CLI11's check()).
inline std::string DurationTextProblem(const std::string& text) {
  return UnitTextProblem(text, ParseDurationText);
}

}  // namespace pf

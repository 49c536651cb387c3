#pragma once
// A number with an optional unit suffix, as people type them on command lines ("7d", "500M"): the
// one parser behind durations (duration_text.h) and sizes (byte_size_text.h).

#include <charconv>
#include <cmath>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "common/core/error.h"

namespace pf {

// value × the factor of its suffix (no suffix: 1), or nothing for anything else: no number, an
// unknown suffix, a negative or non-finite value. Suffixes compare exactly unless ignore_case.
inline std::optional<double> ParseUnitText(std::string_view text,
                                           std::initializer_list<std::pair<std::string_view, double>> units,
                                           bool ignore_case = false) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc{} || !std::isfinite(value) || value < 0) return std::nullopt;
  const std::string_view suffix(ptr, size_t(end - ptr));
  if (suffix.empty()) return value;
  const auto same = [ignore_case](std::string_view a, std::string_view b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i) {
      const char x = ignore_case && a[i] >= 'a' && a[i] <= 'z' ? char(a[i] - 32) : a[i];
      const char y = ignore_case && b[i] >= 'a' && b[i] <= 'z' ? char(b[i] - 32) : b[i];
      if (x != y) return false;
    }
    return true;
  };
  for (const auto& [unit, factor] : units)
    if (same(suffix, unit)) return value * factor;
  return std::nullopt;
}

// "" if parse(text, "") accepts `text`, else its InputError's message: a command-line option's
// validator (CLI11's check()).
template <typename Parse>
std::string UnitTextProblem(const std::string& text, Parse parse) {
  try {
    parse(text, "");
    return {};
  } catch (const InputError& e) {
    return e.what();
  }
}

}  // namespace pf

#include "common/render/render_setting.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

#include "common/core/error.h"
#include "common/core/real_text.h"

namespace pf {

const char* SettingGroupTitle(SettingGroup g) {
  static constexpr const char* kTitles[] = {// SettingGroup's order
                                            "Both integrators",
                                            "Photon maps",
                                            "Radiance estimate",
                                            "Direct light",
                                            "Local pass (final gathering)",
                                            "Importance-driven maps",
                                            "Caustic splitting",
                                            "Farm"};
  return kTitles[int(g)];
}

std::string FormatRenderSettingValue(const RenderSettingValue& v) {
  if (const bool* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
  if (const int64_t* i = std::get_if<int64_t>(&v)) return std::to_string(*i);
  // A float setting's value (every real one but progressive-alpha) as the float's shortest text:
  // 0.05, not 0.05000000074505806 (real_text.h). Still one text per value, so two floats one step
  // apart differ.
  if (const double* d = std::get_if<double>(&v)) return RealText(*d);
  return std::get<std::string>(v);
}

std::string DescribeRenderSettingRange(const RenderSetting& row) {
  switch (row.type) {
    case SettingType::kBool:
      return "true|false";
    case SettingType::kInt:
      return fmt::format("{}..{}", int64_t(row.min), int64_t(row.max));
    case SettingType::kReal:
      if (std::isinf(row.max)) return fmt::format("{} {}", row.min_exclusive ? ">" : ">=", row.min);
      return fmt::format("{}{}, {}]", row.min_exclusive ? "(" : "[", row.min, row.max);
    case SettingType::kChoice: {
      std::string out;
      for (const SettingChoice& c : row.choices) {
        if (!out.empty()) out += '|';
        out += c.name;
      }
      return out;
    }
  }
  return "";
}

void CheckRenderSettingValue(const RenderSetting& row, const RenderSettingValue& v,
                             const std::string& label) {
  switch (row.type) {
    case SettingType::kBool:
      if (!std::holds_alternative<bool>(v)) throw InputError(label + ": must be true or false");
      return;
    case SettingType::kInt: {
      if (!std::holds_alternative<int64_t>(v)) throw InputError(label + ": must be a whole number");
      const int64_t i = std::get<int64_t>(v);
      if (i > int64_t(row.max) && row.max_is_limit)
        throw LimitError(fmt::format("{}: {} exceeds the limit {}", label, i, int64_t(row.max)));
      if (i >= int64_t(row.min) && i <= int64_t(row.max)) return;
      if (row.max_is_limit) throw InputError(fmt::format("{}: must be >= {}", label, int64_t(row.min)));
      if (row.min == 0) throw InputError(fmt::format("{}: must be <= {}", label, int64_t(row.max)));
      throw InputError(label + ": must be in " + DescribeRenderSettingRange(row));
    }
    case SettingType::kReal: {
      if (!std::holds_alternative<double>(v)) throw InputError(label + ": must be a number");
      const double d = std::get<double>(v);
      const bool above_min = row.min_exclusive ? d > row.min : d >= row.min;
      if (std::isfinite(d) && above_min && d <= row.max) return;
      if (std::isinf(row.max))
        throw InputError(label + ": must be a finite number " + DescribeRenderSettingRange(row));
      throw InputError(label + ": must be in " + DescribeRenderSettingRange(row));
    }
    case SettingType::kChoice: {
      const std::string* s = std::get_if<std::string>(&v);
      if (s)
        for (const SettingChoice& c : row.choices)
          if (c.name == *s) return;
      throw InputError(label + ": must be one of " + DescribeRenderSettingRange(row) +
                       (s ? ", got '" + *s + "'" : std::string()));
    }
  }
}

namespace {

template <typename T>
T ParseNumber(std::string_view text, const std::string& label, const char* what) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty())
    throw InputError(label + ": expected " + what + ", got '" + std::string(text) + "'");
  return value;
}

}  // namespace

RenderSettingValue ParseRenderSettingValue(const RenderSetting& row, std::string_view text,
                                           const std::string& label) {
  RenderSettingValue v;
  switch (row.type) {
    case SettingType::kBool:
      if (text == "true" || text == "on" || text == "1" || text == "yes")
        v = true;
      else if (text == "false" || text == "off" || text == "0" || text == "no")
        v = false;
      else
        throw InputError(label + ": expected true or false (on/off, 1/0), got '" + std::string(text) + "'");
      break;
    case SettingType::kInt:
      v = ParseNumber<int64_t>(text, label, "a whole number");
      break;
    case SettingType::kReal:
      v = ParseNumber<double>(text, label, "a number");
      break;
    case SettingType::kChoice:
      v = std::string(text);
      break;
  }
  CheckRenderSettingValue(row, v, label);
  return v;
}

}  // namespace pf

// RenderSettings ↔ JobRenderSettings, driven by the settings table (common/render/
// render_settings_table.h) through protobuf reflection (docs/settings.md, "On the wire").
//
// The wire keeps its typed messages, RenderSettings and PhotonMapSettings, rather than a generic
// name → value map: tools/pf_client.py and every existing client build them with typed setters,
// stored jobs decode unchanged, and a typo in a field name is a compile error for a client rather
// than a job refused at run time. What the table adds is that no code here names a setting: a row
// `caustic-radius` is the field `caustic_radius` of RenderSettings or PhotonMapSettings, a choice
// `photon-direct` the enum value <PREFIX>_PHOTON_DIRECT (the prefix is that of the enum's
// <PREFIX>_UNSPECIFIED; a choice may name its value when it differs: mc ↔ MONTE_CARLO). Adding a
// setting = one table row + one proto field; tests/proto/settings_convert_test.cpp fails when
// either is missing.
//
// Proto3 cannot tell an unset number from 0. A field reads as the setting's default when it is
// unset — explicit presence (`optional`), an enum's UNSPECIFIED, or a 0 that the row's range
// excludes (caustic_split 0 = off), or any photon-map field of a path job — except for the
// settings a job must state (the integrator, and photons and k of a photon-map job), for which 0
// is refused. SettingsToProto leaves a default
// unset where it reads back as the default, so that a spec holds what its sender chose; the
// progressive plan's α is written even at its default (WriteProgressiveAlpha: its default changed,
// and a stored progressive job without it resumes with the old one, server/scheduling/recovery.cpp).

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "common/core/error.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"
#include "proto/convert.h"

namespace pf {
namespace v1 = photonfarm::v1;
namespace gp = google::protobuf;

namespace {

struct WireField {
  const gp::FieldDescriptor* field = nullptr;
  bool in_photon_map = false;
};

std::string SnakeCase(std::string_view kebab) {
  std::string s(kebab);
  for (char& c : s) c = c == '-' ? '_' : c;
  return s;
}

// The field of the row, in RenderSettings or its photon_map.
WireField WireFieldOf(const RenderSetting& row) {
  const std::string name = SnakeCase(row.name);
  if (const gp::FieldDescriptor* f = v1::RenderSettings::descriptor()->FindFieldByName(name))
    return {f, false};
  if (const gp::FieldDescriptor* f = v1::PhotonMapSettings::descriptor()->FindFieldByName(name))
    return {f, true};
  throw std::logic_error("settings table: no field " + name + " in RenderSettings or PhotonMapSettings");
}

// The enum value of a choice: <PREFIX>_<WIRE>, PREFIX from <PREFIX>_UNSPECIFIED.
const gp::EnumValueDescriptor* EnumValueOf(const gp::FieldDescriptor* f, const SettingChoice& c) {
  const gp::EnumDescriptor* e = f->enum_type();
  std::string prefix = e->FindValueByNumber(0)->name();
  prefix.resize(prefix.size() - std::string_view("UNSPECIFIED").size());
  std::string wire = c.wire.empty() ? SnakeCase(c.name) : std::string(c.wire);
  for (char& ch : wire) ch = char(std::toupper(static_cast<unsigned char>(ch)));
  const gp::EnumValueDescriptor* v = e->FindValueByName(prefix + wire);
  if (!v) throw std::logic_error("settings table: no enum value " + prefix + wire);
  return v;
}

// A setting a job must state: 0 (unset) is refused instead of read as the default.
bool Required(const RenderSetting& row, IntegratorKind integrator) {
  if (row.name == "integrator") return true;
  return integrator == IntegratorKind::kPhotonMap && (row.name == "photons" || row.name == "k");
}

// Whether 0 (or false) in a field without presence reads as the row's default.
bool ZeroReadsAsDefault(const RenderSetting& row, IntegratorKind integrator) {
  if (Required(row, integrator)) return false;
  // A path job carries only the photon-map settings someone changed (SettingsToProto).
  if (row.PhotonMapOnly() && integrator != IntegratorKind::kPhotonMap) return true;
  const RenderSettingValue d = DefaultRenderSettingValue(row);
  if (d == RenderSettingValue(false) || d == RenderSettingValue(int64_t(0)) || d == RenderSettingValue(0.0))
    return true;
  return row.type != SettingType::kBool && (row.min > 0 || (row.min == 0 && row.min_exclusive));
}

// Whether the field left unset reads as the row's default (see the top of the file).
bool UnsetReadsAsDefault(const RenderSetting& row, const gp::FieldDescriptor* f, IntegratorKind integrator) {
  if (Required(row, integrator)) return false;
  return f->has_presence() || f->cpp_type() == gp::FieldDescriptor::CPPTYPE_ENUM ||
         ZeroReadsAsDefault(row, integrator);
}

std::string PathOf(const std::string& field, const WireField& w) {
  return field + (w.in_photon_map ? ".photon_map." : ".") + w.field->name();
}

// The field's value, or nullopt when it reads as the default.
std::optional<RenderSettingValue> ReadField(const RenderSetting& row, const WireField& w,
                                            const gp::Message& m, IntegratorKind integrator,
                                            const std::string& path) {
  const gp::Reflection* r = m.GetReflection();
  const gp::FieldDescriptor* f = w.field;
  if (f->has_presence() && !r->HasField(m, f)) return std::nullopt;
  switch (f->cpp_type()) {
    case gp::FieldDescriptor::CPPTYPE_ENUM: {
      const int number = r->GetEnumValue(m, f);
      if (number == 0 && !Required(row, integrator)) return std::nullopt;
      for (const SettingChoice& c : row.choices)
        if (EnumValueOf(f, c)->number() == number) return RenderSettingValue(std::string(c.name));
      if (number == 0) {
        std::string values;
        for (const SettingChoice& c : row.choices) {
          if (!values.empty()) values += " or ";
          values += EnumValueOf(f, c)->name();
        }
        throw InputError(path + ": must be " + values);
      }
      throw InputError(path + ": unknown value " + std::to_string(number));
    }
    case gp::FieldDescriptor::CPPTYPE_BOOL:
      return RenderSettingValue(r->GetBool(m, f));
    case gp::FieldDescriptor::CPPTYPE_DOUBLE:
    case gp::FieldDescriptor::CPPTYPE_FLOAT: {
      const double d = f->cpp_type() == gp::FieldDescriptor::CPPTYPE_DOUBLE ? r->GetDouble(m, f)
                                                                            : double(r->GetFloat(m, f));
      if (d == 0.0 && !f->has_presence() && ZeroReadsAsDefault(row, integrator)) return std::nullopt;
      return RenderSettingValue(d);
    }
    default: {
      uint64_t u = 0;
      if (f->cpp_type() == gp::FieldDescriptor::CPPTYPE_UINT32) u = r->GetUInt32(m, f);
      if (f->cpp_type() == gp::FieldDescriptor::CPPTYPE_UINT64) u = r->GetUInt64(m, f);
      if (f->cpp_type() == gp::FieldDescriptor::CPPTYPE_INT32) u = uint64_t(std::max(0, r->GetInt32(m, f)));
      if (f->cpp_type() == gp::FieldDescriptor::CPPTYPE_INT64)
        u = uint64_t(std::max<int64_t>(0, r->GetInt64(m, f)));
      if (u == 0 && !f->has_presence() && ZeroReadsAsDefault(row, integrator)) return std::nullopt;
      // Above int64: over every limit, and refused as such by the range check.
      return RenderSettingValue(
          int64_t(std::min<uint64_t>(u, uint64_t(std::numeric_limits<int64_t>::max()))));
    }
  }
}

void WriteField(const RenderSetting& row, const WireField& w, const RenderSettingValue& v, gp::Message* m) {
  const gp::Reflection* r = m->GetReflection();
  const gp::FieldDescriptor* f = w.field;
  switch (f->cpp_type()) {
    case gp::FieldDescriptor::CPPTYPE_ENUM:
      for (const SettingChoice& c : row.choices)
        if (c.name == std::get<std::string>(v)) r->SetEnumValue(m, f, EnumValueOf(f, c)->number());
      return;
    case gp::FieldDescriptor::CPPTYPE_BOOL:
      return r->SetBool(m, f, std::get<bool>(v));
    case gp::FieldDescriptor::CPPTYPE_DOUBLE:
      return r->SetDouble(m, f, std::get<double>(v));
    case gp::FieldDescriptor::CPPTYPE_FLOAT:
      return r->SetFloat(m, f, float(std::get<double>(v)));
    case gp::FieldDescriptor::CPPTYPE_UINT32:
      return r->SetUInt32(m, f, uint32_t(std::get<int64_t>(v)));
    case gp::FieldDescriptor::CPPTYPE_UINT64:
      return r->SetUInt64(m, f, uint64_t(std::get<int64_t>(v)));
    case gp::FieldDescriptor::CPPTYPE_INT32:
      return r->SetInt32(m, f, int32_t(std::get<int64_t>(v)));
    case gp::FieldDescriptor::CPPTYPE_INT64:
      return r->SetInt64(m, f, std::get<int64_t>(v));
    default:
      throw std::logic_error("settings table: unsupported field type of " + f->name());
  }
}

}  // namespace

JobRenderSettings SettingsFromProto(const v1::RenderSettings& s, const std::string& field) {
  JobRenderSettings out;
  std::map<std::string_view, std::string> paths;
  // The table's first row is the integrator: read first, it decides what a job must state.
  for (const RenderSetting& row : RenderSettingsTable()) {
    const WireField w = WireFieldOf(row);
    const std::string& path = paths[row.name] = PathOf(field, w);
    const gp::Message& m = w.in_photon_map ? static_cast<const gp::Message&>(s.photon_map()) : s;
    if (auto v = ReadField(row, w, m, out.integrator, path)) {
      CheckRenderSettingValue(row, *v, path);
      row.set(out, *v);
    }
  }
  CheckRenderSettingRules(out, [&](std::string_view name) { return paths.at(name); });
  return out;
}

void WriteProgressiveAlpha(const JobRenderSettings& s, v1::RenderSettings* out) {
  if (s.integrator == IntegratorKind::kPhotonMap)
    out->mutable_photon_map()->set_progressive_alpha(s.progressive_alpha);
}

void SettingsToProto(const JobRenderSettings& s, v1::RenderSettings* out) {
  v1::PhotonMapSettings pm;
  const JobRenderSettings defaults;
  for (const RenderSetting& row : RenderSettingsTable()) {
    const WireField w = WireFieldOf(row);
    const RenderSettingValue v = row.get(s);
    gp::Message* m = w.in_photon_map ? static_cast<gp::Message*>(&pm) : out;
    const bool at_default = v == row.get(defaults);
    // The path tracer's job carries only the photon-map settings someone changed.
    if (at_default && (UnsetReadsAsDefault(row, w.field, s.integrator) ||
                       (row.PhotonMapOnly() && s.integrator != IntegratorKind::kPhotonMap))) {
      m->GetReflection()->ClearField(m, w.field);
      continue;
    }
    WriteField(row, w, v, m);
  }
  if (s.integrator == IntegratorKind::kPhotonMap || pm.ByteSizeLong() > 0)
    *out->mutable_photon_map() = std::move(pm);
  else
    out->clear_photon_map();
}

}  // namespace pf

#pragma once
// A registry of builders by name (integrators, photon-map structures, plans, material kinds):
// each kind keeps one of {name, kind, builder...} entries, the way pbrt-v4 creates an integrator
// from its name and Mitsuba a plugin from its registered name (docs/design.md, S12). An unknown
// name is the user's error and lists the names there are, so that the message says what to
// write instead.

#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/core/error.h"

namespace pf {

// `Entry` has a `name` (std::string_view) and a `kind` (an enum value), both unique.
template <typename Entry>
class NamedRegistry {
 public:
  // `what` names the registry in messages: "integrator".
  NamedRegistry(std::string_view what, std::vector<Entry> entries)
      : what_(what), entries_(std::move(entries)) {}

  // Every entry, in registration order.
  const std::vector<Entry>& entries() const { return entries_; }
  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const Entry& e : entries_) names.emplace_back(e.name);
    return names;
  }
  // "a, b or c".
  std::string JoinedNames() const {
    std::string out;
    for (size_t i = 0; i < entries_.size(); ++i)
      out += (i == 0 ? "" : i + 1 == entries_.size() ? " or " : ", ") + std::string(entries_[i].name);
    return out;
  }

  // The entry called `name`, or nullptr.
  const Entry* Get(std::string_view name) const {
    for (const Entry& e : entries_)
      if (e.name == name) return &e;
    return nullptr;
  }
  // The entry called `name`; InputError "<label>: no <what> is called 'x' (known: a, b or c)".
  const Entry& Find(std::string_view name, const std::string& label) const {
    if (const Entry* e = Get(name)) return *e;
    throw InputError(label + ": no " + what_ + " is called '" + std::string(name) +
                     "' (known: " + JoinedNames() + ")");
  }

  // The entry of an enum value, or nullptr.
  template <typename Kind>
  const Entry* GetKind(Kind kind) const {
    for (const Entry& e : entries_)
      if (e.kind == kind) return &e;
    return nullptr;
  }
  // The entry of an enum value that must have one (a missing one is a bug: std::logic_error).
  template <typename Kind>
  const Entry& FindKind(Kind kind) const {
    if (const Entry* e = GetKind(kind)) return *e;
    throw std::logic_error(what_ + ": a value without a registry entry");
  }

 private:
  std::string what_;
  std::vector<Entry> entries_;
};

}  // namespace pf

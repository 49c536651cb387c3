// Scene reference confinement; the rule is documented in the header.
#include "common/scene/scene_reference.h"

#include <cstdio>
#include <system_error>

namespace pf {
namespace fs = std::filesystem;

namespace {

constexpr size_t kMaxQuotedBytes = 200;
constexpr const char* kOutside =
    "resolves outside the scene folder (references must stay inside the folder of the scene's "
    "entry file)";

fs::path AbsoluteNormal(const fs::path& p) {
  std::error_code ec;
  fs::path a = fs::absolute(p, ec);
  if (ec) a = p;
  return a.lexically_normal();
}

// True if `p` (normalized, absolute) is `root` or below it.
bool Inside(const fs::path& p, const fs::path& root) {
  const fs::path rel = p.lexically_relative(root);
  return !rel.empty() && *rel.begin() != "..";
}

}  // namespace

std::string QuoteReference(std::string_view reference) {
  std::string out = "'";
  const std::string_view shown = reference.substr(0, kMaxQuotedBytes);
  for (const char ch : shown) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '\n') {
      out += "\\n";
    } else if (u < 0x20 || u == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", u);
      out += buf;
    } else {
      out += ch;
    }
  }
  if (reference.size() > shown.size()) out += "...";
  return out + "'";
}

std::string SceneReferenceProblem(const fs::path& root, const fs::path& base_dir, std::string_view reference,
                                  fs::path* resolved) {
  if (reference.empty()) return "empty file reference";
  for (const char ch : reference) {
    const auto u = static_cast<unsigned char>(ch);
    // A NUL would cut the name the OS sees short of the one checked here.
    if (u < 0x20 || u == 0x7f) return "contains a control character";
  }
  const fs::path rel{std::string(reference)};
  if (rel.has_root_name() || rel.has_root_directory())
    return "is an absolute path (references are relative to the file that makes them and stay "
           "inside the scene folder)";
  const fs::path root_abs = AbsoluteNormal(root);
  const fs::path full = AbsoluteNormal(base_dir / rel);
  if (!Inside(full, root_abs)) return kOutside;

  // Symbolic links: the canonical target must stay inside the canonical root, and no link on the
  // way may dangle (its target could be anywhere; not following it keeps the answer the same
  // whether or not that target exists).
  std::error_code ec;
  const fs::path root_canonical = fs::weakly_canonical(root_abs, ec);
  if (ec) return kOutside;
  fs::path prefix = root_abs;
  for (const fs::path& part : full.lexically_relative(root_abs)) {
    prefix /= part;
    const fs::file_status link = fs::symlink_status(prefix, ec);
    if (ec) break;  // does not exist (or unreadable): nothing further to follow
    if (fs::is_symlink(link) && !fs::exists(prefix, ec)) return kOutside;
  }
  const fs::path canonical = fs::weakly_canonical(full, ec);
  if (ec || !Inside(canonical.lexically_normal(), root_canonical.lexically_normal())) return kOutside;
  if (resolved) *resolved = full;
  return "";
}

}  // namespace pf

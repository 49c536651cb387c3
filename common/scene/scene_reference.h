#pragma once
// Confinement of scene references (docs/security.md, "Scene bundles"). A scene file may name
// other files: an MGF `i` include, a manifest's "geometry", an OBJ's `mtllib`. Every such
// reference resolves only inside the scene's root folder:
//   * on the farm, the root is the bundle's directory (LoadBundle), so the image follows from
//     the bundle's hash alone and a hostile bundle cannot make the coordinator or a worker read
//     (and echo in warnings) files of its host;
//   * for local files (`pf render`, `pf preview`, LoadScene without a root), the root is the
//     folder of the entry file — exactly what CollectBundle ships, so a scene that renders
//     locally renders the same on the farm, and one that would not is refused at once instead
//     of after the upload.
// Refused: empty references, control characters, absolute paths, references whose lexical
// resolution leaves the root ("../x", "a/../../x"), and references that leave it through a
// symbolic link (checked on the canonical path; a dangling link counts as leaving). The
// reason is the same whether or not the target exists, and names nothing but the reference as
// written, so the answer is no oracle for the existence of files outside the root.
// (A race that swaps a file for a link between the check and the open is out of scope: bundle
// directories are written by the coordinator/worker itself and hold regular files only.)

#include <filesystem>
#include <string>
#include <string_view>

namespace pf {

// The reference as it may appear in a message: quoted, control characters escaped (\n, \x1b),
// cut to 200 bytes.
std::string QuoteReference(std::string_view reference);

// Resolves `reference` (written in a file whose folder is `base_dir`) inside `root`. Returns ""
// and sets *resolved (a normalized absolute path) if it stays inside; otherwise the reason,
// e.g. "resolves outside the scene folder (references must stay inside it)".
std::string SceneReferenceProblem(const std::filesystem::path& root, const std::filesystem::path& base_dir,
                                  std::string_view reference, std::filesystem::path* resolved);

}  // namespace pf

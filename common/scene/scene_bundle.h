#pragma once
// Scene bundles: the files a scene is made of, shipped as one content-addressed unit (docs/design.md, §1
// Jobs — "scene bundle (content-addressed: hash of all files; uploaded once, cached by
// workers)"). The client collects a bundle, the coordinator validates and stores it under its
// hash, workers fetch it by hash and load it from a directory; all three use this file pair, so
// the hash is computed identically everywhere.
//
// Collection rule (CollectBundle): the entry file plus every regular file under the entry file's
// directory, recursively, with paths relative to that directory ('/'-separated). This covers
// everything a scene can refer to without parsing it: MGF `i` includes below the entry's folder,
// OBJ + MTL, a manifest and its geometry, a .gltf and its .bin buffers — but no .exr/.png
// (references and previews stored next to a scene are outputs) unless a .gltf in the folder
// refers to it by uri (a texture: an input, gltf_document.h GltfFileReferences), a .mtl names it
// in a map statement (map_Kd ...) or the manifest reads it (its "environment.file"). Files *outside* the
// entry's folder (an MGF include of
// "../x.mgf", a manifest pointing to "/abs/path.obj") are not collected; loading the bundle then
// fails with the loader's file:line message. Keep each scene in its own folder.
//
// Limits: at most kMaxBundleBytes of file content in total and kMaxBundleFiles files; over
// them CollectBundle / ValidateBundle throw InputError naming the limit.
//
// Hash layout (BundleHash): lowercase hex SHA-256 of the byte string
//   "photonfarm-bundle-v1\n"
//   u64le(len(entry)) entry
//   u64le(number of files)
//   for each file, sorted by path (bytewise):  u64le(len(path)) path u64le(len(content)) content
// The entry is part of the identity (the same files with another entry are another scene); the
// order of `files` in the struct does not matter; the length prefixes make the encoding
// injective (no two different bundles produce the same byte string).
//
// Paths inside a bundle: non-empty, relative, '/'-separated, no empty, "." or ".." components,
// no backslash, NUL or other control character, at most 1024 bytes, unique, and no path is a
// folder of another ("a" and "a/b"). ValidateBundle enforces this; WriteBundle
// and LoadBundle call it, so a hostile bundle cannot write outside its directory.

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "common/scene/scene.h"

namespace pf {

inline constexpr uint64_t kMaxBundleBytes = uint64_t(64) << 20;  // 64 MiB of file content
inline constexpr size_t kMaxBundleFiles = 10000;
inline constexpr size_t kMaxBundlePathBytes = 1024;

struct SceneBundle {
  std::string entry;                                       // path of the file to load
  std::vector<std::pair<std::string, std::string>> files;  // (path, content)

  uint64_t TotalBytes() const;
};

// Reads the bundle of `entry` (rule above). The bundle's entry is the entry's file name.
// Throws InputError if `entry` is not a regular file or the folder exceeds the limits,
// SystemError if a file cannot be read.
SceneBundle CollectBundle(const std::filesystem::path& entry);

// Hex SHA-256 over the layout above.
std::string BundleHash(const SceneBundle& bundle);

// Throws InputError naming the offending file ("bundle.files[3].path '../x.mgf': ...") when a path
// breaks the rules above, a path repeats, the entry is missing from the files, or a limit is
// exceeded.
void ValidateBundle(const SceneBundle& bundle);

// Validates, then writes every file under `dir` (created if needed; subfolders as the paths
// say). Existing files of the same name are overwritten. SystemError if the file system fails.
void WriteBundle(const SceneBundle& bundle, const std::filesystem::path& dir);

// Loads the scene of a bundle written to `dir` with WriteBundle. `entry` must obey the path
// rules. Every reference between files stays inside `dir` (scene_reference.h). Loader
// messages name files relative to `dir` ("scene.mgf:12: ..."), as the client knows them, not
// the directory they were stored in.
SceneDescription LoadBundle(const std::filesystem::path& dir, const std::string& entry);

}  // namespace pf

#pragma once
// The one way the project writes a file that a crash must not tear (images, checkpoints, scene
// bundles, the client's downloads; docs/design.md, G3): write a temporary beside the target,
// fsync it, rename(2) it over the target, fsync the directory. Readers see the old file or the
// new one, never a mix, and once the call returns the new one survives a power cut.
//
// Temporaries are named "<dir>/.<name>.tmp-<pid>-<n>" (the same directory, so the rename is
// atomic; the leading dot hides them). A process that finds such names at start-up may remove
// them: IsTemporaryName recognises them.

#include <filesystem>
#include <string>
#include <string_view>

#include "common/core/file_layer.h"

namespace pf {

// Whether the written file must survive a power cut. kVolatile skips both fsyncs and keeps the
// rename's atomicity only: for caches whose every read is verified (a worker's photon-map disk
// cache checks the map's digest and discards a bad file), where an fsync would only put a disk
// flush on the critical path of a render.
enum class Durability { kDurable, kVolatile };

// Throws StorageError (common/core/error.h) naming the path, the failed step and the OS reason;
// the temporary is removed on failure and the target is left as it was. Every system call goes
// through `files` (common/core/file_layer.h), so tests can fail any step.
void WriteFileAtomically(const std::filesystem::path& path, std::string_view bytes,
                         Durability durability = Durability::kDurable, FileLayer& files = SystemFiles());

// A fresh temporary name beside `path`, unique within the process and across processes.
std::filesystem::path TemporarySibling(const std::filesystem::path& path);
bool IsTemporaryName(std::string_view filename);

// Publishes a fully written temporary directory (see TemporarySibling) under `target`, for
// content-addressed artifacts made of several files (scene bundles). Returns false, and
// removes `tmp`, when `target` already exists: an artifact of that name has that content, so
// whoever published first wins. Throws SystemError for other failures.
bool PublishDirectory(const std::filesystem::path& tmp, const std::filesystem::path& target);

// fsync(2) of the directory that holds `path`, so that a rename or a new file in it survives a
// power cut. Returns 0, or the errno of a real failure (EIO, ENOSPC…); a file system that does
// not sync directories at all (EINVAL, EROFS on the directory handle) counts as success.
int SyncParentDirectory(const std::filesystem::path& path, FileLayer& files = SystemFiles());

}  // namespace pf

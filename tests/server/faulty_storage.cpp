#include "tests/server/faulty_storage.h"

#include <sqlite3.h>
#include <unistd.h>

#include <cstring>
#include <stdexcept>

namespace pf::server::testing {

void FaultInjector::Arm(const FaultRule& rule) {
  std::lock_guard lock(mu_);
  rules_.push_back({rule, 0});
}

void FaultInjector::Disarm() {
  std::lock_guard lock(mu_);
  rules_.clear();
}

bool FaultInjector::armed() const {
  std::lock_guard lock(mu_);
  return !rules_.empty();
}

uint64_t FaultInjector::failures() const {
  std::lock_guard lock(mu_);
  return failures_;
}

bool FaultInjector::ShouldFail(FileOp op, std::string_view path, int* error, bool* torn) {
  std::lock_guard lock(mu_);
  bool fail = false;
  for (Armed& a : rules_) {
    const FaultRule& r = a.rule;
    if (r.op != op) continue;
    const size_t at = path.rfind(r.path_part);
    if (at == std::string_view::npos || (r.at_end && at + r.path_part.size() != path.size())) continue;
    const uint64_t n = ++a.matched;
    if (fail || n < r.first_call || n - r.first_call >= r.count) continue;
    fail = true;
    *error = r.error;
    if (torn) *torn = r.torn;
  }
  failures_ += fail;
  return fail;
}

// --- FaultyFiles ---

bool FaultyFiles::Fails(FileOp op, std::string_view path, bool* torn) {
  int error = 0;
  if (!faults_.ShouldFail(op, path, &error, torn)) return false;
  errno = error;
  return true;
}

std::string FaultyFiles::PathOf(int fd) {
  std::lock_guard lock(mu_);
  auto it = paths_.find(fd);
  return it == paths_.end() ? std::string() : it->second;
}

int FaultyFiles::Open(const char* path, int flags, mode_t mode) {
  if (Fails(FileOp::kOpen, path)) return -1;
  const int fd = FileLayer::Open(path, flags, mode);
  if (fd >= 0) {
    std::lock_guard lock(mu_);
    paths_[fd] = path;
  }
  return fd;
}

ssize_t FaultyFiles::Write(int fd, const void* data, size_t size) {
  return PositionedWrite(fd, data, size, ::lseek(fd, 0, SEEK_CUR));
}

ssize_t FaultyFiles::PositionedWrite(int fd, const void* data, size_t size, off_t offset) {
  bool torn = false;
  if (Fails(FileOp::kWrite, PathOf(fd), &torn)) {
    const int error = errno;
    if (torn && size > 1) {
      // The device took half, then filled up: the bytes are in the file, the call reports the error.
      if (FileLayer::PositionedWrite(fd, data, size / 2, offset) < 0) return -1;
    }
    errno = error;
    return -1;
  }
  return FileLayer::PositionedWrite(fd, data, size, offset);
}

int FaultyFiles::Fsync(int fd) {
  if (Fails(FileOp::kFsync, PathOf(fd))) return -1;
  return FileLayer::Fsync(fd);
}

int FaultyFiles::Fdatasync(int fd) {
  if (Fails(FileOp::kFdatasync, PathOf(fd))) return -1;
  return FileLayer::Fdatasync(fd);
}

int FaultyFiles::Ftruncate(int fd, off_t size) {
  if (Fails(FileOp::kFtruncate, PathOf(fd))) return -1;
  return FileLayer::Ftruncate(fd, size);
}

int FaultyFiles::Close(int fd) {
  const std::string path = PathOf(fd);
  {
    std::lock_guard lock(mu_);
    paths_.erase(fd);
  }
  const int rc = FileLayer::Close(fd);  // closed either way, as close(2) does
  if (Fails(FileOp::kClose, path)) return -1;
  return rc;
}

int FaultyFiles::Rename(const char* from, const char* to) {
  if (Fails(FileOp::kRename, to)) return -1;
  return FileLayer::Rename(from, to);
}

int FaultyFiles::Unlink(const char* path) {
  if (Fails(FileOp::kUnlink, path)) return -1;
  return FileLayer::Unlink(path);
}

// --- FaultySqlite: a VFS that forwards everything to the default one ---

namespace {

FaultInjector* g_faults = nullptr;
sqlite3_vfs* g_real = nullptr;
sqlite3_vfs g_vfs;
sqlite3_io_methods g_methods;

constexpr size_t kMaxPath = 1024;
struct FaultyFile {
  sqlite3_file base;  // must be first: SQLite hands us this pointer
  sqlite3_file* real;
  char path[kMaxPath];
};

FaultyFile* F(sqlite3_file* f) {
  return reinterpret_cast<FaultyFile*>(f);
}

int SqliteError(int error, int io_kind) {
  return error == ENOSPC ? SQLITE_FULL : io_kind;
}

int Close(sqlite3_file* f) {
  const int rc = F(f)->real->pMethods->xClose(F(f)->real);
  return rc;
}
int Read(sqlite3_file* f, void* p, int n, sqlite3_int64 off) {
  return F(f)->real->pMethods->xRead(F(f)->real, p, n, off);
}
int Write(sqlite3_file* f, const void* p, int n, sqlite3_int64 off) {
  int error = 0;
  bool torn = false;
  if (g_faults->ShouldFail(FileOp::kSqliteWrite, F(f)->path, &error, &torn)) {
    if (torn && n > 1) F(f)->real->pMethods->xWrite(F(f)->real, p, n / 2, off);
    return SqliteError(error, SQLITE_IOERR_WRITE);
  }
  return F(f)->real->pMethods->xWrite(F(f)->real, p, n, off);
}
int Truncate(sqlite3_file* f, sqlite3_int64 size) {
  return F(f)->real->pMethods->xTruncate(F(f)->real, size);
}
int Sync(sqlite3_file* f, int flags) {
  int error = 0;
  if (g_faults->ShouldFail(FileOp::kSqliteSync, F(f)->path, &error, nullptr))
    return SqliteError(error, SQLITE_IOERR_FSYNC);
  return F(f)->real->pMethods->xSync(F(f)->real, flags);
}
int FileSize(sqlite3_file* f, sqlite3_int64* size) {
  return F(f)->real->pMethods->xFileSize(F(f)->real, size);
}
int Lock(sqlite3_file* f, int l) {
  return F(f)->real->pMethods->xLock(F(f)->real, l);
}
int Unlock(sqlite3_file* f, int l) {
  return F(f)->real->pMethods->xUnlock(F(f)->real, l);
}
int CheckReservedLock(sqlite3_file* f, int* out) {
  return F(f)->real->pMethods->xCheckReservedLock(F(f)->real, out);
}
int FileControl(sqlite3_file* f, int op, void* arg) {
  return F(f)->real->pMethods->xFileControl(F(f)->real, op, arg);
}
int SectorSize(sqlite3_file* f) {
  return F(f)->real->pMethods->xSectorSize(F(f)->real);
}
int DeviceCharacteristics(sqlite3_file* f) {
  return F(f)->real->pMethods->xDeviceCharacteristics(F(f)->real);
}
int ShmMap(sqlite3_file* f, int region, int size, int extend, void volatile** p) {
  if (F(f)->real->pMethods->iVersion < 2) return SQLITE_IOERR_SHMMAP;
  return F(f)->real->pMethods->xShmMap(F(f)->real, region, size, extend, p);
}
int ShmLock(sqlite3_file* f, int offset, int n, int flags) {
  return F(f)->real->pMethods->xShmLock(F(f)->real, offset, n, flags);
}
void ShmBarrier(sqlite3_file* f) {
  F(f)->real->pMethods->xShmBarrier(F(f)->real);
}
int ShmUnmap(sqlite3_file* f, int remove) {
  return F(f)->real->pMethods->xShmUnmap(F(f)->real, remove);
}
int Fetch(sqlite3_file* f, sqlite3_int64 off, int n, void** p) {
  if (F(f)->real->pMethods->iVersion < 3) {
    *p = nullptr;  // "not mapped": SQLite reads instead
    return SQLITE_OK;
  }
  return F(f)->real->pMethods->xFetch(F(f)->real, off, n, p);
}
int Unfetch(sqlite3_file* f, sqlite3_int64 off, void* p) {
  if (F(f)->real->pMethods->iVersion < 3) return SQLITE_OK;
  return F(f)->real->pMethods->xUnfetch(F(f)->real, off, p);
}

int Open(sqlite3_vfs*, const char* name, sqlite3_file* file, int flags, int* out_flags) {
  FaultyFile* f = F(file);
  f->real = reinterpret_cast<sqlite3_file*>(reinterpret_cast<char*>(file) + sizeof(FaultyFile));
  std::strncpy(f->path, name ? name : "", kMaxPath - 1);
  f->path[kMaxPath - 1] = 0;
  const int rc = g_real->xOpen(g_real, name, f->real, flags, out_flags);
  f->base.pMethods = f->real->pMethods ? &g_methods : nullptr;
  return rc;
}

}  // namespace

FaultySqlite::FaultySqlite(FaultInjector& faults) {
  if (g_faults) throw std::logic_error("one FaultySqlite at a time");
  g_faults = &faults;
  g_real = sqlite3_vfs_find(nullptr);
  g_vfs = *g_real;  // forwards every VFS call but xOpen to the default one, with its own pointer
  g_vfs.szOsFile = int(sizeof(FaultyFile)) + g_real->szOsFile;
  g_vfs.zName = "pf-faulty";
  g_vfs.pNext = nullptr;
  g_vfs.xOpen = Open;
  g_vfs.xDelete = [](sqlite3_vfs*, const char* n, int s) { return g_real->xDelete(g_real, n, s); };
  g_vfs.xAccess = [](sqlite3_vfs*, const char* n, int fl, int* o) {
    return g_real->xAccess(g_real, n, fl, o);
  };
  g_vfs.xFullPathname = [](sqlite3_vfs*, const char* n, int sz, char* o) {
    return g_real->xFullPathname(g_real, n, sz, o);
  };
  g_vfs.xRandomness = [](sqlite3_vfs*, int n, char* o) { return g_real->xRandomness(g_real, n, o); };
  g_vfs.xSleep = [](sqlite3_vfs*, int us) { return g_real->xSleep(g_real, us); };
  g_vfs.xCurrentTime = [](sqlite3_vfs*, double* t) { return g_real->xCurrentTime(g_real, t); };
  g_vfs.xGetLastError = [](sqlite3_vfs*, int n, char* o) { return g_real->xGetLastError(g_real, n, o); };
  g_vfs.xCurrentTimeInt64 = [](sqlite3_vfs*, sqlite3_int64* t) {
    return g_real->xCurrentTimeInt64(g_real, t);
  };
  g_vfs.xDlOpen = nullptr;
  g_vfs.xDlError = nullptr;
  g_vfs.xDlSym = nullptr;
  g_vfs.xDlClose = nullptr;
  g_vfs.xSetSystemCall = nullptr;
  g_vfs.xGetSystemCall = nullptr;
  g_vfs.xNextSystemCall = nullptr;
  g_methods = sqlite3_io_methods{3,
                                 Close,
                                 Read,
                                 Write,
                                 Truncate,
                                 Sync,
                                 FileSize,
                                 Lock,
                                 Unlock,
                                 CheckReservedLock,
                                 FileControl,
                                 SectorSize,
                                 DeviceCharacteristics,
                                 ShmMap,
                                 ShmLock,
                                 ShmBarrier,
                                 ShmUnmap,
                                 Fetch,
                                 Unfetch};
  if (sqlite3_vfs_register(&g_vfs, /*makeDflt=*/1) != SQLITE_OK)
    throw std::runtime_error("sqlite3_vfs_register");
}

FaultySqlite::~FaultySqlite() {
  sqlite3_vfs_unregister(&g_vfs);
  sqlite3_vfs_register(g_real, 1);
  g_faults = nullptr;
}

}  // namespace pf::server::testing

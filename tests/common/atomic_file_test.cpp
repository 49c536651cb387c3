// common/core/atomic_file.h: whole-file writes that leave the old or the new file, never a mix,
// and no temporaries behind; directories published once.

#include "common/core/atomic_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>

#include "common/core/error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;

using AtomicFileTest = test_util::TempDirTest;
std::string Read(const fs::path& p) {
  return test_util::ReadFileBytes(p);
}

TEST_F(AtomicFileTest, WritesAndReplacesTheWholeFileAndLeavesNoTemporary) {
  const fs::path file = dir_ / "image.exr";
  WriteFileAtomically(file, std::string("first\0version", 13));
  EXPECT_EQ(Read(file), std::string("first\0version", 13));
  WriteFileAtomically(file, "2");
  EXPECT_EQ(Read(file), "2");
  WriteFileAtomically(file, "");
  EXPECT_EQ(Read(file), "");
  EXPECT_EQ(DirListing(), std::vector<std::string>{"image.exr"});
}

TEST_F(AtomicFileTest, AFailedRenameKeepsTheTargetAndRemovesTheTemporary) {
  // The target is a non-empty directory: rename(2) refuses, the write must fail cleanly.
  const fs::path target = dir_ / "busy";
  fs::create_directories(target / "inside");
  EXPECT_THAT([&] { (void)WriteFileAtomically(target, "bytes"); },
              ::testing::ThrowsMessage<SystemError>(::testing::AllOf(HasSubstr("busy"), HasSubstr("rename"))))
      << "wrote over a directory";
  EXPECT_TRUE(fs::is_directory(target / "inside"));
  EXPECT_EQ(DirListing(), std::vector<std::string>{"busy"});
}

TEST_F(AtomicFileTest, AMissingFolderIsASystemErrorNamingThePath) {
  const fs::path file = dir_ / "no-such-folder" / "out.png";
  EXPECT_THAT([&] { (void)WriteFileAtomically(file, "bytes"); },
              ::testing::ThrowsMessage<SystemError>(
                  ::testing::AllOf(HasSubstr("no-such-folder/out.png"), HasSubstr("open"))))
      << "wrote into a missing folder";
}

TEST_F(AtomicFileTest, TemporaryNamesAreUniqueHiddenAndRecognised) {
  std::set<fs::path> seen;
  for (int i = 0; i < 100; ++i) {
    const fs::path t = TemporarySibling(dir_ / "job-1.acc");
    EXPECT_EQ(t.parent_path(), dir_) << "same folder, so rename is atomic";
    EXPECT_TRUE(IsTemporaryName(t.filename().string())) << t;
    EXPECT_TRUE(seen.insert(t).second) << "repeated " << t;
  }
  EXPECT_FALSE(IsTemporaryName("job-1.acc"));
  EXPECT_FALSE(IsTemporaryName(".hidden"));
  EXPECT_FALSE(IsTemporaryName("scene.tmp-1"));
}

TEST_F(AtomicFileTest, ADirectoryIsPublishedOnceAndTheLoserIsRemoved) {
  const fs::path target = dir_ / "abc123";
  const fs::path first = TemporarySibling(target), second = TemporarySibling(target);
  fs::create_directories(first);
  std::ofstream(first / "scene.mgf") << "first";
  fs::create_directories(second);
  std::ofstream(second / "scene.mgf") << "second";
  EXPECT_TRUE(PublishDirectory(first, target));
  EXPECT_FALSE(PublishDirectory(second, target));
  EXPECT_EQ(Read(target / "scene.mgf"), "first");
  EXPECT_EQ(DirListing(), std::vector<std::string>{"abc123"});
}

}  // namespace
}  // namespace pf

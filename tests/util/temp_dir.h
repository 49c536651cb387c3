#pragma once
// A fresh, empty directory per test, removed with everything in it when the object goes. Shared by
// the unit and farm tests so that each test writes its files where no other test (or a parallel
// ctest run, hence the process id and a counter) can see them.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace pf::test_util {

class TempDir {
 public:
  // `prefix` names the test binary's area ("pf_mgf_test"); the test's suite and name follow.
  // `root`: where (default: the system's temporary directory).
  explicit TempDir(std::string_view prefix,
                   const std::filesystem::path& root = std::filesystem::temp_directory_path()) {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string(prefix) + "_" + std::to_string(::getpid()) + "_" +
                       (info ? std::string(info->test_suite_name()) + "_" + info->name() : "x") + "_" +
                       std::to_string(counter++);
    // Parameterised tests have '/' in their names.
    std::replace(name.begin(), name.end(), '/', '_');
    path_ = root / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

  // Writes `text` to `rel` (below the directory; parent folders are created); returns its path.
  std::filesystem::path Write(const std::string& rel, const std::string& text) const {
    const std::filesystem::path p = path_ / rel;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

  // The names directly in the directory, sorted.
  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  std::filesystem::path path_;
};

// A fixture with a fresh directory `dir_` per test.
class TempDirTest : public ::testing::Test {
 protected:
  std::vector<std::string> DirListing() const { return tmp_.Names(); }
  TempDir tmp_{"pf_test"};
  const std::filesystem::path dir_ = tmp_.path();
};

// The bytes of a file ("" if it cannot be read).
inline std::string ReadFileBytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace pf::test_util

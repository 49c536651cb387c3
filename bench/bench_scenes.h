#pragma once
// The scenes the C++ benchmarks load, by name: scenes/NAME/NAME.json of this source tree
// (PF_SOURCE_DIR, set for every benchmark in bench/CMakeLists.txt).

#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace pf::bench {

// The manifest of the shipped scene `name`.
inline std::string SceneManifest(const std::string& name) {
  return std::string(PF_SOURCE_DIR) + "/scenes/" + name + "/" + name + ".json";
}

// (name, manifest) of each scene, in the order given.
inline std::vector<std::pair<std::string, std::string>> SceneManifests(
    std::initializer_list<const char*> names) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const char* name : names) out.emplace_back(name, SceneManifest(name));
  return out;
}

}  // namespace pf::bench

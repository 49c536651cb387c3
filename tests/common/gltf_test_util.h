#pragma once
// glTF files built in tests: base64 data URIs and a small builder of buffers, views and
// accessors (tests/common/gltf_*_test.cpp).

#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

namespace pf::gltf_test {

inline std::string Base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t n = static_cast<uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size()) n |= static_cast<uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    if (i + 2 < bytes.size()) n |= static_cast<uint32_t>(static_cast<unsigned char>(bytes[i + 2]));
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(n >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[n & 63] : '=';
  }
  return out;
}

inline std::string Floats(std::initializer_list<float> values) {
  std::string out;
  for (float f : values) out.append(reinterpret_cast<const char*>(&f), sizeof f);
  return out;
}

// One buffer; each Add* appends a view and an accessor over it and returns the accessor index.
class GltfBuilder {
 public:
  int AddVec3(std::initializer_list<float> xyz) {
    return Add(Floats(xyz), 5126, "VEC3", int(xyz.size() / 3));
  }
  int AddScalars(std::initializer_list<float> v) { return Add(Floats(v), 5126, "SCALAR", int(v.size())); }
  int AddVec4(std::initializer_list<float> v) { return Add(Floats(v), 5126, "VEC4", int(v.size() / 4)); }
  int AddVec2(std::initializer_list<float> uv) { return Add(Floats(uv), 5126, "VEC2", int(uv.size() / 2)); }
  int AddIndices16(std::initializer_list<uint16_t> indices) {
    std::string bytes;
    for (uint16_t i : indices) bytes.append(reinterpret_cast<const char*>(&i), sizeof i);
    while (bytes.size() % 4 != 0) bytes += '\0';
    return Add(bytes, 5123, "SCALAR", int(indices.size()));
  }
  const std::string& Bin() const { return bin_; }

  // The whole file: asset, the buffer (a data URI, or `buffer_uri`), views, accessors, then
  // `rest` (the other top-level members, comma-separated, without braces).
  std::string Json(const std::string& rest, const std::string& buffer_uri = "") const {
    const std::string uri =
        buffer_uri.empty() ? "data:application/octet-stream;base64," + Base64(bin_) : buffer_uri;
    std::string views, accessors;
    for (const std::string& v : views_) views += (views.empty() ? "" : ",") + v;
    for (const std::string& a : accessors_) accessors += (accessors.empty() ? "" : ",") + a;
    return R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":)" + std::to_string(bin_.size()) +
           R"(,"uri":")" + uri + R"("}],"bufferViews":[)" + views + R"(],"accessors":[)" + accessors + "]," +
           rest + "}";
  }

 private:
  int Add(const std::string& bytes, int component_type, const std::string& type, int count) {
    views_.push_back(R"({"buffer":0,"byteOffset":)" + std::to_string(bin_.size()) + R"(,"byteLength":)" +
                     std::to_string(bytes.size()) + "}");
    accessors_.push_back(R"({"bufferView":)" + std::to_string(views_.size() - 1) + R"(,"componentType":)" +
                         std::to_string(component_type) + R"(,"count":)" + std::to_string(count) +
                         R"(,"type":")" + type + R"("})");
    bin_ += bytes;
    return int(accessors_.size() - 1);
  }
  std::string bin_;
  std::vector<std::string> views_;
  std::vector<std::string> accessors_;
};

}  // namespace pf::gltf_test

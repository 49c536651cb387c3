// glTF accessor reading (gltf_accessors.h).
#include "common/scene/gltf_accessors.h"

#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <string>

#include "common/core/error.h"

namespace pf {

namespace {

struct View {
  const unsigned char* data;
  size_t stride;
  size_t count;
};

// The bytes of accessor `index`, checked to lie inside its buffer view and buffer.
View Locate(const GltfDocument& doc, int index, size_t element_size) {
  const tinygltf::Model& m = *doc.model;
  const std::string where = "accessors[" + std::to_string(index) + "]";
  auto fail = [&](const std::string& why) {
    throw InputError(SourceLocation{doc.file, 0}, where + ": " + why);
  };
  if (index < 0 || static_cast<size_t>(index) >= m.accessors.size()) fail("no such accessor");
  const tinygltf::Accessor& a = m.accessors[static_cast<size_t>(index)];
  if (a.sparse.isSparse) fail("sparse accessors are not supported");
  if (a.bufferView < 0 || static_cast<size_t>(a.bufferView) >= m.bufferViews.size()) fail("no buffer view");
  const tinygltf::BufferView& v = m.bufferViews[static_cast<size_t>(a.bufferView)];
  if (v.buffer < 0 || static_cast<size_t>(v.buffer) >= m.buffers.size()) fail("buffer view has no buffer");
  const std::vector<unsigned char>& b = m.buffers[static_cast<size_t>(v.buffer)].data;
  const size_t stride = v.byteStride != 0 ? v.byteStride : element_size;
  if (v.byteOffset > b.size() || v.byteLength > b.size() - v.byteOffset)
    fail("buffer view outside its buffer");
  if (a.count == 0) return View{nullptr, stride, 0};
  // By division: a hostile count must not wrap the product around (stride · (count − 1)).
  if (stride < element_size || a.byteOffset > v.byteLength || element_size > v.byteLength - a.byteOffset ||
      a.count - 1 > (v.byteLength - a.byteOffset - element_size) / stride)
    fail("out of range of its buffer view");
  return View{b.data() + v.byteOffset + a.byteOffset, stride, a.count};
}

}  // namespace

std::vector<Vec3d> ReadGltfVec3(const GltfDocument& doc, int accessor) {
  const std::string where = "accessors[" + std::to_string(accessor) + "]";
  if (accessor >= 0 && static_cast<size_t>(accessor) < doc.model->accessors.size()) {
    const tinygltf::Accessor& a = doc.model->accessors[static_cast<size_t>(accessor)];
    if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
      throw InputError(SourceLocation{doc.file, 0}, where + ": expected VEC3 of FLOAT");
    }
  }
  const View view = Locate(doc, accessor, 3 * sizeof(float));
  std::vector<Vec3d> out(view.count);
  for (size_t i = 0; i < view.count; ++i) {
    float f[3];
    std::memcpy(f, view.data + i * view.stride, sizeof f);
    if (!std::isfinite(f[0]) || !std::isfinite(f[1]) || !std::isfinite(f[2])) {
      throw InputError(SourceLocation{doc.file, 0},
                       where + ": element " + std::to_string(i) + " is not finite (NaN or infinity)");
    }
    out[i] = Vec3d(f[0], f[1], f[2]);
  }
  return out;
}

std::vector<std::array<float, 2>> ReadGltfTexCoords(const GltfDocument& doc, int accessor) {
  const std::string where = "accessors[" + std::to_string(accessor) + "]";
  size_t width = 0;  // bytes per component
  if (accessor >= 0 && static_cast<size_t>(accessor) < doc.model->accessors.size()) {
    const tinygltf::Accessor& a = doc.model->accessors[static_cast<size_t>(accessor)];
    if (a.type == TINYGLTF_TYPE_VEC2 && a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) width = 4;
    if (a.type == TINYGLTF_TYPE_VEC2 && a.normalized &&
        a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE)
      width = 1;
    if (a.type == TINYGLTF_TYPE_VEC2 && a.normalized &&
        a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
      width = 2;
    if (width == 0)
      throw InputError(
          SourceLocation{doc.file, 0},
          where + ": texture coordinates must be VEC2 of FLOAT or normalized UNSIGNED_BYTE/SHORT");
  }
  const View view = Locate(doc, accessor, 2 * width);
  std::vector<std::array<float, 2>> out(view.count);
  for (size_t i = 0; i < view.count; ++i) {
    const unsigned char* p = view.data + i * view.stride;
    for (size_t c = 0; c < 2; ++c) {
      float v = 0.0f;
      if (width == 4) {
        std::memcpy(&v, p + 4 * c, sizeof v);
      } else if (width == 1) {
        v = float(p[c]) / 255.0f;
      } else {
        v = float(uint32_t(p[2 * c]) | uint32_t(p[2 * c + 1]) << 8) / 65535.0f;  // little-endian
      }
      if (!std::isfinite(v))
        throw InputError(SourceLocation{doc.file, 0},
                         where + ": element " + std::to_string(i) + " is not finite (NaN or infinity)");
      out[i][c] = v;
    }
  }
  return out;
}

std::vector<double> ReadGltfFloats(const GltfDocument& doc, int accessor, int components) {
  const std::string where = "accessors[" + std::to_string(accessor) + "]";
  const int type = components == 1   ? TINYGLTF_TYPE_SCALAR
                   : components == 3 ? TINYGLTF_TYPE_VEC3
                                     : TINYGLTF_TYPE_VEC4;
  if (accessor >= 0 && static_cast<size_t>(accessor) < doc.model->accessors.size()) {
    const tinygltf::Accessor& a = doc.model->accessors[static_cast<size_t>(accessor)];
    if (a.type != type || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      throw InputError(SourceLocation{doc.file, 0}, where + ": expected " +
                                                        (components == 1   ? std::string("SCALAR")
                                                         : components == 3 ? std::string("VEC3")
                                                                           : std::string("VEC4")) +
                                                        " of FLOAT");
  }
  const size_t n = static_cast<size_t>(components);
  const View view = Locate(doc, accessor, n * sizeof(float));
  std::vector<double> out(view.count * n);
  for (size_t i = 0; i < view.count; ++i)
    for (size_t c = 0; c < n; ++c) {
      float f = 0.0f;
      std::memcpy(&f, view.data + i * view.stride + c * sizeof f, sizeof f);
      if (!std::isfinite(f))
        throw InputError(SourceLocation{doc.file, 0},
                         where + ": element " + std::to_string(i) + " is not finite (NaN or infinity)");
      out[i * n + c] = f;
    }
  return out;
}

std::vector<uint32_t> ReadGltfIndices(const GltfDocument& doc, int accessor) {
  const std::string where = "accessors[" + std::to_string(accessor) + "]";
  size_t width = 0;
  if (accessor >= 0 && static_cast<size_t>(accessor) < doc.model->accessors.size()) {
    const tinygltf::Accessor& a = doc.model->accessors[static_cast<size_t>(accessor)];
    if (a.type == TINYGLTF_TYPE_SCALAR && a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) width = 1;
    if (a.type == TINYGLTF_TYPE_SCALAR && a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
      width = 2;
    if (a.type == TINYGLTF_TYPE_SCALAR && a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) width = 4;
    if (width == 0)
      throw InputError(SourceLocation{doc.file, 0}, where + ": indices must be unsigned SCALAR");
  }
  const View view = Locate(doc, accessor, width);
  std::vector<uint32_t> out(view.count);
  for (size_t i = 0; i < view.count; ++i) {
    const unsigned char* p = view.data + i * view.stride;
    uint32_t v = 0;
    for (size_t k = 0; k < width; ++k) v |= static_cast<uint32_t>(p[k]) << (8 * k);  // little-endian
    out[i] = v;
  }
  return out;
}

}  // namespace pf

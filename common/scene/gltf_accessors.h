#pragma once
// Reading glTF 2.0 accessors (spec §3.6.2) into pf's types: VEC3 float attributes and triangle
// indices of any width. Every error names the file and the accessor ("scene.gltf: accessors[2]:
// ..."); tinygltf has checked that buffers exist, not that a view or accessor stays inside them.

#include <array>
#include <cstdint>
#include <vector>

#include "common/core/math.h"
#include "common/scene/gltf_document.h"

namespace pf {

// A VEC3 FLOAT accessor (POSITION, NORMAL). Sparse accessors are refused. A NaN or an infinity
// is an InputError naming the accessor and the element.
std::vector<Vec3d> ReadGltfVec3(const GltfDocument& doc, int accessor);

// A VEC2 accessor of texture coordinates (TEXCOORD_n, spec §3.7.2.1): FLOAT, or normalized
// UNSIGNED_BYTE / UNSIGNED_SHORT. A non-finite element is an InputError naming it.
std::vector<std::array<float, 2>> ReadGltfTexCoords(const GltfDocument& doc, int accessor);

// A FLOAT accessor of `components` per element (1: SCALAR, 3: VEC3, 4: VEC4; animation samplers'
// times and values, spec §3.11), flat: element i's components at [i·components, (i+1)·components).
// A NaN or an infinity is an InputError naming the accessor and the element.
std::vector<double> ReadGltfFloats(const GltfDocument& doc, int accessor, int components);

// A SCALAR UNSIGNED_BYTE / UNSIGNED_SHORT / UNSIGNED_INT accessor (primitive indices).
std::vector<uint32_t> ReadGltfIndices(const GltfDocument& doc, int accessor);

}  // namespace pf

// glTF 2.0 → SceneDescription (gltf_loader.h).
#include "common/scene/gltf_loader.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/core/error.h"
#include "common/scene/gltf_accessors.h"
#include "common/scene/gltf_camera_path.h"
#include "common/scene/gltf_document.h"
#include "common/scene/gltf_lights.h"
#include "common/scene/gltf_materials.h"
#include "common/scene/gltf_textures.h"
#include "common/scene/gltf_transform.h"
#include "common/scene/mgf_transform.h"
#include "common/scene/scene_frame.h"

namespace pf {

namespace {

using mgf::Affine;

// A camera's image: 512 rows, as many columns as its aspectRatio asks (the manifest's limit).
constexpr int kCameraHeight = 512;
constexpr int kMaxCameraWidth = 65536;

std::string Indexed(const char* array, size_t i) {
  return std::string(array) + "[" + std::to_string(i) + "]";
}

// The node's local transform: its matrix (column-major), else T·R·S (glTF 2.0 spec, §3.5.3).
Affine LocalTransform(const tinygltf::Node& n) {
  Affine a;
  if (n.matrix.size() == 16) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a.m[r][c] = n.matrix[size_t(c * 4 + r)];
    a.t = Vec3d(n.matrix[12], n.matrix[13], n.matrix[14]);
    return a;
  }
  return GltfTrs(n.translation, n.rotation, n.scale);
}

// Normals transform by the inverse transpose. Only its direction matters, so the cofactor
// matrix (det · M⁻ᵀ) is used, times the sign of det: no division by a tiny determinant.
Affine NormalTransform(const Affine& a) {
  const auto& m = a.m;
  Affine n;
  n.m[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  n.m[0][1] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  n.m[0][2] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  n.m[1][0] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
  n.m[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
  n.m[1][2] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
  n.m[2][0] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
  n.m[2][1] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
  n.m[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  if (a.Mirrors())
    for (auto& row : n.m)
      for (double& v : row) v = -v;
  return n;
}

Vec3d UnitOrZero(const Vec3d& v) {
  const double len = Length(v);
  return len > 0.0 && std::isfinite(len) ? v / len : Vec3d(0.0);
}

class GltfSceneBuilder {
 public:
  GltfSceneBuilder(const GltfDocument& doc, const SceneBudget& budget, PixelAllowance* texels,
                   SceneDescription* scene)
      : doc_(doc),
        m_(*doc.model),
        budget_(budget),
        scene_(scene),
        visited_(m_.nodes.size(), false),
        textures_(doc, scene, texels) {
    for (size_t i = 0; i < m_.materials.size(); ++i) {
      scene_->materials.push_back(MapGltfMaterial(m_.materials[i], i, doc_.file, &scene_->warnings));
      AddMaterialTextures(i, &scene_->materials.back());
    }
    // Alpha channels no mask reads are let go (a 4096² RGBA texture's is 64 MiB).
    std::vector<bool> alpha_read(scene_->textures.size(), false);
    for (const Material& m : scene_->materials)
      if (m.alpha_texture >= 0) alpha_read[size_t(m.alpha_texture)] = true;
    for (size_t t = 0; t < scene_->textures.size(); ++t)
      if (!alpha_read[t]) scene_->textures[t].alpha.reset();
  }

  // KHR_materials_transmission.transmissionTexture of material `i`, if it names one: its index
  // (−1 where it is not a whole number) and texCoord (0 unless given).
  std::optional<tinygltf::TextureInfo> TransmissionTexture(size_t i) const {
    const auto ext = m_.materials[i].extensions.find("KHR_materials_transmission");
    if (ext == m_.materials[i].extensions.end() || !ext->second.IsObject() ||
        !ext->second.Has("transmissionTexture"))
      return std::nullopt;
    const tinygltf::Value& info = ext->second.Get("transmissionTexture");
    tinygltf::TextureInfo out;
    out.index = -1;
    if (!info.IsObject()) return out;
    const auto whole = [&](const char* key, int fallback) {
      if (!info.Has(key)) return fallback;
      const tinygltf::Value& v = info.Get(key);
      if (!v.IsNumber()) return -1;
      const double d = v.GetNumberAsDouble();
      return d >= 0.0 && d <= 1e9 && d == std::floor(d) ? int(d) : -1;
    };
    out.index = whole("index", -1);
    out.texCoord = whole("texCoord", 0);
    return out;
  }

  // The texture at `where` of material `i` names TEXCOORD_`set`: the material's set if it has none
  // yet; one naming another than the material's reads the material's (warned).
  void ReadTexCoord(size_t i, const std::string& where, int set) {
    const auto [it, first] = texcoord_set_.emplace(uint32_t(i), set);
    if (!first && it->second != set)
      WarnOnce(where + ": reads TEXCOORD_" + std::to_string(set) +
               ", the material's other textures TEXCOORD_" + std::to_string(it->second) +
               ": it reads TEXCOORD_" + std::to_string(it->second) +
               " (one set of texture coordinates per vertex)");
  }

  // A material's baseColorTexture (colour: sRGB), metallicRoughnessTexture (data: linear),
  // transmissionTexture (data) and emissiveTexture (colour), and its alpha mask's texture (the base colour's
  // alpha: specification §3.9.3). One set of texture coordinates per vertex: the first of those textures' in
  // that order.
  void AddMaterialTextures(size_t i, Material* material) {
    const tinygltf::PbrMetallicRoughness& pbr = m_.materials[i].pbrMetallicRoughness;
    const tinygltf::TextureInfo& base = pbr.baseColorTexture;
    const tinygltf::TextureInfo& mr = pbr.metallicRoughnessTexture;
    const std::string prefix = Indexed("materials", i) + ".pbrMetallicRoughness.";
    if (base.index >= 0) {
      const std::string where = prefix + "baseColorTexture";
      material->base_color_texture = textures_.Use(base.index, where, ImageCodes::kColor);
      if (base.texCoord < 0) Fail(where + ": texCoord must be >= 0");
      texcoord_set_[uint32_t(i)] = base.texCoord;
    }
    if (mr.index >= 0) {
      const std::string where = prefix + "metallicRoughnessTexture";
      material->metallic_roughness_texture = textures_.Use(mr.index, where, ImageCodes::kData);
      if (mr.texCoord < 0) Fail(where + ": texCoord must be >= 0");
      if (base.index < 0)
        texcoord_set_[uint32_t(i)] = mr.texCoord;
      else if (mr.texCoord != base.texCoord)
        WarnOnce(where + ": reads TEXCOORD_" + std::to_string(mr.texCoord) + ", baseColorTexture TEXCOORD_" +
                 std::to_string(base.texCoord) + ": both read TEXCOORD_" + std::to_string(base.texCoord) +
                 " (one set of texture coordinates per vertex)");
    }
    // KHR_materials_transmission's transmissionTexture (data: linear, red channel) multiplies
    // transmissionFactor; moot (and not decoded) when the factor is 0.
    if (const std::optional<tinygltf::TextureInfo> transmission = TransmissionTexture(i)) {
      const std::string where =
          Indexed("materials", i) + ".extensions.KHR_materials_transmission.transmissionTexture";
      if (transmission->index < 0) Fail(where + ": must be an object whose index is a whole number >= 0");
      if (transmission->texCoord < 0) Fail(where + ": texCoord must be a whole number >= 0");
      if (!material->metallic_roughness || !(material->metallic_roughness->transmission > 0.0f)) {
        WarnOnce(where + ": not applied: transmissionFactor is 0 (the texture multiplies it)");
      } else {
        material->transmission_texture = textures_.Use(transmission->index, where, ImageCodes::kData);
        ReadTexCoord(i, where, transmission->texCoord);
      }
    }
    // emissiveTexture (colour: sRGB) multiplies emissiveFactor × emissiveStrength; moot (and
    // not decoded) when they are black.
    const tinygltf::TextureInfo& emissive = m_.materials[i].emissiveTexture;
    if (emissive.index >= 0 && material->IsEmissive()) {
      const std::string where = Indexed("materials", i) + ".emissiveTexture";
      material->emission_texture = textures_.Use(emissive.index, where, ImageCodes::kColor);
      if (emissive.texCoord < 0) Fail(where + ": texCoord must be >= 0");
      ReadTexCoord(i, where, emissive.texCoord);
    }
    if (material->HasAlphaMask()) {
      material->alpha_texture = material->base_color_texture;
      // A mask that can cut nothing (no alpha texels, the factor at or above the cutoff) is dropped:
      // the surface is opaque and its rays pay no filter (accel/embree_scene.cpp).
      const bool textured_alpha =
          material->alpha_texture >= 0 && scene_->textures[size_t(material->alpha_texture)].alpha;
      if (!textured_alpha && material->alpha_factor >= material->alpha_cutoff) {
        material->alpha_cutoff = 0.0f;
        material->alpha_texture = -1;
      }
    }
  }

  // Every node of the scene's roots, depth first (an explicit stack: a hostile file may nest
  // a million nodes).
  void VisitScene(const std::vector<int>& roots) {
    std::vector<std::pair<int, Affine>> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, Affine{});
    while (!stack.empty()) {
      const auto [index, parent] = stack.back();
      stack.pop_back();
      const std::string where = Indexed("nodes", size_t(std::max(index, 0)));
      if (index < 0 || size_t(index) >= m_.nodes.size())
        Fail("node " + std::to_string(index) + " does not exist");
      if (visited_[size_t(index)])
        Fail(where +
             ": appears twice in the node hierarchy (glTF 2.0 spec, §3.5.2: the nodes form "
             "disjoint trees)");
      visited_[size_t(index)] = true;
      const tinygltf::Node& node = m_.nodes[size_t(index)];
      const Affine world = mgf::Compose(parent, LocalTransform(node));
      if (!world.IsFinite() || !IsFinite(Vec3(world.t))) Fail(where + ": its world transform is not finite");
      if (node.mesh >= 0) AddMesh(where, size_t(node.mesh), world);
      if (node.camera >= 0) {
        const bool had_camera = !scene_->cameras.empty();
        AddCamera(where, size_t(node.camera), world);
        // The scene's camera: its animation, if any, is the scene's camera path.
        // A malformed one is a warning: the scene renders still frames without it.
        if (!had_camera && !scene_->cameras.empty()) {
          try {
            scene_->camera_path = GltfCameraPath(doc_, index, parent, &scene_->warnings);
          } catch (const InputError& e) {
            scene_->warnings.push_back(std::string(e.what()) + " (the camera's animation is not used)");
          }
        }
      }
      AddLight(where, node, world);
      if (node.skin >= 0) WarnOnce(where + ": skins are not applied (the mesh is rendered in its bind pose)");
      for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
    }
  }

  void Finish() {
    // The file's camera looks at the point of its axis nearest the centre of the scene (1 m
    // ahead if the centre is behind it): what `pf info` shows, and inside the scene's bounds.
    WorldBounds bounds;
    for (const Vec3d& p : world_) bounds.Extend(p);
    for (CameraSpec& c : scene_->cameras) {
      const Vec3d forward = c.look_at - c.eye;  // unit (AddCamera)
      const double ahead = bounds.Empty() ? 1.0 : Dot((bounds.lo + bounds.hi) * 0.5 - c.eye, forward);
      if (ahead > 1.0 && std::isfinite(ahead)) c.look_at = c.eye + forward * ahead;
    }
    StoreInSceneFrame(world_, scene_);
    if (!scene_->textures.empty()) scene_->uvs = std::move(uvs_);
    for (const Vec3& p : scene_->positions)
      if (!IsFinite(p)) Fail("a transformed vertex does not fit a 32-bit float");
    if (any_normal_) scene_->normals = std::move(normals_);
    // Zero-area triangles (in float, as traced) are dropped; light ids go to the primitive
    // instances that keep a triangle, in order.
    std::vector<uint32_t> light_of_instance(instance_emits_.size(), kNoLight);
    size_t degenerate = 0;
    for (size_t t = 0; t < triangles_.size(); ++t) {
      const auto& tri = triangles_[t];
      const std::vector<Vec3>& p = scene_->positions;
      if (!(LengthSquared(Cross(p[tri[1]] - p[tri[0]], p[tri[2]] - p[tri[0]])) > 0.0f)) {
        ++degenerate;
        continue;
      }
      const uint32_t instance = triangle_instance_[t];
      if (instance_emits_[instance] && light_of_instance[instance] == kNoLight)
        light_of_instance[instance] = scene_->num_lights++;
      scene_->triangles.push_back(tri);
      scene_->triangle_material.push_back(triangle_material_[t]);
      scene_->triangle_light.push_back(light_of_instance[instance]);
    }
    if (degenerate > 0)
      scene_->warnings.push_back(doc_.file + ": " + std::to_string(degenerate) +
                                 " degenerate (zero-area) triangles dropped");
    for (PunctualLight& l : lights_) {
      l.light = scene_->num_lights++;
      scene_->punctual_lights.push_back(std::move(l));
    }
    if (scene_->triangles.empty())
      scene_->warnings.push_back(doc_.file + ": the scene contains no triangles");
  }

  [[noreturn]] void Fail(const std::string& why) const {
    throw InputError(SourceLocation{doc_.file, 0}, why);
  }

 private:
  void WarnOnce(const std::string& warning) {
    if (warned_.insert(warning).second) scene_->warnings.push_back(doc_.file + ": " + warning);
  }

  // An accessor read for `where`: its errors name the primitive first.
  template <typename Read>
  auto Accessor(const std::string& where, Read read) const {
    try {
      return read();
    } catch (const InputError& e) {
      throw InputError(SourceLocation{doc_.file, 0}, where + ": " + e.reason());
    }
  }

  uint32_t MaterialIndex(const std::string& where, int material) {
    if (material >= 0) {
      if (size_t(material) >= m_.materials.size())
        Fail(where + ": material " + std::to_string(material) + " does not exist");
      return uint32_t(material);
    }
    if (default_material_ == kNoLight) {
      default_material_ = uint32_t(scene_->materials.size());
      scene_->materials.push_back(DefaultGltfMaterial());
    }
    return default_material_;
  }

  void AddMesh(const std::string& node_where, size_t mesh, const Affine& world) {
    if (mesh >= m_.meshes.size()) Fail(node_where + ": mesh " + std::to_string(mesh) + " does not exist");
    const Affine normal_transform = NormalTransform(world);
    const bool mirrors = world.Mirrors();
    const auto& primitives = m_.meshes[mesh].primitives;
    for (size_t p = 0; p < primitives.size(); ++p) {
      const tinygltf::Primitive& prim = primitives[p];
      const std::string where = Indexed("meshes", mesh) + "." + Indexed("primitives", p);
      if (prim.mode != -1 && prim.mode != TINYGLTF_MODE_TRIANGLES) {
        WarnOnce(where + ": mode " + std::to_string(prim.mode) + " is not TRIANGLES (4); skipped");
        continue;
      }
      if (!prim.targets.empty()) WarnOnce(where + ": morph targets are not applied");
      const auto position = prim.attributes.find("POSITION");
      if (position == prim.attributes.end()) Fail(where + ": no POSITION attribute");
      const std::vector<Vec3d> positions =
          Accessor(where, [&] { return ReadGltfVec3(doc_, position->second); });
      std::vector<Vec3d> normals;
      if (const auto normal = prim.attributes.find("NORMAL"); normal != prim.attributes.end()) {
        normals = Accessor(where, [&] { return ReadGltfVec3(doc_, normal->second); });
        if (normals.size() != positions.size())
          Fail(where + ": NORMAL has " + std::to_string(normals.size()) + " elements, POSITION " +
               std::to_string(positions.size()));
      }
      std::vector<uint32_t> indices;
      if (prim.indices >= 0) {
        indices = Accessor(where, [&] { return ReadGltfIndices(doc_, prim.indices); });
      } else {
        indices.resize(positions.size());
        std::iota(indices.begin(), indices.end(), 0u);
      }
      if (indices.size() % 3 != 0)
        Fail(where + ": " + std::to_string(indices.size()) + " indices are not a whole number of triangles");
      for (const uint32_t i : indices)
        if (i >= positions.size())
          Fail(where + ": index " + std::to_string(i) + " is out of range (" +
               std::to_string(positions.size()) + " vertices)");
      if (triangles_.size() + indices.size() / 3 > budget_.max_triangles)
        Fail(where + ": more than " + std::to_string(budget_.max_triangles) +
             " triangles in the scene (SceneBudget::max_triangles)");
      if (world_.size() + positions.size() > std::min<uint64_t>(budget_.max_vertices, 0xfffffff0u))
        Fail(where + ": more than " + std::to_string(budget_.max_vertices) +
             " vertices in the scene (SceneBudget::max_vertices)");
      const uint32_t material = MaterialIndex(where, prim.material);

      AddTexCoords(where, prim, material, positions.size());
      const uint32_t base = uint32_t(world_.size());
      for (size_t v = 0; v < positions.size(); ++v) {
        world_.push_back(world.Point(positions[v]));
        const Vec3 n = normals.empty() ? Vec3(0.0f) : Vec3(UnitOrZero(normal_transform.Vector(normals[v])));
        any_normal_ = any_normal_ || !(n == Vec3(0.0f));
        normals_.push_back(IsFinite(n) ? n : Vec3(0.0f));
      }
      const uint32_t instance = uint32_t(instance_emits_.size());
      instance_emits_.push_back(scene_->materials[material].IsEmissive());
      for (size_t i = 0; i < indices.size(); i += 3) {
        // A mirroring transform turns counter-clockwise into clockwise: swap to keep the front.
        const uint32_t b = base + indices[i + (mirrors ? 2 : 1)], c = base + indices[i + (mirrors ? 1 : 2)];
        triangles_.push_back({base + indices[i], b, c});
        triangle_material_.push_back(material);
        triangle_instance_.push_back(instance);
      }
    }
  }

  // The texture coordinates of a primitive's vertices, when the scene has textures: the set its
  // material's texture reads (TEXCOORD_<texCoord>), (0, 0) for an untextured material; a textured
  // material without its set gets (0, 0) and a warning (the texture's first texel then).
  void AddTexCoords(const std::string& where, const tinygltf::Primitive& prim, uint32_t material,
                    size_t count) {
    if (scene_->textures.empty()) return;
    const auto set = texcoord_set_.find(material);
    if (set != texcoord_set_.end()) {
      const std::string name = "TEXCOORD_" + std::to_string(set->second);
      if (const auto it = prim.attributes.find(name); it != prim.attributes.end()) {
        const std::vector<TextureCoordinates> uv =
            Accessor(where, [&] { return ReadGltfTexCoords(doc_, it->second); });
        if (uv.size() != count)
          Fail(where + ": " + name + " has " + std::to_string(uv.size()) + " elements, POSITION " +
               std::to_string(count));
        uvs_.insert(uvs_.end(), uv.begin(), uv.end());
        return;
      }
      WarnOnce(where + ": its material's texture reads " + name +
               ", which the primitive lacks (the texture's corner is used)");
    }
    uvs_.resize(uvs_.size() + count, TextureCoordinates{0.0f, 0.0f});
  }

  // The first perspective camera in node order (gltf_loader.h): eye at the node's origin,
  // looking down its −Z with its +Y up; yfov (radians) is the vertical field of view.
  void AddCamera(const std::string& node_where, size_t camera, const Affine& world) {
    if (camera >= m_.cameras.size())
      Fail(node_where + ": camera " + std::to_string(camera) + " does not exist");
    if (!scene_->cameras.empty()) return;
    const tinygltf::Camera& c = m_.cameras[camera];
    const std::string where = Indexed("cameras", camera);
    if (c.type != "perspective") {
      WarnOnce(where + ": a " + c.type + " camera is not supported (pf's camera is a pinhole); not used");
      return;
    }
    const double yfov = c.perspective.yfov, pi = 2.0 * std::acos(0.0);
    if (!(yfov > 0.0 && yfov < pi)) Fail(where + ": perspective.yfov must be in (0, pi) radians");
    const Vec3d forward = UnitOrZero(world.Vector(Vec3d(0, 0, -1)));
    const Vec3d up = UnitOrZero(world.Vector(Vec3d(0, 1, 0)));
    if (forward == Vec3d(0.0) || up == Vec3d(0.0))
      Fail(node_where + ": its transform gives the camera no direction");
    CameraSpec spec;
    spec.name = c.name.empty() ? where : c.name;
    spec.eye = world.t;
    spec.look_at = world.t + forward;
    spec.up = Vec3(up);
    spec.vfov_degrees = float(yfov * 180.0 / pi);
    spec.height = kCameraHeight;
    spec.width = kCameraHeight;
    if (c.perspective.aspectRatio > 0.0) {
      const double width = std::round(kCameraHeight * c.perspective.aspectRatio);
      spec.width = int(std::clamp(width, 1.0, double(kMaxCameraWidth)));
      if (width != double(spec.width))
        WarnOnce(where + ": aspectRatio gives " + std::to_string(width) + " columns; clamped to " +
                 std::to_string(spec.width));
    }
    scene_->cameras.push_back(spec);
  }

  void AddLight(const std::string& node_where, const tinygltf::Node& node, const Affine& world) {
    const auto ext = node.extensions.find("KHR_lights_punctual");
    if (ext == node.extensions.end() || !ext->second.IsObject() || !ext->second.Has("light")) return;
    const tinygltf::Value& v = ext->second.Get("light");
    const double index = v.IsNumber() ? v.GetNumberAsDouble() : -1.0;
    if (!(index >= 0.0 && index < double(m_.lights.size())))
      Fail(node_where + ": KHR_lights_punctual.light does not name a light of the file");
    PunctualLight light;
    if (MapGltfLight(m_.lights[size_t(index)], size_t(index), world, doc_.file, &scene_->warnings, &light))
      lights_.push_back(std::move(light));
  }

  const GltfDocument& doc_;
  const tinygltf::Model& m_;
  const SceneBudget& budget_;
  SceneDescription* scene_;
  std::vector<bool> visited_;
  std::set<std::string> warned_;
  GltfTextures textures_;
  std::map<uint32_t, int> texcoord_set_;  // a textured material's TEXCOORD_n
  std::vector<TextureCoordinates> uvs_;   // one per world_ vertex when the scene has textures
  uint32_t default_material_ = kNoLight;  // "none yet"
  std::vector<Vec3d> world_;
  std::vector<Vec3> normals_;
  bool any_normal_ = false;
  std::vector<std::array<uint32_t, 3>> triangles_;
  std::vector<uint32_t> triangle_material_;
  std::vector<uint32_t> triangle_instance_;  // the primitive instance of each triangle
  std::vector<bool> instance_emits_;
  std::vector<PunctualLight> lights_;
};

// The default scene's root nodes (or scene 0's); with no scenes, every node no node has as a child.
std::vector<int> SceneRoots(const tinygltf::Model& m, const GltfSceneBuilder& builder,
                            std::vector<std::string>* warnings, const std::string& file) {
  if (!m.scenes.empty()) {
    const int s = m.defaultScene >= 0 ? m.defaultScene : 0;
    if (size_t(s) >= m.scenes.size()) builder.Fail("scene " + std::to_string(s) + " does not exist");
    return m.scenes[size_t(s)].nodes;
  }
  std::vector<bool> child(m.nodes.size(), false);
  for (const tinygltf::Node& n : m.nodes)
    for (const int c : n.children)
      if (c >= 0 && size_t(c) < child.size()) child[size_t(c)] = true;
  std::vector<int> roots;
  for (size_t i = 0; i < m.nodes.size(); ++i)
    if (!child[i]) roots.push_back(int(i));
  if (!m.nodes.empty()) warnings->push_back(file + ": no scenes: every root node is rendered");
  return roots;
}

}  // namespace

SceneDescription LoadGltf(const std::filesystem::path& path, const std::filesystem::path& root,
                          const SceneBudget& budget, PixelAllowance* texels) {
  PixelAllowance own(budget.max_texels);
  const GltfDocument doc = ReadGltfDocument(path, root);
  SceneDescription scene;
  scene.source = path.string();
  scene.warnings = doc.warnings;
  GltfSceneBuilder builder(doc, budget, texels != nullptr ? texels : &own, &scene);
  builder.VisitScene(SceneRoots(*doc.model, builder, &scene.warnings, doc.file));
  builder.Finish();
  if (!doc.model->animations.empty())
    scene.warnings.push_back(doc.file +
                             (scene.camera_path.keys.empty()
                                  ? ": animations are not applied (the scene is rendered at rest)"
                                  : ": animations are not applied, except the camera's as its camera path "
                                    "(pf submit --frames); the scene is rendered at rest"));
  return scene;
}

}  // namespace pf

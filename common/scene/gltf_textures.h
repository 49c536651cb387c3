#pragma once
// glTF textures (specification §3.8) → Texture (texture.h), for the glTF scene loader: the
// texture's image decoded once (image/image_file.h: PNG or JPEG, sRGB-decoded as the colour slots
// they serve require) and its sampler's wrap modes. Errors name the file and the element
// ("scene.gltf: materials[2].pbrMetallicRoughness.baseColorTexture: textures[4]: images[1]: ...").

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>

#include "common/scene/gltf_document.h"
#include "common/scene/scene.h"

namespace pf {

class GltfTextures {
 public:
  GltfTextures(const GltfDocument& doc, SceneDescription* scene) : doc_(doc), scene_(scene) {}

  // The index in scene->textures of glTF texture `texture`, referred to at `where`; adds it (and
  // decodes its image, once per image) on first use. Throws InputError naming `where`.
  int32_t Use(int texture, const std::string& where);

 private:
  std::shared_ptr<const Image> DecodedImage(int image, const std::string& where);
  void WarnOnce(const std::string& warning);

  const GltfDocument& doc_;
  SceneDescription* scene_;
  std::map<int, int32_t> texture_index_;
  std::map<int, std::shared_ptr<const Image>> images_;
  std::set<std::string> warned_;
};

}  // namespace pf

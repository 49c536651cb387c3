#pragma once
// glTF textures (specification §3.8) → Texture (texture.h), for the glTF scene loader: the
// texture's image decoded once per way it is read (image/image_file.h: PNG or JPEG, sRGB-decoded
// for colour slots, linear for data slots such as metallicRoughnessTexture, its alpha channel
// kept) and its sampler's wrap modes. Errors name the file and the element
// ("scene.gltf: materials[2].pbrMetallicRoughness.baseColorTexture: textures[4]: images[1]: ...").

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/image/image_file.h"
#include "common/scene/gltf_document.h"
#include "common/scene/scene.h"

namespace pf {

class GltfTextures {
 public:
  // Every image decoded is charged to `allowance` (SceneBudget::max_texels).
  GltfTextures(const GltfDocument& doc, SceneDescription* scene, PixelAllowance* allowance)
      : doc_(doc), scene_(scene), allowance_(allowance) {}

  // The index in scene->textures of glTF texture `texture`, referred to at `where`, its image's
  // codes read as `codes` says (kColor: sRGB; kData: linear); adds it (and decodes its image,
  // once per image and codes) on first use. The texture keeps the image's alpha channel, if any
  // (Texture::alpha). Throws InputError naming `where`.
  int32_t Use(int texture, const std::string& where, ImageCodes codes);

 private:
  struct Decoded {
    std::shared_ptr<const Image> rgb;
    std::shared_ptr<const std::vector<float>> alpha;  // null: the image has none
  };
  const Decoded& DecodedImage(int image, const std::string& where, ImageCodes codes);
  void WarnOnce(const std::string& warning);

  const GltfDocument& doc_;
  SceneDescription* scene_;
  PixelAllowance* allowance_;
  std::map<std::pair<int, ImageCodes>, int32_t> texture_index_;
  std::map<std::pair<int, ImageCodes>, Decoded> images_;
  std::set<std::string> warned_;
};

}  // namespace pf

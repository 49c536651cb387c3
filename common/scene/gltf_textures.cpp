// glTF textures (gltf_textures.h).
#include "common/scene/gltf_textures.h"

#include <tiny_gltf.h>

#include "common/core/error.h"
#include "common/image/image_file.h"

namespace pf {
namespace {

TextureWrap WrapOf(int mode) {
  switch (mode) {
    case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
      return TextureWrap::kClampToEdge;
    case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
      return TextureWrap::kMirroredRepeat;
    default:
      return TextureWrap::kRepeat;
  }
}

}  // namespace

void GltfTextures::WarnOnce(const std::string& warning) {
  if (warned_.insert(warning).second) scene_->warnings.push_back(doc_.file + ": " + warning);
}

const GltfTextures::Decoded& GltfTextures::DecodedImage(int image, const std::string& where,
                                                        ImageCodes codes) {
  const tinygltf::Model& m = *doc_.model;
  if (image < 0 || size_t(image) >= m.images.size())
    throw InputError(SourceLocation{doc_.file, 0},
                     where + ": image " + std::to_string(image) + " does not exist");
  Decoded& decoded = images_[{image, codes}];
  if (decoded.rgb) return decoded;
  const auto keep = [&](ImageWithAlpha im) {
    decoded.rgb = std::make_shared<const Image>(std::move(im.rgb));
    if (!im.alpha.empty()) decoded.alpha = std::make_shared<const std::vector<float>>(std::move(im.alpha));
  };
  const tinygltf::Image& g = m.images[size_t(image)];
  const bool file = !g.uri.empty() && g.uri.rfind("data:", 0) != 0;
  const std::string element = "images[" + std::to_string(image) + "]" + (file ? " '" + g.uri + "'" : "");
  if (g.bufferView >= 0) {
    // The view's bytes, checked to lie inside its buffer (gltf_document.cpp keeps none of them).
    auto fail = [&](const std::string& why) {
      throw InputError(SourceLocation{doc_.file, 0}, where + ": " + element + ": " + why);
    };
    if (size_t(g.bufferView) >= m.bufferViews.size()) fail("buffer view does not exist");
    const tinygltf::BufferView& v = m.bufferViews[size_t(g.bufferView)];
    if (v.buffer < 0 || size_t(v.buffer) >= m.buffers.size()) fail("buffer view has no buffer");
    const std::vector<unsigned char>& b = m.buffers[size_t(v.buffer)].data;
    if (v.byteOffset > b.size() || v.byteLength > b.size() - v.byteOffset)
      fail("buffer view outside its buffer");
    const std::string name = doc_.file + ": " + where + ": " + element;
    keep(DecodeImageWithAlpha(b.data() + v.byteOffset, v.byteLength, name, codes, allowance_));
    return decoded;
  }
  if (g.image.empty())
    throw InputError(SourceLocation{doc_.file, 0},
                     where + ": " + element +
                         (file ? ": the file is missing from the scene folder, unreadable or empty"
                               : ": no image data (a missing or empty buffer view or data URI)"));
  const std::string name = doc_.file + ": " + where + ": " + element;
  // DecodeLinearImage's errors name `name` (its SourceLocation), already the whole element path.
  keep(DecodeImageWithAlpha(g.image.data(), g.image.size(), name, codes, allowance_));
  return decoded;
}

int32_t GltfTextures::Use(int texture, const std::string& where, ImageCodes codes) {
  const tinygltf::Model& m = *doc_.model;
  if (texture < 0 || size_t(texture) >= m.textures.size())
    throw InputError(SourceLocation{doc_.file, 0},
                     where + ": texture " + std::to_string(texture) + " does not exist");
  if (const auto it = texture_index_.find({texture, codes}); it != texture_index_.end()) return it->second;
  const tinygltf::Texture& t = m.textures[size_t(texture)];
  const std::string element = where + ": textures[" + std::to_string(texture) + "]";
  if (t.source < 0)
    throw InputError(SourceLocation{doc_.file, 0},
                     element + ": no source image (only PNG and JPEG sources are read; KTX2/basisu is not)");
  Texture out;
  const Decoded& decoded = DecodedImage(t.source, element, codes);
  out.image = decoded.rgb;
  out.alpha = decoded.alpha;
  out.source = "images[" + std::to_string(t.source) + "]";
  if (t.sampler >= 0) {
    if (size_t(t.sampler) >= m.samplers.size())
      throw InputError(SourceLocation{doc_.file, 0},
                       element + ": sampler " + std::to_string(t.sampler) + " does not exist");
    const tinygltf::Sampler& s = m.samplers[size_t(t.sampler)];
    out.wrap_u = WrapOf(s.wrapS);
    out.wrap_v = WrapOf(s.wrapT);
    if (s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST)
      WarnOnce("samplers[" + std::to_string(t.sampler) +
               "]: magFilter NEAREST is not applied (textures are filtered bilinearly)");
  }
  const int32_t index = int32_t(scene_->textures.size());
  scene_->textures.push_back(std::move(out));
  texture_index_.emplace(std::make_pair(texture, codes), index);
  return index;
}

}  // namespace pf

// OBJ/MTL loading through tinyobjloader; the mapping to Ward's model is documented in the
// header. tinyobjloader reports problems as free text (warnings and errors); this file turns
// the ones that would leave broken geometry into InputError with the file and line.
#include "common/scene/obj_loader.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "common/core/error.h"
#include "common/image/image_file.h"
#include "common/scene/scene_frame.h"
#include "common/scene/scene_reference.h"

namespace pf {
namespace {

constexpr float kDefaultGrey = 0.8f;
// Sums of reflectance and transmittance this close to 1 are not worth a warning.
constexpr float kEnergyTolerance = 1e-4f;

std::string FormatRgb(const Rgb& c) {
  std::ostringstream s;
  s << c.r << " " << c.g << " " << c.b;
  return s.str();
}

// Negative or non-finite channels become 0 (with a warning): they would break every estimator.
Rgb NonNegative(const Rgb& c, const std::string& material, const char* what,
                std::vector<std::string>* warnings) {
  Rgb out = c;
  bool changed = false;
  for (int i = 0; i < 3; ++i) {
    if (!(out[i] >= 0.0f) || !std::isfinite(out[i])) {
      out[i] = 0.0f;
      changed = true;
    }
  }
  if (changed && warnings)
    warnings->push_back("material '" + material + "': " + what + " " + FormatRgb(c) +
                        " has negative or non-finite channels; set to 0");
  return out;
}

// tinyobjloader's messages often end with "line N." or "(line N.)".
int LineFromMessage(const std::string& message) {
  static const std::regex kLine(R"(line[ :]*([0-9]+))");
  std::smatch m;
  if (std::regex_search(message, m, kLine)) return std::stoi(m[1].str());
  return 0;
}

std::vector<std::string> SplitLines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) lines.push_back(line);
  }
  return lines;
}

// tinyobjloader's warnings that mean the geometry cannot be trusted.
bool IsFatalWarning(const std::string& w) {
  return w.find("Vertex indices out of bounds") != std::string::npos ||
         w.find("Vertex normal indices out of bounds") != std::string::npos ||
         w.find("Face with invalid vertex index") != std::string::npos;
}

// Parses the leading integer of an OBJ index field ("12", "-3"); nullopt-like 0 if absent.
bool ParseIndex(std::string_view field, long* value) {
  if (field.empty()) return false;
  const char* begin = field.data();
  const char* end = begin + field.size();
  auto [ptr, ec] = std::from_chars(begin, end, *value);
  return ec == std::errc() && ptr != begin;
}

// Error path only: re-reads the file to find the first face line whose vertex or normal index
// does not resolve (tinyobjloader reports only the last line of the file). Positive indices are
// checked against the final counts (tinyobjloader accepts forward references), negative ones
// against the counts so far. Returns 0 if nothing is found.
int FindFirstBadFaceLine(const std::filesystem::path& path, long total_v, long total_vn) {
  std::ifstream in(path);
  std::string line;
  int line_number = 0;
  long v_so_far = 0, vn_so_far = 0;
  auto resolves = [](long idx, long so_far, long total) {
    if (idx > 0) return idx <= total;
    if (idx < 0) return so_far + idx >= 0;
    return false;
  };
  while (std::getline(in, line)) {
    ++line_number;
    std::istringstream tokens(line);
    std::string keyword;
    if (!(tokens >> keyword)) continue;
    if (keyword == "v") {
      ++v_so_far;
    } else if (keyword == "vn") {
      ++vn_so_far;
    } else if (keyword == "f") {
      std::string corner;
      while (tokens >> corner) {
        const size_t slash1 = corner.find('/');
        long vi = 0;
        if (!ParseIndex(std::string_view(corner).substr(0, slash1), &vi) || !resolves(vi, v_so_far, total_v))
          return line_number;
        if (slash1 == std::string::npos) continue;
        const size_t slash2 = corner.find('/', slash1 + 1);
        if (slash2 == std::string::npos) continue;
        long ni = 0;
        const std::string_view normal_field = std::string_view(corner).substr(slash2 + 1);
        if (!normal_field.empty() && (!ParseIndex(normal_field, &ni) || !resolves(ni, vn_so_far, total_vn)))
          return line_number;
      }
    }
  }
  return 0;
}

// Reads `mtllib` files for tinyobjloader, but only inside the scene's root (scene_reference.h);
// tinyobjloader's own reader opens any path an OBJ names. A refused reference is kept and
// turned into an InputError by LoadObj (tinyobjloader would only warn); a missing file inside
// the root stays a warning, as before.
class ConfinedMtlReader : public tinyobj::MaterialReader {
 public:
  ConfinedMtlReader(std::filesystem::path root, std::filesystem::path base_dir)
      : root_(std::move(root)), base_dir_(std::move(base_dir)) {}

  bool operator()(const std::string& reference, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) override {
    std::filesystem::path resolved;
    const std::string problem = SceneReferenceProblem(root_, base_dir_, reference, &resolved);
    if (!problem.empty()) {
      if (refused_reference_.empty()) {
        refused_reference_ = reference;
        refusal_ = problem;
      }
      return false;
    }
    std::error_code ec;
    std::ifstream in;
    if (std::filesystem::is_regular_file(resolved, ec)) in.open(resolved, std::ios::binary);
    if (!in) {
      missing_.push_back(reference);
      return false;
    }
    tinyobj::LoadMtl(material_map, materials, &in, warn, err);
    return true;
  }

  const std::string& refused_reference() const { return refused_reference_; }
  const std::string& refusal() const { return refusal_; }
  const std::vector<std::string>& missing() const { return missing_; }

 private:
  std::filesystem::path root_, base_dir_;
  std::string refused_reference_, refusal_;
  std::vector<std::string> missing_;
};

// The next line of `in` into `line`, ended as tinyobjloader ends lines (its safeGetline): by
// "\n", "\r\n" or a lone "\r", so that statements are counted as it will parse them (a file with
// "\r" line ends must not look like one long line). False at the end of the stream.
bool NextLine(std::istream& in, std::string& line) {
  line.clear();
  std::streambuf* buffer = in.rdbuf();
  for (;;) {
    const int c = buffer->sbumpc();
    if (c == std::char_traits<char>::eof()) return !line.empty();
    if (c == '\n') return true;
    if (c == '\r') {
      if (buffer->sgetc() == '\n') buffer->sbumpc();
      return true;
    }
    line.push_back(char(c));
  }
}

// The statements of an OBJ file, counted before tinyobjloader stores them (scene_budget.h), and
// its coordinates checked: tinyobjloader reads "nan", "inf" or "1e999" in a `v`/`vn` line as some
// number without a word; a scene with such a vertex must not load (it would poison the kd-tree
// and every estimator). Checks the first three fields of every `v` and `vn` line. Throws at the
// line where a count crosses its budget.
SceneExpansion ScanStatements(std::istream& in, const std::string& file, const SceneBudget& budget) {
  SceneExpansion counts;
  constexpr std::string_view kSpace = " \t\r";
  auto next_field = [&](std::string_view& rest) {
    const size_t start = rest.find_first_not_of(kSpace);
    if (start == std::string_view::npos) {
      rest = {};
      return std::string_view();
    }
    const size_t end = std::min(rest.find_first_of(kSpace, start), rest.size());
    const std::string_view field = rest.substr(start, end - start);
    rest.remove_prefix(end);
    return field;
  };
  int number = 0;
  std::string line;
  while (NextLine(in, line)) {
    std::string_view rest = line;
    ++number;
    const std::string_view keyword = next_field(rest);
    if (keyword.empty() || keyword[0] == '#') continue;
    counts.entities = SceneExpansion::Add(counts.entities, 1);
    if (keyword == "f") {
      uint64_t corners = 0;
      while (!next_field(rest).empty()) ++corners;
      if (corners >= 3) counts.triangles = SceneExpansion::Add(counts.triangles, corners - 2);
    } else if (keyword == "v" || keyword == "vn" || keyword == "vt") {
      counts.vertices = SceneExpansion::Add(counts.vertices, 1);
      for (int i = 0; i < 3 && keyword != "vt"; ++i) {
        const std::string_view field = next_field(rest);
        if (field.empty()) break;  // too few fields: tinyobjloader's own error
        double value = 0;
        const char* first = field.data() + (field.size() > 1 && field[0] == '+' ? 1 : 0);
        const auto [ptr, ec] = std::from_chars(first, field.data() + field.size(), value);
        if (ec != std::errc() || ptr != field.data() + field.size() || !std::isfinite(value) ||
            !std::isfinite(float(value)))
          throw InputError(SourceLocation{file, number}, std::string(keyword) + " coordinate " +
                                                             QuoteReference(std::string(field)) +
                                                             " is not a finite number");
      }
    } else {
      continue;
    }
    if (const std::string over = budget.Exceeded(counts); !over.empty())
      throw InputError(SourceLocation{file, number}, over);
  }
  return counts;
}

// Output vertices, one per (position, normal, texture coordinate) triple, numbered in first-use
// order. Almost every OBJ gives a position one normal or none (and one `vt` or none), so the
// first triple of each position is kept in flat tables (12 bytes per position) and only further
// ones of a position go to a hash map.
class VertexTable {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;
  explicit VertexTable(size_t positions) : first_(positions, kNone), first_attributes_(positions, 0) {}
  // The vertex of (position, attributes: normal + 1 | (texcoord + 1) << 32); `make` creates it
  // (and returns its number) if absent.
  template <typename Make>
  uint32_t Find(uint32_t position, uint64_t attributes, Make make) {
    if (first_[position] == kNone) {
      first_[position] = make();
      first_attributes_[position] = attributes;
      return first_[position];
    }
    if (first_attributes_[position] == attributes) return first_[position];
    const Key key{position, attributes};
    const auto it = others_.find(key);
    if (it != others_.end()) return it->second;
    const uint32_t v = make();
    others_.emplace(key, v);
    return v;
  }

 private:
  struct Key {
    uint32_t position;
    uint64_t attributes;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return std::hash<uint64_t>()(k.attributes * 0x9e3779b97f4a7c15ull ^ k.position);
    }
  };
  std::vector<uint32_t> first_;
  std::vector<uint64_t> first_attributes_;
  std::unordered_map<Key, uint32_t, KeyHash> others_;
};

// The line of the first `mtllib` statement that names `reference` (0 if none is found).
int MtllibLine(const std::filesystem::path& path, const std::string& reference) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line.compare(start, 6, "mtllib") != 0) continue;
    if (line.find(reference, start + 6) != std::string::npos) return number;
  }
  return 0;
}

MtlParameters FromTinyObj(const tinyobj::material_t& m) {
  MtlParameters p;
  p.name = m.name;
  auto rgb = [](const tinyobj::real_t* c) { return Rgb(float(c[0]), float(c[1]), float(c[2])); };
  p.kd = rgb(m.diffuse);
  p.ks = rgb(m.specular);
  p.ke = rgb(m.emission);
  p.tf = rgb(m.transmittance);
  p.ns = float(m.shininess);
  p.ni = float(m.ior);
  p.d = float(m.dissolve);
  p.illum = m.illum;
  return p;
}

// The maps of a material this loader does not apply, named in its warning.
std::vector<std::string> UnappliedMaps(const tinyobj::material_t& m) {
  std::vector<std::string> maps;
  const std::pair<const char*, const std::string*> slots[] = {{"map_Ka", &m.ambient_texname},
                                                              {"map_Ks", &m.specular_texname},
                                                              {"map_Ns", &m.specular_highlight_texname},
                                                              {"bump", &m.bump_texname},
                                                              {"disp", &m.displacement_texname},
                                                              {"refl", &m.reflection_texname},
                                                              {"map_Pr", &m.roughness_texname},
                                                              {"map_Pm", &m.metallic_texname},
                                                              {"norm", &m.normal_texname}};
  for (const auto& [slot, name] : slots)
    if (!name->empty()) maps.push_back(slot);
  return maps;
}

// map_Kd of each material as an image texture (texture.h) multiplying Kd, map_Ke multiplying Ke,
// map_d as an alpha mask (docs/renderer.md, "Alpha masks"); the other maps are warned about once per
// material. An image is resolved like an mtllib (scene_reference.h: inside `root`, relative to the OBJ's
// folder) and read once however many materials use it.
void ReadObjTextures(const std::vector<tinyobj::material_t>& materials, const std::filesystem::path& root,
                     const std::filesystem::path& base_dir, const std::string& file, PixelAllowance* texels,
                     SceneDescription* scene) {
  std::map<std::filesystem::path, std::shared_ptr<const Image>> images;
  std::map<std::filesystem::path,
           std::pair<std::shared_ptr<const Image>, std::shared_ptr<const std::vector<float>>>>
      masks;
  for (size_t i = 0; i < materials.size(); ++i) {
    const tinyobj::material_t& tm = materials[i];
    const std::string where = "material '" + tm.name + "'";
    const std::vector<std::string> unapplied = UnappliedMaps(tm);
    if (!unapplied.empty()) {
      std::string list;
      for (const std::string& m : unapplied) list += (list.empty() ? "" : ", ") + m;
      scene->warnings.push_back(file + ": " + where + ": " + list +
                                " not applied (only map_Kd, map_d and map_Ke are)");
    }
    // The image `name` names for `slot`, resolved, decoded by `read` (errors name the slot).
    const auto resolve = [&](const char* slot, const std::string& name, std::string* ref) {
      *ref = std::string(slot) + " " + QuoteReference(name);
      std::filesystem::path resolved;
      const std::string problem = SceneReferenceProblem(root, base_dir, name, &resolved);
      if (!problem.empty()) throw InputError(SourceLocation{file, 0}, where + ": " + *ref + " " + problem);
      return resolved;
    };
    const auto read = [&](const std::string& ref, const std::filesystem::path& path, ImageCodes codes) {
      try {
        return ReadImageWithAlpha(path, codes, texels);
      } catch (const LimitError& e) {
        throw LimitError(SourceLocation{file, 0}, where + ": " + ref + ": " + e.reason());
      } catch (const InputError& e) {
        throw InputError(SourceLocation{file, 0}, where + ": " + ref + ": " + e.reason());
      }
    };
    const auto wrap_of = [&](const std::string& ref, const tinyobj::texture_option_t& opt) {
      if (opt.scale[0] != 1 || opt.scale[1] != 1 || opt.origin_offset[0] != 0 || opt.origin_offset[1] != 0)
        scene->warnings.push_back(file + ": " + where + ": " + ref + ": options -s and -o are not applied");
      return opt.clamp ? TextureWrap::kClampToEdge : TextureWrap::kRepeat;
    };
    // A colour map (sRGB) of `statement` as a new scene texture; its index.
    const auto colour_texture = [&](const char* statement, const std::string& name,
                                    const tinyobj::texture_option_t& opt) {
      std::string ref;
      const std::filesystem::path resolved = resolve(statement, name, &ref);
      std::shared_ptr<const Image>& image = images[resolved];
      if (!image) image = std::make_shared<const Image>(read(ref, resolved, ImageCodes::kColor).rgb);
      Texture texture;
      texture.source = name;
      texture.image = image;
      texture.wrap_u = texture.wrap_v = wrap_of(ref, opt);
      scene->textures.push_back(std::move(texture));
      return int32_t(scene->textures.size() - 1);
    };
    if (!tm.diffuse_texname.empty())
      scene->materials[i].base_color_texture =
          colour_texture("map_Kd", tm.diffuse_texname, tm.diffuse_texopt);
    if (!tm.emissive_texname.empty() && !scene->materials[i].IsEmissive())
      scene->warnings.push_back(file + ": " + where +
                                ": map_Ke not applied (the material has no Ke to multiply)");
    // map_Ke multiplies Ke (sRGB, like map_Kd); without Ke it has nothing to multiply.
    if (!tm.emissive_texname.empty() && scene->materials[i].IsEmissive())
      scene->materials[i].emission_texture =
          colour_texture("map_Ke", tm.emissive_texname, tm.emissive_texopt);
    if (!tm.alpha_texname.empty()) {
      std::string ref;
      const std::filesystem::path resolved = resolve("map_d", tm.alpha_texname, &ref);
      if (scene->materials[i].IsEmissive()) {
        scene->warnings.push_back(file + ": " + where + ": " + ref +
                                  " not applied to an emitting material (the surface is opaque)");
        continue;
      }
      auto& mask = masks[resolved];
      if (!mask.first) {
        // The map's alpha channel when it has one, else its (grey) value: linear either way.
        ImageWithAlpha im = read(ref, resolved, ImageCodes::kData);
        if (im.alpha.empty()) {
          im.alpha.resize(im.rgb.size());
          for (size_t k = 0; k < im.rgb.size(); ++k) im.alpha[k] = im.rgb[k].r;
        }
        mask.first = std::make_shared<const Image>(std::move(im.rgb));
        mask.second = std::make_shared<const std::vector<float>>(std::move(im.alpha));
      }
      Texture texture;
      texture.source = tm.alpha_texname;
      texture.image = mask.first;
      texture.alpha = mask.second;
      texture.wrap_u = texture.wrap_v = wrap_of(ref, tm.alpha_texopt);
      Material& m = scene->materials[i];
      m.alpha_texture = int32_t(scene->textures.size());
      m.alpha_cutoff = kObjAlphaCutoff;
      scene->textures.push_back(std::move(texture));
    }
  }
}

}  // namespace

float WardAlphaFromPhongExponent(float ns) {
  if (!(ns >= 0.0f)) ns = 0.0f;  // also maps NaN to 0
  if (ns >= kMirrorPhongExponent) return 0.0f;
  return std::sqrt(2.0f / (ns + 2.0f));
}

bool ClampEnergy(Material* m) {
  bool clamped = false;
  for (int i = 0; i < 3; ++i) {
    const float sum = m->diffuse_reflectance[i] + m->specular_reflectance[i] + m->diffuse_transmittance[i] +
                      m->specular_transmittance[i];
    if (sum > 1.0f + kEnergyTolerance) {
      const float s = 1.0f / sum;
      m->diffuse_reflectance[i] *= s;
      m->specular_reflectance[i] *= s;
      m->diffuse_transmittance[i] *= s;
      m->specular_transmittance[i] *= s;
      clamped = true;
    }
  }
  return clamped;
}

Material MaterialFromMtl(const MtlParameters& mtl, std::vector<std::string>* warnings) {
  auto warn = [&](const std::string& reason) {
    if (warnings) warnings->push_back("material '" + mtl.name + "': " + reason);
  };
  const Rgb kd = NonNegative(mtl.kd, mtl.name, "Kd", warnings);
  const Rgb ks = NonNegative(mtl.ks, mtl.name, "Ks", warnings);
  const Rgb ke = NonNegative(mtl.ke, mtl.name, "Ke", warnings);
  const Rgb tf = NonNegative(mtl.tf, mtl.name, "Tf", warnings);

  Material m;
  m.name = mtl.name;
  m.emission = ke;

  const bool glass = mtl.illum == 4 || mtl.illum == 6 || mtl.illum == 7;
  if (glass) {
    m.specular_transmittance = tf.IsBlack() ? Rgb(1.0f) : tf;
    m.ior = std::isfinite(mtl.ni) ? mtl.ni : 1.0f;
    if (!(m.ior > 1.0f))
      warn("glass (illum " + std::to_string(mtl.illum) + ") with Ni " + std::to_string(mtl.ni) +
           " <= 1: light passes straight through without refraction");
    if (!kd.IsBlack() || !ks.IsBlack())
      warn("glass (illum " + std::to_string(mtl.illum) +
           ") reflects by Fresnel's law; its Kd/Ks are ignored");
  } else {
    m.diffuse_reflectance = kd;
    m.specular_reflectance = ks;
    if (!ks.IsBlack()) {
      const bool mirror_illum = mtl.illum == 3 || mtl.illum == 5;
      m.specular_roughness = mirror_illum ? 0.0f : WardAlphaFromPhongExponent(mtl.ns);
    }
    const float d = std::isfinite(mtl.d) ? std::clamp(mtl.d, 0.0f, 1.0f) : 1.0f;
    if (d < 1.0f) {
      m.specular_transmittance = Rgb(1.0f - d);
      m.diffuse_reflectance *= d;
      m.specular_reflectance *= d;
      m.ior = 1.0f;
    } else if (!tf.IsBlack() && !(tf == Rgb(1.0f))) {
      warn("Tf " + FormatRgb(tf) + " ignored: the material is opaque (illum " + std::to_string(mtl.illum) +
           ", d = 1); use illum 4/6/7 for glass or a manifest material override");
    }
  }
  if (ClampEnergy(&m)) warn("reflectance + transmittance exceeds 1 in some channel; scaled down to 1");
  return m;
}

SceneDescription LoadObj(const std::filesystem::path& path, const std::filesystem::path& root,
                         const SceneBudget& budget, SceneExpansion* counts, PixelAllowance* texels) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(SourceLocation{file, 0}, "no such file");
  // Counted and checked before tinyobjloader stores anything (its arrays are the peak of a load).
  // The file is read twice, as a stream, rather than held in memory (a copy of it was 1/6 of the
  // peak of a 5M-face OBJ: docs/security.md "Scene budgets").
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(SourceLocation{file, 0}, "cannot open file for reading");
  const SceneExpansion statements = ScanStatements(in, file, budget);
  if (counts) *counts = statements;
  in.clear();
  in.seekg(0);
  if (!in) throw InputError(SourceLocation{file, 0}, "cannot read the file a second time");

  const std::filesystem::path base_dir = path.has_parent_path() ? path.parent_path() : ".";
  ConfinedMtlReader mtl_reader(root.empty() ? base_dir : root, base_dir);
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string tiny_warning, tiny_error;
  const bool ok = tinyobj::LoadObj(&attrib, &shapes, &materials, &tiny_warning, &tiny_error, &in, &mtl_reader,
                                   /*triangulate=*/true,
                                   /*default_vcols_fallback=*/false);
  // Not needed (texture coordinates: unless a material has a texture): released before the scene
  // is built next to tinyobjloader's arrays.
  const bool textured = std::any_of(materials.begin(), materials.end(), [](const tinyobj::material_t& m) {
    return !m.diffuse_texname.empty() || !m.alpha_texname.empty() || !m.emissive_texname.empty();
  });
  if (!textured) std::vector<tinyobj::real_t>().swap(attrib.texcoords);
  std::vector<tinyobj::real_t>().swap(attrib.colors);
  if (!mtl_reader.refused_reference().empty()) {
    const std::string& ref = mtl_reader.refused_reference();
    throw InputError(SourceLocation{file, MtllibLine(path, ref)},
                     "mtllib " + QuoteReference(ref) + " " + mtl_reader.refusal());
  }

  SceneDescription scene;
  scene.source = file;
  for (const std::string& ref : mtl_reader.missing())
    scene.warnings.push_back(file + ": mtllib " + QuoteReference(ref) +
                             ": no such file in the scene folder; its materials are missing");

  // tinyobjloader's warnings: fatal ones become errors, the rest are passed on.
  bool fatal_warning = false;
  std::string fatal_text;
  for (const std::string& w : SplitLines(tiny_warning)) {
    if (IsFatalWarning(w)) {
      fatal_warning = true;
      if (fatal_text.empty()) fatal_text = w;
    } else {
      scene.warnings.push_back(file + ": " + w);
    }
  }
  if (!ok || !tiny_error.empty()) {
    const std::vector<std::string> lines = SplitLines(tiny_error);
    std::string message = lines.empty() ? "tinyobjloader failed to parse the file" : lines[0];
    for (size_t i = 1; i < lines.size(); ++i) message += "; " + lines[i];
    throw InputError(SourceLocation{file, LineFromMessage(message)}, message);
  }

  const long num_v = long(attrib.vertices.size() / 3);
  const long num_vn = long(attrib.normals.size() / 3);
  const long num_vt = long(attrib.texcoords.size() / 2);  // 0 unless textured
  auto bad_faces = [&](const std::string& reason) {
    const int line = FindFirstBadFaceLine(path, num_v, num_vn);
    throw InputError(SourceLocation{file, line},
                     line > 0 ? "face references a vertex or normal that does not exist" : reason);
  };
  if (fatal_warning) bad_faces(fatal_text);

  // Materials in MTL order; "(default)" appended on demand.
  for (const tinyobj::material_t& tm : materials) {
    std::vector<std::string> material_warnings;
    scene.materials.push_back(MaterialFromMtl(FromTinyObj(tm), &material_warnings));
    for (const std::string& w : material_warnings) scene.warnings.push_back(file + ": " + w);
    const auto positive = [](const tinyobj::real_t* c) { return c[0] > 0 || c[1] > 0 || c[2] > 0; };
    if (positive(tm.ambient) && !scene.materials.back().IsEmissive())
      scene.ambient_only_materials.push_back(tm.name);
  }
  PixelAllowance own(budget.max_texels);
  ReadObjTextures(materials, root.empty() ? base_dir : root, base_dir, file,
                  texels != nullptr ? texels : &own, &scene);
  uint32_t default_material = kNoLight;  // "none yet"
  auto material_index = [&](int id) -> uint32_t {
    if (id >= 0 && size_t(id) < scene.materials.size()) return uint32_t(id);
    if (default_material == kNoLight) {
      Material grey;
      grey.name = "(default)";
      grey.diffuse_reflectance = Rgb(kDefaultGrey);
      default_material = uint32_t(scene.materials.size());
      scene.materials.push_back(grey);
      scene.warnings.push_back(file + ": faces without a material use a grey diffuse (" +
                               std::to_string(kDefaultGrey) + ")");
    }
    return default_material;
  };

  // The scene's frame (scene_frame.h) from the double-precision bounds of the vertices the faces
  // use (tinyobjloader parses in double here: TINYOBJLOADER_USE_DOUBLE), before any is rounded.
  uint64_t triangles = 0;  // n − 2 per face: what the loop below emits at most
  uint64_t corners = 0;
  WorldBounds bounds;
  auto world_position = [&](size_t v) {
    return Vec3d(attrib.vertices[3 * v], attrib.vertices[3 * v + 1], attrib.vertices[3 * v + 2]);
  };
  for (const tinyobj::shape_t& shape : shapes) {
    size_t offset = 0;
    for (const unsigned int n : shape.mesh.num_face_vertices) {
      for (size_t k = 0; n >= 3 && k < n && offset + k < shape.mesh.indices.size(); ++k) {
        const int v = shape.mesh.indices[offset + k].vertex_index;
        if (v >= 0 && v < num_v) bounds.Extend(world_position(size_t(v)));
      }
      triangles += n >= 3 ? n - 2 : 0;
      corners += n >= 3 ? n : 0;
      offset += n;
    }
  }
  scene.origin = SceneFrameOrigin(bounds);
  // Sized once, so that the vectors do not grow by doubling next to tinyobjloader's arrays: the
  // triangles exactly (less the degenerate ones), the vertices for one normal per position (the
  // usual case; more pairs grow the vector).
  scene.triangles.reserve(size_t(std::min<uint64_t>(triangles, budget.max_triangles)));
  scene.triangle_material.reserve(scene.triangles.capacity());
  scene.triangle_light.reserve(scene.triangles.capacity());
  const size_t expected_vertices =
      size_t(std::min<uint64_t>({uint64_t(num_v), corners, budget.max_vertices}));
  scene.positions.reserve(expected_vertices);

  // Vertices shared per (position, normal, texture coordinate).
  VertexTable vertex_of{size_t(num_v)};
  if (textured) scene.uvs.reserve(expected_vertices);
  std::vector<Vec3> normals;
  if (num_vn > 0) normals.reserve(expected_vertices);
  bool any_normal = false;
  auto vertex = [&](const tinyobj::index_t& idx) -> uint32_t {
    if (idx.vertex_index < 0 || idx.vertex_index >= num_v || idx.normal_index < -1 ||
        idx.normal_index >= num_vn)
      bad_faces("face references a vertex or normal that does not exist");
    // Without textures the coordinates are not read (num_vt is 0): every `vt` counts as none.
    const bool has_uv = idx.texcoord_index >= 0 && idx.texcoord_index < num_vt;
    if (textured && idx.texcoord_index >= num_vt)
      bad_faces("face references a texture coordinate that does not exist");
    const uint64_t attributes = uint64_t(uint32_t(idx.normal_index + 1)) |
                                uint64_t(has_uv ? uint32_t(idx.texcoord_index + 1) : 0u) << 32;
    return vertex_of.Find(uint32_t(idx.vertex_index), attributes, [&] {
      const Vec3 p = InSceneFrame(world_position(size_t(idx.vertex_index)), scene.origin);
      if (!IsFinite(p))
        throw InputError(SourceLocation{file, 0},
                         "vertex " + std::to_string(idx.vertex_index + 1) + " is not finite");
      if (scene.positions.size() >= std::min<uint64_t>(budget.max_vertices, 0xfffffff0u))
        throw InputError(SourceLocation{file, 0}, "more than " + std::to_string(budget.max_vertices) +
                                                      " vertices (SceneBudget::max_vertices)");
      scene.positions.push_back(p);
      Vec3 n(0.0f);
      if (idx.normal_index >= 0) {
        const size_t k = size_t(idx.normal_index) * 3;
        const Vec3 raw(float(attrib.normals[k]), float(attrib.normals[k + 1]), float(attrib.normals[k + 2]));
        const float len2 = LengthSquared(raw);
        if (std::isfinite(len2) && len2 > 0.0f) {
          n = raw / std::sqrt(len2);
          any_normal = true;
        }
      }
      normals.push_back(n);
      if (textured) {
        // OBJ's v runs upwards, glTF's (texture.h) downwards from the image's top.
        const size_t k = size_t(has_uv ? idx.texcoord_index : 0) * 2;
        scene.uvs.push_back(
            has_uv ? TextureCoordinates{float(attrib.texcoords[k]), 1.0f - float(attrib.texcoords[k + 1])}
                   : TextureCoordinates{0.0f, 0.0f});
      }
      return uint32_t(scene.positions.size() - 1);
    });
  };

  size_t degenerate = 0;
  for (const tinyobj::shape_t& shape : shapes) {
    const tinyobj::mesh_t& mesh = shape.mesh;
    uint32_t light = kNoLight;
    size_t offset = 0;
    for (size_t f = 0; f < mesh.num_face_vertices.size(); ++f) {
      const size_t n = mesh.num_face_vertices[f];
      const int material_id = f < mesh.material_ids.size() ? mesh.material_ids[f] : -1;
      if (offset + n > mesh.indices.size()) bad_faces("inconsistent face data from tinyobjloader");
      const uint32_t mat = material_index(material_id);
      const bool emissive = scene.materials[mat].IsEmissive();
      // Triangulated already; a fan covers anything tinyobjloader left as a polygon.
      for (size_t k = 1; k + 1 < n; ++k) {
        const std::array<uint32_t, 3> tri{vertex(mesh.indices[offset]), vertex(mesh.indices[offset + k]),
                                          vertex(mesh.indices[offset + k + 1])};
        const Vec3 e = Cross(scene.positions[tri[1]] - scene.positions[tri[0]],
                             scene.positions[tri[2]] - scene.positions[tri[0]]);
        if (!(LengthSquared(e) > 0.0f)) {
          ++degenerate;
          continue;
        }
        if (emissive && light == kNoLight) light = scene.num_lights++;
        if (scene.triangles.size() >= budget.max_triangles)
          throw InputError(SourceLocation{file, 0}, "more than " + std::to_string(budget.max_triangles) +
                                                        " triangles (SceneBudget::max_triangles)");
        scene.triangles.push_back(tri);
        scene.triangle_material.push_back(mat);
        scene.triangle_light.push_back(emissive ? light : kNoLight);
      }
      offset += n;
    }
  }
  if (degenerate > 0)
    scene.warnings.push_back(file + ": " + std::to_string(degenerate) +
                             " degenerate (zero-area) triangles dropped");
  if (any_normal) scene.normals = std::move(normals);
  if (scene.triangles.empty()) scene.warnings.push_back(file + ": the file contains no triangles");
  return scene;
}

}  // namespace pf

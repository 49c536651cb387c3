// Manifest parsing with nlohmann-json. Every access goes through a helper that knows the key
// path, so a type error names the key ("cameras[0].eye") — nlohmann's own type errors do not
// say where they happened. JSON syntax errors carry a byte offset, converted to a line.
#include "common/scene/manifest.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "common/core/error.h"
#include "common/scene/material_kinds.h"

namespace pf {
namespace {

using Json = nlohmann::json;

constexpr int kMaxResolution = 65536;
constexpr int64_t kMaxFrameNumber = 999999;

class Parser {
 public:
  Parser(std::string file, std::vector<std::string>* warnings)
      : file_(std::move(file)), warnings_(warnings) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& reason) const {
    throw InputError(SourceLocation{file_, 0}, "key '" + key + "': " + reason);
  }

  void Warn(const std::string& reason) const { warnings_->push_back(file_ + ": " + reason); }

  // Warns about keys of `object` not in `known`.
  void CheckKeys(const Json& object, const std::string& prefix,
                 std::initializer_list<const char*> known) const {
    for (auto it = object.begin(); it != object.end(); ++it) {
      bool found = false;
      for (const char* k : known) found = found || it.key() == k;
      if (!found) Warn("key '" + Join(prefix, it.key()) + "' is not part of the manifest format; ignored");
    }
  }

  static std::string Join(const std::string& prefix, const std::string& key) {
    return prefix.empty() ? key : prefix + "." + key;
  }

  std::string String(const Json& v, const std::string& key) const {
    if (!v.is_string()) Fail(key, "expected a string");
    return v.get<std::string>();
  }

  double Number(const Json& v, const std::string& key) const {
    if (!v.is_number()) Fail(key, "expected a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) Fail(key, "expected a finite number");
    return d;
  }

  double PositiveNumber(const Json& v, const std::string& key) const {
    const double d = Number(v, key);
    if (!(d > 0.0)) Fail(key, "expected a number > 0");
    return d;
  }

  // A world point: kept in double (scene_frame.h); it must still be finite as a float, like
  // every world coordinate (docs/security.md, "Limits").
  Vec3d Point(const Json& v, const std::string& key) const {
    if (!v.is_array() || v.size() != 3) Fail(key, "expected 3 numbers");
    Vec3d p;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number()) Fail(key, "expected 3 numbers");
      p[i] = v[i].get<double>();
      if (!std::isfinite(float(p[i]))) Fail(key, "expected 3 finite numbers");
    }
    return p;
  }

  Vec3 Direction(const Json& v, const std::string& key) const { return Vec3(Point(v, key)); }

  // A colour: 3 non-negative numbers, or one number for grey.
  Rgb Colour(const Json& v, const std::string& key) const {
    if (v.is_number()) {
      const float g = float(Number(v, key));
      if (!std::isfinite(g) || g < 0.0f) Fail(key, "expected a finite non-negative number");
      return Rgb(g);
    }
    if (!v.is_array() || v.size() != 3) Fail(key, "expected 3 non-negative numbers or one number");
    Rgb c;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number()) Fail(key, "expected 3 non-negative numbers or one number");
      c[i] = v[i].get<float>();
      if (!std::isfinite(c[i]) || c[i] < 0.0f)
        Fail(key, "expected 3 finite non-negative numbers or one number");
    }
    return c;
  }

  // A camera's or a camera key's required "eye" and "look_at".
  void View(const Json& v, const std::string& key, Vec3d* eye, Vec3d* look_at) const {
    if (!v.contains("eye")) Fail(key + ".eye", "missing (expected 3 numbers)");
    if (!v.contains("look_at")) Fail(key + ".look_at", "missing (expected 3 numbers)");
    *eye = Point(v["eye"], key + ".eye");
    *look_at = Point(v["look_at"], key + ".look_at");
  }

  float FieldOfView(const Json& v, const std::string& key) const {
    const double fov = Number(v, key);
    if (!(fov > 0.0 && fov < 180.0)) Fail(key, "expected degrees in (0, 180)");
    return float(fov);
  }

  // "camera_path": [{"frame": 1, "eye": [...], "look_at": [...], "up"?: [...], "fov"?: deg}, ...],
  // frames integers ≥ 0 in strictly increasing order.
  CameraPath Path(const Json& v, const std::string& key) const {
    if (!v.is_array() || v.empty()) Fail(key, "expected a non-empty array of camera keys");
    CameraPath path;
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string k = key + "[" + std::to_string(i) + "]";
      const Json& e = v[i];
      if (!e.is_object()) Fail(k, "expected an object");
      CheckKeys(e, k, {"frame", "eye", "look_at", "up", "fov"});
      CameraKey c;
      if (!e.contains("frame") || !e["frame"].is_number_integer() || e["frame"].get<int64_t>() < 0 ||
          e["frame"].get<int64_t>() > kMaxFrameNumber)
        Fail(k + ".frame", "expected an integer in [0, " + std::to_string(kMaxFrameNumber) + "]");
      c.frame = int(e["frame"].get<int64_t>());
      if (!path.keys.empty() && c.frame <= path.keys.back().frame)
        Fail(k + ".frame", "expected frames in strictly increasing order (the key before is frame " +
                               std::to_string(path.keys.back().frame) + ")");
      View(e, k, &c.eye, &c.look_at);
      if (e.contains("up")) c.up = Direction(e["up"], k + ".up");
      if (e.contains("fov")) c.vfov_degrees = FieldOfView(e["fov"], k + ".fov");
      path.keys.push_back(c);
    }
    return path;
  }

  CameraSpec Camera(const Json& v, const std::string& key, size_t index) const {
    if (!v.is_object()) Fail(key, "expected an object");
    CheckKeys(v, key, {"name", "eye", "look_at", "up", "fov", "resolution"});
    CameraSpec cam;
    cam.name = "camera" + std::to_string(index);
    if (v.contains("name")) {
      cam.name = String(v["name"], key + ".name");
      if (cam.name.empty()) Fail(key + ".name", "expected a non-empty string");
    }
    View(v, key, &cam.eye, &cam.look_at);
    if (v.contains("up")) cam.up = Direction(v["up"], key + ".up");
    if (v.contains("fov")) cam.vfov_degrees = FieldOfView(v["fov"], key + ".fov");
    if (v.contains("resolution")) {
      const Json& r = v["resolution"];
      const std::string rkey = key + ".resolution";
      const char* expect = "expected 2 positive integers [width, height]";
      if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
        Fail(rkey, expect);
      const int64_t w = r[0].get<int64_t>(), h = r[1].get<int64_t>();
      if (w <= 0 || h <= 0) Fail(rkey, expect);
      if (w > kMaxResolution || h > kMaxResolution)
        Fail(rkey, "width and height must be at most " + std::to_string(kMaxResolution));
      cam.width = int(w);
      cam.height = int(h);
    }
    const Vec3 forward(cam.look_at - cam.eye);
    if (!(LengthSquared(forward) > 0.0f)) Fail(key + ".look_at", "must differ from eye");
    if (!(LengthSquared(Cross(Normalize(forward), cam.up)) > 1e-12f))
      Fail(key + ".up", "must not be zero or parallel to the view direction");
    return cam;
  }

  MaterialOverride Override(const Json& v, const std::string& key) const {
    if (!v.is_object()) Fail(key, "expected an object");
    CheckKeys(v, key, {"kind", "diffuse", "specular", "roughness", "transmission", "ior", "emission"});
    MaterialOverride o;
    if (v.contains("kind")) {
      const MaterialKind* kind = MaterialKinds().Get(String(v["kind"], key + ".kind"));
      if (!kind) Fail(key + ".kind", "expected one of " + QuotedMaterialKindNames());
      o.kind = kind->kind;
    }
    if (v.contains("diffuse")) o.diffuse = Colour(v["diffuse"], key + ".diffuse");
    if (v.contains("specular")) o.specular = Colour(v["specular"], key + ".specular");
    if (v.contains("transmission")) o.transmission = Colour(v["transmission"], key + ".transmission");
    if (v.contains("emission")) o.emission = Colour(v["emission"], key + ".emission");
    if (v.contains("roughness")) {
      const double a = Number(v["roughness"], key + ".roughness");
      if (a < 0.0) Fail(key + ".roughness", "expected a number >= 0");
      o.roughness = float(a);
    }
    if (v.contains("ior")) o.ior = float(PositiveNumber(v["ior"], key + ".ior"));
    // Each kind checks the parameters it needs (material_kinds.h).
    if (const MaterialKind* kind = MaterialKinds().GetKind(o.kind))
      kind->check(o, [&](const std::string& parameter, const std::string& reason) {
        Fail(key + "." + parameter, reason);
      });
    return o;
  }

  // A "lights" entry (punctual_light.h; docs/scene-manifest.md, "lights"). Keys another type
  // does not use are warned about, like unknown keys.
  PunctualLight Light(const Json& v, const std::string& key) const {
    using Kind = PunctualLight::Kind;
    if (!v.is_object()) Fail(key, "expected an object");
    CheckKeys(
        v, key,
        {"type", "name", "position", "direction", "color", "intensity", "inner_cone_deg", "outer_cone_deg"});
    PunctualLight l;
    if (!v.contains("type")) Fail(key + ".type", "missing (expected \"point\", \"spot\" or \"directional\")");
    const std::string type = String(v["type"], key + ".type");
    if (type == "point") {
      l.kind = Kind::kPoint;
    } else if (type == "spot") {
      l.kind = Kind::kSpot;
    } else if (type == "directional") {
      l.kind = Kind::kDirectional;
    } else {
      Fail(key + ".type", "expected \"point\", \"spot\" or \"directional\"");
    }
    const auto unused = [&](const char* name) {
      if (v.contains(name))
        Warn("key '" + key + "." + name + "' is not used by a " + type + " light; ignored");
    };
    if (v.contains("name")) l.name = String(v["name"], key + ".name");
    if (l.kind == Kind::kDirectional) {
      unused("position");
    } else {
      if (!v.contains("position")) Fail(key + ".position", "missing (expected 3 numbers)");
      l.position = Point(v["position"], key + ".position");
    }
    if (l.kind == Kind::kPoint) {
      unused("direction");
    } else {
      if (!v.contains("direction")) Fail(key + ".direction", "missing (expected 3 numbers)");
      const Vec3 d = Direction(v["direction"], key + ".direction");
      if (!(LengthSquared(d) > 0.0f) || !IsFinite(Normalize(d)))
        Fail(key + ".direction", "expected a non-zero vector");
      l.direction = Normalize(d);
    }
    const Rgb color = v.contains("color") ? Colour(v["color"], key + ".color") : Rgb(1.0f);
    const float intensity =
        v.contains("intensity") ? float(Number(v["intensity"], key + ".intensity")) : 1.0f;
    if (!(intensity >= 0.0f) || !std::isfinite(intensity))
      Fail(key + ".intensity", "expected a finite number >= 0");
    l.intensity = color * intensity;
    if (l.intensity.IsBlack() || !l.intensity.IsFinite())
      Fail(key + (v.contains("intensity") ? ".intensity" : ".color"),
           "color x intensity must be finite and not black (a light that emits nothing)");
    // Its power (4π·I, or E⊥ over the scene's disc) must stay a finite float: 1e20 W/sr is
    // ~10^17 times the brightest lamp anyone models.
    if (l.intensity.Max() > kMaxLightIntensity)
      Fail(key + (v.contains("intensity") ? ".intensity" : ".color"),
           "color x intensity exceeds " + std::to_string(kMaxLightIntensity) + " in a channel");
    if (l.kind == Kind::kSpot) {
      const auto angle = [&](const char* name, float fallback) {
        if (!v.contains(name)) return fallback;
        const double a = Number(v[name], key + "." + name);
        if (!(a >= 0.0 && a <= 90.0)) Fail(key + "." + name, "expected degrees in [0, 90]");
        return float(a);
      };
      l.inner_cone_deg = angle("inner_cone_deg", 0.0f);
      l.outer_cone_deg = angle("outer_cone_deg", 45.0f);
      // The falloff divides by cos θi − cos θo: narrower than 0.1° and float cosines of the two
      // angles are too close to tell apart (the spot would emit nothing).
      if (!(l.outer_cone_deg >= l.inner_cone_deg + kMinSpotFalloffDeg))
        Fail(key + ".outer_cone_deg", "expected an angle at least " + std::to_string(kMinSpotFalloffDeg) +
                                          " degrees greater than inner_cone_deg (" +
                                          std::to_string(l.inner_cone_deg) + ")");
    } else {
      unused("inner_cone_deg");
      unused("outer_cone_deg");
    }
    return l;
  }

  // The "environment" object (environment.h; docs/scene-manifest.md, "environment"): a constant
  // "color" or an image "file", with "rotation" (degrees about +Y) and "strength".
  Environment EnvironmentOf(const Json& v, const std::string& key) const {
    if (!v.is_object()) Fail(key, "expected an object with \"color\" or \"file\"");
    CheckKeys(v, key, {"color", "file", "rotation", "strength"});
    Environment e;
    if (v.contains("color") == v.contains("file"))
      Fail(key, "expected exactly one of \"color\" (constant radiance) and \"file\" (an image)");
    if (v.contains("file")) {
      e.file = String(v["file"], key + ".file");
      if (e.file.empty()) Fail(key + ".file", "expected a non-empty file name");
    } else {
      e.color = Colour(v["color"], key + ".color");
      if (e.color.IsBlack())
        Fail(key + ".color", "expected a colour that is not black (a light that emits nothing)");
    }
    if (v.contains("rotation")) e.rotation_deg = float(Number(v["rotation"], key + ".rotation"));
    if (v.contains("strength")) {
      e.strength = float(Number(v["strength"], key + ".strength"));
      if (!(e.strength > 0.0f) || !std::isfinite(e.strength))
        Fail(key + ".strength", "expected a finite number > 0");
    }
    // Every power (π·R²·∫L dω) must stay a finite float, like a punctual light's.
    if ((e.color * e.strength).Max() > kMaxLightIntensity || !(e.color * e.strength).IsFinite())
      Fail(key + ".color",
           "color x strength exceeds " + std::to_string(kMaxLightIntensity) + " in a channel");
    return e;
  }

 private:
  std::string file_;
  std::vector<std::string>* warnings_;
};

int LineOfByte(const std::string& text, size_t byte) {
  byte = std::min(byte, text.size());
  int line = 1;
  for (size_t i = 0; i < byte; ++i) line += text[i] == '\n';
  return line;
}

// nlohmann's messages start with "[json.exception.parse_error.101] "; the id is noise here.
std::string StripExceptionId(const std::string& what) {
  if (!what.empty() && what[0] == '[') {
    const size_t close = what.find("] ");
    if (close != std::string::npos) return what.substr(close + 2);
  }
  return what;
}

}  // namespace

SceneManifest ParseManifest(const std::string& text, const std::filesystem::path& file) {
  const std::string file_name = file.string();
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::parse_error& e) {
    throw InputError(SourceLocation{file_name, LineOfByte(text, e.byte == 0 ? 0 : e.byte - 1)},
                     "invalid JSON: " + StripExceptionId(e.what()));
  } catch (const Json::exception& e) {
    // Not a syntax error but a value the parser cannot hold (e.g. `1E400` overflows a double:
    // out_of_range.406). nlohmann reports no byte offset for these, so point at the first line
    // that contains the quoted token, if the message names one.
    const std::string what = StripExceptionId(e.what());
    int line = 0;
    const size_t open = what.find('\'');
    const size_t close = open == std::string::npos ? open : what.find('\'', open + 1);
    if (close != std::string::npos) {
      const size_t at = text.find(what.substr(open + 1, close - open - 1));
      if (at != std::string::npos) line = LineOfByte(text, at);
    }
    throw InputError(SourceLocation{file_name, line}, "invalid JSON: " + what);
  }

  SceneManifest m;
  m.file = file;
  Parser p(file_name, &m.warnings);
  if (!root.is_object()) throw InputError(SourceLocation{file_name, 0}, "a manifest must be a JSON object");
  p.CheckKeys(root, "",
              {"version", "name", "geometry", "scale", "cameras", "camera_path", "lights", "environment",
               "settings", "materials", "notes"});

  if (root.contains("version")) {
    const Json& v = root["version"];
    if (!v.is_number_integer() || v.get<int64_t>() != 1)
      p.Fail("version", "expected 1 (the only manifest version so far)");
  }

  m.name = root.contains("name") ? p.String(root["name"], "name") : file.stem().string();

  if (!root.contains("geometry")) p.Fail("geometry", "missing (expected a file name)");
  const std::string geometry = p.String(root["geometry"], "geometry");
  if (geometry.empty()) p.Fail("geometry", "expected a non-empty file name");
  m.geometry_reference = geometry;
  if (const size_t at = text.find("\"geometry\""); at != std::string::npos)
    m.geometry_line = LineOfByte(text, at);
  std::filesystem::path g(geometry);
  if (g.is_relative()) g = file.parent_path() / g;
  m.geometry = g.lexically_normal();

  if (root.contains("scale")) {
    m.scale = p.PositiveNumber(root["scale"], "scale");
    if (const size_t at = text.find("\"scale\""); at != std::string::npos)
      m.scale_line = LineOfByte(text, at);
  }

  if (root.contains("cameras")) {
    const Json& cams = root["cameras"];
    if (!cams.is_array()) p.Fail("cameras", "expected an array of camera objects");
    std::set<std::string> names;
    for (size_t i = 0; i < cams.size(); ++i) {
      const std::string key = "cameras[" + std::to_string(i) + "]";
      CameraSpec cam = p.Camera(cams[i], key, i);
      if (!names.insert(cam.name).second) p.Fail(key + ".name", "duplicate camera name \"" + cam.name + "\"");
      m.cameras.push_back(std::move(cam));
    }
  }

  if (root.contains("camera_path")) m.camera_path = p.Path(root["camera_path"], "camera_path");

  if (root.contains("lights")) {
    const Json& lights = root["lights"];
    if (!lights.is_array()) p.Fail("lights", "expected an array of light objects");
    for (size_t i = 0; i < lights.size(); ++i)
      m.lights.push_back(p.Light(lights[i], "lights[" + std::to_string(i) + "]"));
  }

  if (root.contains("environment")) m.environment = p.EnvironmentOf(root["environment"], "environment");

  if (root.contains("settings")) {
    const Json& s = root["settings"];
    if (!s.is_object()) p.Fail("settings", "expected an object");
    for (auto it = s.begin(); it != s.end(); ++it) {
      const Json& v = it.value();
      if (v.is_number()) {
        m.settings[it.key()] = p.Number(v, "settings." + it.key());
      } else if (v.is_string()) {
        m.settings[it.key()] = v.get<std::string>();
      } else {
        m.settings[it.key()] = v.dump();
      }
    }
  }

  if (root.contains("materials")) {
    const Json& mats = root["materials"];
    if (!mats.is_object()) p.Fail("materials", "expected an object (material name → changes)");
    for (auto it = mats.begin(); it != mats.end(); ++it)
      m.materials[it.key()] = p.Override(it.value(), "materials." + it.key());
  }

  if (root.contains("notes")) {
    const Json& n = root["notes"];
    if (n.is_string()) {
      m.notes = n.get<std::string>();
    } else if (n.is_array()) {
      for (size_t i = 0; i < n.size(); ++i) {
        if (!n[i].is_string()) p.Fail("notes[" + std::to_string(i) + "]", "expected a string");
        if (i > 0) m.notes += "\n";
        m.notes += n[i].get<std::string>();
      }
    } else {
      p.Fail("notes", "expected a string or an array of strings");
    }
  }
  return m;
}

SceneManifest LoadManifest(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(SourceLocation{path.string(), 0}, "no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(SourceLocation{path.string(), 0}, "cannot open file for reading");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseManifest(text.str(), path);
}

}  // namespace pf

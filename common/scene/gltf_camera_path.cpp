#include "common/scene/gltf_camera_path.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "common/core/error.h"
#include "common/scene/gltf_accessors.h"
#include "common/scene/gltf_transform.h"

namespace pf {
namespace {

using mgf::Affine;

// One sampled property: key times and their values (3 or 4 components each).
struct Track {
  std::vector<double> times;
  std::vector<double> values;  // components per key, the CUBICSPLINE tangents dropped
  int components = 3;
  bool step = false;

  // The value at time t: clamped to the first and last keys outside them.
  std::vector<double> At(double t) const {
    const size_t n = times.size();
    const auto value = [&](size_t k) {
      return std::vector<double>(values.begin() + ptrdiff_t(k) * components,
                                 values.begin() + ptrdiff_t(k + 1) * components);
    };
    if (t <= times.front()) return value(0);
    if (t >= times.back()) return value(n - 1);
    const size_t b = size_t(std::upper_bound(times.begin(), times.end(), t) - times.begin());
    const size_t a = b - 1;
    if (step) return value(a);
    const double u = (t - times[a]) / (times[b] - times[a]);
    std::vector<double> va = value(a), vb = value(b);
    std::vector<double> out(static_cast<size_t>(components));
    if (components == 3) {
      for (size_t c = 0; c < 3; ++c) out[c] = va[c] + (vb[c] - va[c]) * u;
      return out;
    }
    // Quaternions: slerp along the shorter arc (spec §3.11, Appendix C), of unit quaternions.
    for (std::vector<double>* q : {&va, &vb}) {
      double norm = 0;
      for (double v : *q) norm += v * v;
      norm = std::sqrt(norm);
      if (norm > 0 && std::isfinite(norm))
        for (double& v : *q) v /= norm;
    }
    double dot = 0;
    for (size_t c = 0; c < 4; ++c) dot += va[c] * vb[c];
    if (dot < 0) {
      for (double& v : vb) v = -v;
      dot = -dot;
    }
    double wa = 1 - u, wb = u;
    if (dot < 0.9995) {
      const double theta = std::acos(std::min(1.0, dot));
      wa = std::sin((1 - u) * theta) / std::sin(theta);
      wb = std::sin(u * theta) / std::sin(theta);
    }
    for (size_t c = 0; c < 4; ++c) out[c] = wa * va[c] + wb * vb[c];
    return out;
  }
};

Vec3d Unit(const Vec3d& v) {
  const double l = std::sqrt(Dot(v, v));
  return l > 0.0 && std::isfinite(l) ? v * (1.0 / l) : Vec3d(0.0);
}

}  // namespace

CameraPath GltfCameraPath(const GltfDocument& doc, int node, const Affine& parent,
                          std::vector<std::string>* warnings) {
  const tinygltf::Model& m = *doc.model;
  const tinygltf::Node& n = m.nodes.at(size_t(node));
  std::optional<Track> translation, rotation;
  std::string where;
  for (size_t a = 0; a < m.animations.size() && !translation && !rotation; ++a) {
    const tinygltf::Animation& anim = m.animations[a];
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& ch = anim.channels[c];
      if (ch.target_node != node) continue;
      const std::string at = "animations[" + std::to_string(a) + "].channels[" + std::to_string(c) + "]";
      const auto fail = [&](const std::string& why) {
        throw InputError(SourceLocation{doc.file, 0}, at + ": " + why);
      };
      if (ch.target_path == "scale" || ch.target_path == "weights") {
        warnings->push_back(doc.file + ": " + at + ": the camera's " + ch.target_path + " is not animated");
        continue;
      }
      if (ch.target_path != "translation" && ch.target_path != "rotation") fail("unknown target path");
      if (!n.matrix.empty()) fail("animates a node with a matrix (glTF 2.0 §3.11: only TRS nodes move)");
      if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size()) fail("no such sampler");
      const tinygltf::AnimationSampler& s = anim.samplers[size_t(ch.sampler)];
      Track track;
      track.components = ch.target_path == "rotation" ? 4 : 3;
      track.step = s.interpolation == "STEP";
      const bool cubic = s.interpolation == "CUBICSPLINE";
      if (!track.step && !cubic && s.interpolation != "LINEAR" && !s.interpolation.empty())
        fail("unknown interpolation '" + s.interpolation + "'");
      if ((ch.target_path == "rotation" ? rotation : translation).has_value())
        fail("a second " + ch.target_path + " channel for the camera (glTF 2.0 §3.11: one per path)");
      track.times = ReadGltfFloats(doc, s.input, 1);
      const std::vector<double> out = ReadGltfFloats(doc, s.output, track.components);
      const size_t keys = track.times.size(), per = cubic ? 3 : 1, k = size_t(track.components);
      if (keys == 0) fail("its sampler has no keys");
      if (out.size() != keys * per * k)
        fail("its sampler has " + std::to_string(out.size() / k) + " output values; " + std::to_string(keys) +
             " keys need " + std::to_string(keys * per));
      for (size_t i = 1; i < keys; ++i)
        if (!(track.times[i] > track.times[i - 1])) fail("its key times are not strictly increasing");
      if (track.times.front() < 0) fail("its key times start before 0");
      for (size_t i = 0; i < keys; ++i)  // CUBICSPLINE: in-tangent, value, out-tangent per key
        for (size_t c = 0; c < k; ++c) track.values.push_back(out[(i * per + (cubic ? 1 : 0)) * k + c]);
      if (cubic)
        warnings->push_back(doc.file + ": " + at +
                            ": CUBICSPLINE keys are taken as their values, linear between them");
      (ch.target_path == "rotation" ? rotation : translation) = std::move(track);
      where = "animations[" + std::to_string(a) + "]";
    }
  }
  CameraPath path;
  if (!translation && !rotation) return path;
  // A key at every frame from the first key's to the last key's, sampled at the frame's own time
  // (f − 1)/24: STEP holds between keys and rotations are slerped frame by frame, which the path's
  // linear interpolation between keys (camera_path.h) would not do.
  double t_first = 1e300, t_last = 0;
  for (const std::optional<Track>* t : {&translation, &rotation})
    if (*t) {
      t_first = std::min(t_first, (*t)->times.front());
      t_last = std::max(t_last, (*t)->times.back());
    }
  const double max_time = double(kMaxGltfPathFrames - 1) / kGltfFramesPerSecond;
  if (t_last > max_time) {
    warnings->push_back(doc.file + ": " + where + ": the camera's keys after " + std::to_string(max_time) +
                        " s (frame " + std::to_string(kMaxGltfPathFrames) + ") are not used");
    t_last = max_time;
    t_first = std::min(t_first, t_last);
  }
  const long first = 1 + std::lround(t_first * kGltfFramesPerSecond);
  const long last = 1 + std::lround(t_last * kGltfFramesPerSecond);
  const std::vector<double> rest_t = n.translation.size() == 3 ? n.translation : std::vector<double>{0, 0, 0};
  const std::vector<double> rest_r = n.rotation.size() == 4 ? n.rotation : std::vector<double>{0, 0, 0, 1};
  const std::vector<double> rest_s = n.scale.size() == 3 ? n.scale : std::vector<double>{1, 1, 1};
  for (long frame = first; frame <= last; ++frame) {
    const double time = double(frame - 1) / kGltfFramesPerSecond;
    const Affine world = mgf::Compose(parent, GltfTrs(translation ? translation->At(time) : rest_t,
                                                      rotation ? rotation->At(time) : rest_r, rest_s));
    const Vec3d forward = Unit(world.Vector(Vec3d(0, 0, -1))), up = Unit(world.Vector(Vec3d(0, 1, 0)));
    if (!world.IsFinite() || !IsFinite(Vec3(world.t)) || forward == Vec3d(0.0) || up == Vec3d(0.0))
      throw InputError(SourceLocation{doc.file, 0},
                       where + ": at frame " + std::to_string(frame) +
                           " the camera's transform is not finite or has no direction");
    path.keys.push_back({.frame = int(frame), .eye = world.t, .look_at = world.t + forward, .up = Vec3(up)});
  }
  return path;
}

}  // namespace pf

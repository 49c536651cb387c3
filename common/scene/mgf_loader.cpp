// MGF 2.0 loader. What is supported, and what was chosen where the spec is silent, is documented
// in mgf_loader.h; comments here explain how and cite the spec (mgfdoc.tr) sections.
//
// Structure: a file is read once into memory and cut into entities (words of one logical line,
// continuation lines joined); an interpreter then executes the entities, keeping the MGF
// contexts (§2.1 named contexts, §2.2 hierarchical contexts) and emitting triangles directly into
// the SceneDescription. Arrays (`xf -a N`) re-execute the entities of their block, exactly as the
// spec describes them (§2.2.3), so redefinitions inside a block behave as in mgflib.

#include "common/scene/mgf_loader.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <memory>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "common/core/error.h"
#include "common/core/math.h"
#include "common/scene/curved_primitives.h"
#include "common/scene/mgf_reader.h"
#include "common/scene/mgf_tokenizer.h"
#include "common/scene/mgf_transform.h"
#include "common/scene/polygon_triangulation.h"
#include "common/scene/scene_frame.h"
#include "common/scene/scene_reference.h"

namespace pf::mgf {
namespace {

namespace fs = std::filesystem;

constexpr long kMaxRepeat = 1'000'000;                  // largest N of `-i N` / `-a N`
constexpr uint64_t kMaxArrayInstances = 1'000'000'000;  // product of the -a counts of one xf
constexpr size_t kMaxStoredWarnings = 500;              // then only counted, to keep logs readable
constexpr int kMinCurveSegments = 3;
constexpr int kMaxCurveSegments = 1024;

Kind KindOf(std::string_view w) {
  static const std::unordered_map<std::string_view, Kind> kKinds = {
      {"o", Kind::kObject},  {"xf", Kind::kXf},        {"i", Kind::kInclude},   {"ies", Kind::kIes},
      {"c", Kind::kColor},   {"cxy", Kind::kCxy},      {"cspec", Kind::kCspec}, {"cct", Kind::kCct},
      {"cmix", Kind::kCmix}, {"m", Kind::kMaterial},   {"sides", Kind::kSides}, {"rd", Kind::kRd},
      {"td", Kind::kTd},     {"ed", Kind::kEd},        {"rs", Kind::kRs},       {"ts", Kind::kTs},
      {"ir", Kind::kIr},     {"v", Kind::kVertex},     {"p", Kind::kPoint},     {"n", Kind::kNormal},
      {"f", Kind::kFace},    {"fh", Kind::kFaceHoles}, {"sph", Kind::kSphere},  {"cyl", Kind::kCylinder},
      {"cone", Kind::kCone}, {"prism", Kind::kPrism},  {"ring", Kind::kRing},   {"torus", Kind::kTorus},
  };
  const auto it = kKinds.find(w);
  return it == kKinds.end() ? Kind::kUnknown : it->second;
}

}  // namespace

void MgfReader::Run(std::unique_ptr<MgfFile> top) {
  const MgfFile& file = *top;
  include_stack_.push_back(file.canonical);
  files_.emplace(file.canonical, std::move(top));
  // The budgets are checked on the whole expansion before anything is executed.
  const SceneExpansion expected = ExpansionOf(file);
  if (options_.counts) options_.counts->expected = expected;
  Execute(file);
  include_stack_.pop_back();
  Finish();
}

void MgfReader::ReportCounts() const {
  if (!options_.counts) return;
  options_.counts->executed_entities = executed_;
  options_.counts->emitted_triangles = scene_.triangles.size();
}

void MgfReader::Warn(const std::string& message) {
  if (scene_.warnings.size() >= kMaxStoredWarnings) {
    ++suppressed_warnings_;
    return;
  }
  std::string text = Here().ToString() + ": " + message;
  spdlog::warn("{}", text);
  scene_.warnings.push_back(std::move(text));
}

void MgfReader::ExpectCount(const Args& a, size_t lo, size_t hi, const char* usage) const {
  const size_t n = a.size() - 1;
  if (n < lo || n > hi) {
    Fail(std::string(a.keyword()) + ": expected " + usage + ", got " + std::to_string(n) + " argument" +
         (n == 1 ? "" : "s"));
  }
}

double MgfReader::Number(const Args& a, size_t i) const {
  std::string_view s = a[i];
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) {
    Fail(std::string(a.keyword()) + ": number " + Quote(a[i]) + " is out of range");
  }
  if (ec != std::errc() || end != s.data() + s.size()) {
    Fail(std::string(a.keyword()) + ": " + Quote(a[i]) + " is not a number");
  }
  if (!std::isfinite(v)) {
    Fail(std::string(a.keyword()) + ": " + Quote(a[i]) + " is not a finite number");
  }
  return v;
}

long MgfReader::Integer(const Args& a, size_t i) const {
  std::string_view s = a[i];
  if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  long v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) {
    Fail(std::string(a.keyword()) + ": " + Quote(a[i]) + " is not an integer");
  }
  return v;
}

double MgfReader::Fraction(const Args& a, size_t i, const char* what) const {
  const double v = Number(a, i);
  if (v < 0.0 || v > 1.0) {
    Fail(std::string(a.keyword()) + ": " + what + " " + Quote(a[i]) + " must be in [0, 1]");
  }
  return v;
}

double MgfReader::NonNegative(const Args& a, size_t i, const char* what) const {
  const double v = Number(a, i);
  if (v < 0.0) Fail(std::string(a.keyword()) + ": " + what + " must not be negative");
  if (v > kMaxMaterialValue) Fail(std::string(a.keyword()) + ": " + what + " is out of range");
  return v;
}

const Affine& MgfReader::World() const {
  static const Affine kIdentity;
  return xf_stack_.empty() ? kIdentity : xf_stack_.back().world;
}

XformSpec MgfReader::ParseXform(const Args& a, size_t first) const {
  XformSpec spec;
  spec.segments.emplace_back();  // the arguments before the first -a / -i
  auto need = [&](size_t i, size_t n) {
    if (i + n >= a.size()) {
      Fail(std::string(a.keyword()) + ": transform option " + Quote(a[i]) + " needs " + std::to_string(n) +
           " argument" + (n == 1 ? "" : "s"));
    }
  };
  auto apply = [&](const Affine& op) {
    XformSegment& s = spec.segments.back();
    s.step = Compose(op, s.step);
  };
  for (size_t i = first; i < a.size();) {
    const std::string_view opt = a[i];
    if (opt == "-t") {
      need(i, 3);
      Affine t;
      t.t = {Number(a, i + 1), Number(a, i + 2), Number(a, i + 3)};
      apply(t);
      i += 4;
    } else if (opt == "-rx" || opt == "-ry" || opt == "-rz") {
      need(i, 1);
      apply(Rotation(opt[2] - 'x', Number(a, i + 1)));
      i += 2;
    } else if (opt == "-s") {
      need(i, 1);
      const double s = Number(a, i + 1);
      if (s == 0.0) Fail(std::string(a.keyword()) + ": scale factor must not be zero");
      Affine t;
      for (int k = 0; k < 3; ++k) t.m[k][k] = s;
      apply(t);
      i += 2;
    } else if (opt == "-mx" || opt == "-my" || opt == "-mz") {
      Affine t;
      const int k = opt[2] - 'x';
      t.m[k][k] = -1.0;  // -mx mirrors about the Y-Z plane, i.e. negates x
      apply(t);
      i += 1;
    } else if (opt == "-i" || opt == "-a") {
      need(i, 1);
      const long count = Integer(a, i + 1);
      const bool array = opt == "-a";
      if (count < (array ? 1 : 0) || count > kMaxRepeat) {
        Fail(std::string(a.keyword()) + ": " + std::string(opt) + " count " + Quote(a[i + 1]) +
             " must be in [" + (array ? "1" : "0") + ", " + std::to_string(kMaxRepeat) + "]");
      }
      if (array) {
        spec.instances *= static_cast<uint64_t>(count);
        if (spec.instances > kMaxArrayInstances) {
          Fail(std::string(a.keyword()) + ": array of more than " + std::to_string(kMaxArrayInstances) +
               " instances");
        }
      }
      spec.segments.push_back(XformSegment{array, count, Affine{}});
      i += 2;
    } else {
      Fail(std::string(a.keyword()) + ": unknown transform option " + Quote(opt));
    }
  }
  return spec;
}

void MgfReader::PushFrame(XformSpec spec, size_t resume) {
  if (static_cast<int>(xf_stack_.size()) >= options_.max_depth) {
    Fail("transforms nested deeper than " + std::to_string(options_.max_depth));
  }
  XfFrame f;
  f.counters.assign(spec.NumArrays(), 0);
  f.spec = std::move(spec);
  f.parent = World();
  f.resume = resume;
  f.line = line_;
  xf_stack_.push_back(std::move(f));
  UpdateFrameWorld(xf_stack_.back());
}

void MgfReader::UpdateFrameWorld(XfFrame& f) const {
  // Enclosed transforms are prepended to the enclosing ones (§2.2.2): apply this frame first.
  f.world = Compose(f.parent, f.spec.Instance(f.counters));
  if (!f.world.IsFinite()) Fail("transform overflows (huge -s or -t values)");
}

const MgfFile& MgfReader::Include(std::string_view name) {
  // A NUL would cut the name the OS sees short of the one checked below.
  for (const char ch : name) {
    if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) {
      Fail("include path " + Quote(name) + " contains a control character");
    }
  }
  const fs::path rel{std::string(name)};
  if (rel.has_root_name() || rel.has_root_directory()) {
    Fail("include path " + Quote(name) + " is absolute; MGF allows only relative paths (§3 i)");
  }
  const fs::path full = (state_->file->dir / rel).lexically_normal();
  // Checked before the file is looked at, with one answer for existing and missing files
  // (scene_reference.h).
  if (!options_.include_root.empty()) {
    const std::string problem =
        SceneReferenceProblem(options_.include_root, state_->file->dir, name, nullptr);
    if (!problem.empty()) Fail("include " + Quote(name) + " " + problem);
  }
  const std::string canonical = CanonicalKey(full);
  if (std::find(include_stack_.begin(), include_stack_.end(), canonical) != include_stack_.end()) {
    std::string chain;
    for (const std::string& f : include_stack_) chain += fs::path(f).filename().string() + " -> ";
    Fail("include cycle: " + chain + full.filename().string());
  }
  if (static_cast<int>(include_stack_.size()) > options_.max_depth) {
    Fail("includes nested deeper than " + std::to_string(options_.max_depth));
  }
  if (const auto it = files_.find(canonical); it != files_.end()) return *it->second;
  auto file = std::make_unique<MgfFile>();
  if (std::string err = ReadWholeFile(full, &file->text); !err.empty()) {
    Fail("cannot include " + Quote(name) + " (" + full.string() + "): " + err);
  }
  file->name = full.string();
  file->dir = full.parent_path();
  file->canonical = canonical;
  Tokenize(*file);
  const MgfFile& ref = *file;
  files_.emplace(canonical, std::move(file));
  return ref;
}

SceneExpansion MgfReader::PrimitiveExpansion(Kind kind, const Args& a) const {
  const uint64_t n = static_cast<uint64_t>(options_.curve_segments);
  const uint64_t words = a.size();
  SceneExpansion e;
  switch (kind) {
    case Kind::kFace:  // n = words − 1 vertices, n − 2 triangles
      e.triangles = words > 3 ? words - 3 : 0;
      e.vertices = words - 1;
      break;
    case Kind::kFaceHoles:
      e.triangles = 3 * words;
      e.vertices = 3 * words;
      break;
    case Kind::kSphere: {
      const uint64_t bands = static_cast<uint64_t>(geometry::SphereBands(options_.curve_segments));
      e.triangles = 2 * n * bands;
      e.vertices = (bands + 1) * n;
      break;
    }
    case Kind::kCylinder:
    case Kind::kCone:
    case Kind::kRing:
      e.triangles = 2 * n;
      e.vertices = 2 * n + 1;
      break;
    case Kind::kTorus:
      e.triangles = 2 * n * n;
      e.vertices = n * n;
      break;
    case Kind::kPrism:
      e.triangles = 4 * words;
      e.vertices = 6 * words;
      break;
    default:
      break;
  }
  return e;
}

SceneExpansion MgfReader::ExpansionOf(const MgfFile& file) {
  if (const auto it = expansion_of_.find(file.canonical); it != expansion_of_.end()) return it->second;
  FileState st{&file, xf_stack_.size(), object_depth_};
  FileState* const saved_state = state_;
  const int saved_line = line_;
  state_ = &st;
  struct Block {
    SceneExpansion body;  // one execution of the block, its closing `xf` included
    uint64_t instances = 1;
    bool array = false;
    int line = 0;
  };
  std::vector<Block> open;  // `xf` blocks begun and not yet ended
  SceneExpansion top;
  auto current = [&]() -> SceneExpansion& { return open.empty() ? top : open.back().body; };
  auto check = [&](const SceneExpansion& e, int line) {
    if (const std::string over = options_.budget.Exceeded(e); !over.empty()) {
      line_ = line;
      Fail(over);
    }
  };
  // `times` executions of `body` (plus `array_instances` new instances) into the current count.
  auto add = [&](const SceneExpansion& body, uint64_t times, uint64_t array_instances, int line) {
    SceneExpansion& c = current();
    c.AddTimes(body, times);
    c.instances = SceneExpansion::Add(c.instances, array_instances);
    check(c, line);
  };
  for (const Entity& e : file.entities) {
    line_ = e.line;
    const Args a(&file.words[e.first], e.count);
    current().entities = SceneExpansion::Add(current().entities, 1);
    const Kind kind = KindOf(a.keyword());
    if (kind == Kind::kXf && a.size() > 1) {
      const XformSpec spec = ParseXform(a, 1);
      open.push_back(Block{{}, spec.instances, spec.NumArrays() > 0, e.line});
    } else if (kind == Kind::kXf) {
      if (open.empty()) continue;  // an end without a begin: execution reports it
      const Block block = std::move(open.back());
      open.pop_back();
      add(block.body, block.instances, block.array ? block.instances : 0, block.line);
    } else if (kind == Kind::kInclude) {
      if (a.size() < 2) Fail("i: expected a file name");
      const MgfFile& included = Include(a[1]);
      const XformSpec spec = a.size() > 2 ? ParseXform(a, 2) : XformSpec{};
      include_stack_.push_back(included.canonical);
      SceneExpansion one = ExpansionOf(included);
      include_stack_.pop_back();
      line_ = e.line;
      one.entities = SceneExpansion::Add(one.entities, 1);  // ExecuteIncluded counts the include itself
      add(one, spec.instances, spec.NumArrays() > 0 ? spec.instances : 0, e.line);
    } else {
      add(PrimitiveExpansion(kind, a), 1, 0, e.line);
    }
  }
  // A block left open at the end of the file runs once, up to the end (execution then fails).
  while (!open.empty()) {
    const Block block = std::move(open.back());
    open.pop_back();
    add(block.body, block.instances, block.array ? block.instances : 0, block.line);
  }
  state_ = saved_state;
  line_ = saved_line;
  expansion_of_.emplace(file.canonical, top);
  return top;
}

void MgfReader::ExecuteIncluded(const MgfFile& file) {
  CountEntity();  // an include of an empty file, arrayed, must still count as work
  include_stack_.push_back(file.canonical);
  Execute(file);
  include_stack_.pop_back();
}

void MgfReader::CountEntity() {
  if (++executed_ > options_.budget.max_entities) {
    Fail("more than " + std::to_string(options_.budget.max_entities) +
         " entities executed (array repeats and includes included; SceneBudget::max_entities)");
  }
}

void MgfReader::Execute(const MgfFile& file) {
  FileState st{&file, xf_stack_.size(), object_depth_};
  FileState* const saved_state = state_;
  const int saved_line = line_;
  state_ = &st;
  size_t pc = 0;
  while (pc < file.entities.size()) {
    const Entity& e = file.entities[pc++];
    line_ = e.line;
    CountEntity();
    const Args a(&file.words[e.first], e.count);
    Dispatch(a, &pc);
  }
  if (xf_stack_.size() > st.xf_base) {
    line_ = xf_stack_[st.xf_base].line;
    Fail("xf begun here is not ended before the end of the file (§3 xf: must be balanced)");
  }
  if (object_depth_ > st.object_base) {
    line_ = file.last_line;
    Warn(std::to_string(object_depth_ - st.object_base) +
         " object context(s) not ended at the end of the file");
    object_depth_ = st.object_base;
  }
  state_ = saved_state;
  line_ = saved_line;
}

void MgfReader::Dispatch(const Args& a, size_t* pc) {
  const Kind kind = KindOf(a.keyword());
  switch (kind) {
    case Kind::kObject:
      ExpectCount(a, 0, 1, "at most one object name");
      if (a.size() == 2) {
        ++object_depth_;
      } else if (object_depth_ <= state_->object_base) {
        Fail("'o' ends an object that was not begun in this file");
      } else {
        --object_depth_;
      }
      return;
    case Kind::kXf:
      if (a.size() == 1) {
        if (xf_stack_.size() <= state_->xf_base) {
          Fail("'xf' end without a matching begin in this file");
        }
        XfFrame& f = xf_stack_.back();
        if (AdvanceCounters(f.spec, f.counters)) {
          UpdateFrameWorld(f);
          *pc = f.resume;  // next array instance: run the block again (§2.2.3)
        } else {
          xf_stack_.pop_back();
        }
      } else {
        PushFrame(ParseXform(a, 1), *pc);
      }
      return;
    case Kind::kInclude: {
      if (a.size() < 2) Fail("i: expected a file name");
      const MgfFile& file = Include(a[1]);
      if (a.size() == 2) {
        ExecuteIncluded(file);
        return;
      }
      // "as though the include statement were enclosed by xf entities" (§3 i), arrays too.
      PushFrame(ParseXform(a, 2), 0);
      const size_t depth = xf_stack_.size();
      while (true) {
        ExecuteIncluded(file);
        XfFrame& f = xf_stack_[depth - 1];  // re-fetched: the stack may have reallocated
        if (!AdvanceCounters(f.spec, f.counters)) break;
        UpdateFrameWorld(f);
      }
      xf_stack_.pop_back();
      return;
    }
    case Kind::kIes:
      WarnOnce("ies", "ies luminaires are not supported; entity ignored");
      return;
    case Kind::kColor:
    case Kind::kCxy:
    case Kind::kCspec:
    case Kind::kCct:
    case Kind::kCmix:
    case Kind::kMaterial:
    case Kind::kSides:
    case Kind::kRd:
    case Kind::kTd:
    case Kind::kEd:
    case Kind::kRs:
    case Kind::kTs:
    case Kind::kIr:
    case Kind::kVertex:
    case Kind::kPoint:
    case Kind::kNormal:
      ContextEntity(kind, a);
      return;
    case Kind::kFace:
    case Kind::kFaceHoles:
    case Kind::kSphere:
    case Kind::kCylinder:
    case Kind::kCone:
    case Kind::kPrism:
    case Kind::kRing:
    case Kind::kTorus:
      EmitGeometry(kind, a);
      return;
    case Kind::kUnknown:
      WarnOnce(a.keyword(), "unknown entity " + Quote(a.keyword()) + " ignored");
      return;
  }
}

void MgfReader::WarnOnce(std::string_view kind, const std::string& message) {
  std::string key = state_->file->canonical;
  key += '\0';
  key += kind;
  if (warned_once_.insert(std::move(key)).second) Warn(message);
}

void MgfReader::Finish() {
  StoreInSceneFrame(world_positions_, &scene_);
  std::vector<Vec3d>().swap(world_positions_);
  if (!any_normal_) std::vector<Vec3>().swap(scene_.normals);
  if (suppressed_warnings_ > 0) {
    scene_.warnings.push_back(scene_.source + ": " + std::to_string(suppressed_warnings_) +
                              " more warnings not shown");
    spdlog::warn("{}", scene_.warnings.back());
  }
}

}  // namespace pf::mgf

namespace pf {
namespace {

namespace fs = std::filesystem;
using mgf::CanonicalKey;
using mgf::MgfFile;
using mgf::MgfReader;
using mgf::ReadWholeFile;

void CheckOptions(const MgfOptions& o, const std::string& name) {
  if (o.curve_segments < mgf::kMinCurveSegments || o.curve_segments > mgf::kMaxCurveSegments) {
    throw InputError(SourceLocation{name, 0},
                     "MgfOptions::curve_segments = " + std::to_string(o.curve_segments) + " is not in [" +
                         std::to_string(mgf::kMinCurveSegments) + ", " +
                         std::to_string(mgf::kMaxCurveSegments) + "]");
  }
  if (o.max_depth < 1) throw InputError(SourceLocation{name, 0}, "MgfOptions::max_depth < 1");
}

SceneDescription Load(std::unique_ptr<MgfFile> file, const MgfOptions& options) {
  CheckOptions(options, file->name);
  mgf::Tokenize(*file);
  SceneDescription scene;
  scene.source = file->name;
  MgfReader reader(options, &scene);
  try {
    reader.Run(std::move(file));
  } catch (...) {
    reader.ReportCounts();
    throw;
  }
  reader.ReportCounts();
  return scene;
}

}  // namespace

SceneDescription LoadMgf(const std::filesystem::path& file, const MgfOptions& options) {
  auto f = std::make_unique<MgfFile>();
  f->name = file.string();
  if (std::string err = ReadWholeFile(file, &f->text); !err.empty()) {
    throw InputError(SourceLocation{f->name, 0}, "cannot load MGF file: " + err);
  }
  f->dir = file.parent_path();
  f->canonical = CanonicalKey(file);
  return Load(std::move(f), options);
}

SceneDescription LoadMgfFromString(std::string_view text, const std::string& virtual_name,
                                   const MgfOptions& options) {
  auto f = std::make_unique<MgfFile>();
  f->name = virtual_name;
  f->text = std::string(text);
  const fs::path p(virtual_name);
  f->dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  f->canonical = CanonicalKey(p);
  return Load(std::move(f), options);
}

}  // namespace pf

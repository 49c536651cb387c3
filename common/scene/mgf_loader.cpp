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
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <numbers>
#include <set>
#include <span>
#include <string>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/core/error.h"
#include "common/core/math.h"
#include "common/scene/curved_primitives.h"
#include "common/scene/mgf_color.h"
#include "common/scene/mgf_tokenizer.h"
#include "common/scene/mgf_transform.h"
#include "common/scene/polygon_triangulation.h"
#include "common/scene/scene_frame.h"
#include "common/scene/scene_reference.h"

namespace pf {
namespace {

namespace fs = std::filesystem;

constexpr double kPiD = std::numbers::pi;
constexpr uint32_t kNone = 0xffffffffu;
// Beyond this magnitude (after transformation) coordinates are rejected: products of two such
// numbers stay far from overflow in double, and the value still fits a float.
constexpr double kMaxCoordinate = 1e18;
constexpr long kMaxRepeat = 1'000'000;                  // largest N of `-i N` / `-a N`
constexpr uint64_t kMaxArrayInstances = 1'000'000'000;  // product of the -a counts of one xf
constexpr size_t kMaxStoredWarnings = 500;              // then only counted, to keep logs readable
constexpr int kMinCurveSegments = 3;
// The spec limits an entity to 4096 characters, i.e. about 2000 vertices per face; far larger
// polygons are refused rather than ear-clipped in quadratic time.
constexpr size_t kMaxPolygonVertices = 16384;
// Material values beyond this are not physical and would overflow the float Material.
constexpr double kMaxMaterialValue = 1e30;
constexpr int kMaxCurveSegments = 1024;

// The pieces the interpreter is built from: colour (mgf_color.h), transforms
// (mgf_transform.h), files and entities (mgf_tokenizer.h), polygon triangulation
// (polygon_triangulation.h) and curved-primitive tessellation (curved_primitives.h).
using geometry::BridgeHoles;
using geometry::ContourVertex;
using geometry::SafeNormalize;
using geometry::TriangulatePolygon;
using geometry::UnitCircle;
using mgf::AdvanceCounters;
using mgf::Affine;
using mgf::CanonicalKey;
using mgf::Chroma;
using mgf::ChromaRgb;
using mgf::Compose;
using mgf::Entity;
using mgf::kMinChromaY;
using mgf::MgfFile;
using mgf::Quote;
using mgf::ReadWholeFile;
using mgf::Rotation;
using mgf::Tokenize;
using mgf::XformSegment;
using mgf::XformSpec;
using mgf::XyzToChroma;

// ----------------------------------------------------------------------------------------------
// The interpreter.

struct StringHash {
  using is_transparent = void;
  size_t operator()(std::string_view s) const { return std::hash<std::string_view>{}(s); }
};
template <typename T>
using NameMap = std::unordered_map<std::string, T, StringHash, std::equal_to<>>;

struct VertexCtx {
  Vec3d p;  // the unnamed vertex is the origin without normal (§3 v)
  Vec3d n;  // unit normal, or zero for "none"
};

struct MaterialCtx {
  std::string name;
  int sides = 2;  // the unnamed material is a two-sided black absorber (§3 m)
  double rd = 0, td = 0, ed = 0, rs = 0, rs_alpha = 0, ts = 0, ts_alpha = 0;
  double ir_n = 1, ir_k = 0;
  Chroma rd_c, td_c, ed_c, rs_c, ts_c;  // the colour in effect when each value was set (§2.1)
  uint32_t cached = kNone;              // index in SceneDescription::materials, kNone if stale
};

// The named contexts of one kind (§2.1): the unnamed one, the named ones, and which is current.
template <typename T>
struct ContextTable {
  T unnamed{};
  NameMap<T> named;
  T* current = &unnamed;
};

class Args {
 public:
  Args(const std::string_view* words, size_t count) : words_(words), count_(count) {}
  size_t size() const { return count_; }
  std::string_view operator[](size_t i) const { return words_[i]; }
  std::string_view keyword() const { return words_[0]; }

 private:
  const std::string_view* words_;
  size_t count_;
};

enum class Kind {
  kUnknown,
  kObject,
  kXf,
  kInclude,
  kIes,
  kColor,
  kCxy,
  kCspec,
  kCct,
  kCmix,
  kMaterial,
  kSides,
  kRd,
  kTd,
  kEd,
  kRs,
  kTs,
  kIr,
  kVertex,
  kPoint,
  kNormal,
  kFace,
  kFaceHoles,
  kSphere,
  kCylinder,
  kCone,
  kPrism,
  kRing,
  kTorus,
};

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

// A pushed transform context (§3 xf): its specification, the current array instance, and the
// total transform in effect inside it.
struct XfFrame {
  XformSpec spec;
  std::vector<long> counters;  // one per -a segment
  Affine parent;               // world transform of the enclosing context
  Affine world;                // this instance's transform, then the enclosing ones
  size_t resume = 0;           // entity to jump back to for the next array instance
  int line = 0;                // where it was begun, for messages
};

// A world-space vertex of a polygon with its (optional) normal.
struct PolyVertex {
  Vec3d p;
  Vec3d n;
};

class MgfReader final : private geometry::MeshSink {
 public:
  MgfReader(const MgfOptions& options, SceneDescription* scene)
      : options_(options), scene_(*scene), circle_(options.curve_segments) {}

  void Run(std::unique_ptr<MgfFile> top) {
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

  void ReportCounts() const {
    if (!options_.counts) return;
    options_.counts->executed_entities = executed_;
    options_.counts->emitted_triangles = scene_.triangles.size();
  }

 private:
  struct FileState {
    const MgfFile* file;
    size_t xf_base;
    int object_base;
  };

  // ---- messages ------------------------------------------------------------------------------
  SourceLocation Here() const { return SourceLocation{state_ ? state_->file->name : std::string(), line_}; }
  [[noreturn]] void Fail(const std::string& reason) const { throw InputError(Here(), reason); }
  void Warn(const std::string& message) {
    if (scene_.warnings.size() >= kMaxStoredWarnings) {
      ++suppressed_warnings_;
      return;
    }
    std::string text = Here().ToString() + ": " + message;
    spdlog::warn("{}", text);
    scene_.warnings.push_back(std::move(text));
  }

  // ---- arguments -----------------------------------------------------------------------------
  void ExpectCount(const Args& a, size_t lo, size_t hi, const char* usage) const {
    const size_t n = a.size() - 1;
    if (n < lo || n > hi) {
      Fail(std::string(a.keyword()) + ": expected " + usage + ", got " + std::to_string(n) + " argument" +
           (n == 1 ? "" : "s"));
    }
  }
  double Number(const Args& a, size_t i) const {
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
  long Integer(const Args& a, size_t i) const {
    std::string_view s = a[i];
    if (s.size() > 1 && s[0] == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
    long v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || end != s.data() + s.size()) {
      Fail(std::string(a.keyword()) + ": " + Quote(a[i]) + " is not an integer");
    }
    return v;
  }
  double Fraction(const Args& a, size_t i, const char* what) const {
    const double v = Number(a, i);
    if (v < 0.0 || v > 1.0) {
      Fail(std::string(a.keyword()) + ": " + what + " " + Quote(a[i]) + " must be in [0, 1]");
    }
    return v;
  }
  double NonNegative(const Args& a, size_t i, const char* what) const {
    const double v = Number(a, i);
    if (v < 0.0) Fail(std::string(a.keyword()) + ": " + what + " must not be negative");
    if (v > kMaxMaterialValue) Fail(std::string(a.keyword()) + ": " + what + " is out of range");
    return v;
  }

  // ---- contexts ------------------------------------------------------------------------------
  // The four forms of c/m/v (§2.1): "x", "x id", "x id =", "x id = template". Returns the
  // name of a newly defined context (empty otherwise) through *defined.
  template <typename T>
  void SelectContext(ContextTable<T>& table, const Args& a, const char* what, bool* defined) {
    *defined = false;
    if (a.size() == 1) {
      table.unnamed = T{};  // re-establishing the unnamed context restores its defaults
      table.current = &table.unnamed;
      return;
    }
    if (a.size() == 2) {
      const auto it = table.named.find(a[1]);
      if (it == table.named.end()) Fail(std::string("undefined ") + what + " " + Quote(a[1]));
      table.current = &it->second;
      return;
    }
    if ((a.size() == 3 || a.size() == 4) && a[2] == "=") {
      T value{};
      if (a.size() == 4) {
        const auto it = table.named.find(a[3]);
        if (it == table.named.end()) Fail(std::string("undefined ") + what + " " + Quote(a[3]));
        value = it->second;  // by-value copy: later changes to the template do not propagate
      }
      auto [it, inserted] = table.named.try_emplace(std::string(a[1]));
      it->second = std::move(value);
      table.current = &it->second;
      *defined = true;
      return;
    }
    Fail(std::string(a.keyword()) + ": expected [id [= [template]]]");
  }

  const VertexCtx& NamedVertex(std::string_view name) const {
    const auto it = vertices_.named.find(name);
    if (it == vertices_.named.end()) Fail("undefined vertex " + Quote(name));
    return it->second;
  }
  MaterialCtx& Mat() {
    MaterialCtx& m = *materials_.current;
    m.cached = kNone;  // about to be modified
    return m;
  }
  const Chroma& CurrentColor() const { return *colors_.current; }

  // ---- transforms ----------------------------------------------------------------------------
  const Affine& World() const {
    static const Affine kIdentity;
    return xf_stack_.empty() ? kIdentity : xf_stack_.back().world;
  }

  XformSpec ParseXform(const Args& a, size_t first) const {
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

  void PushFrame(XformSpec spec, size_t resume) {
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
  void UpdateFrameWorld(XfFrame& f) const {
    // Enclosed transforms are prepended to the enclosing ones (§2.2.2): apply this frame first.
    f.world = Compose(f.parent, f.spec.Instance(f.counters));
    if (!f.world.IsFinite()) Fail("transform overflows (huge -s or -t values)");
  }

  // ---- files ---------------------------------------------------------------------------------
  const MgfFile& Include(std::string_view name) {
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

  // ---- expansion (scene_budget.h) --------------------------------------------------------------
  // Triangles and vertices one geometric entity emits at most (the tessellation rule of
  // mgf_loader.h; curved_primitives.h gives the exact counts, polygons are bounded by their
  // vertex lists: `fh` bridges each hole with two extra vertices).
  SceneExpansion PrimitiveExpansion(Kind kind, const Args& a) const {
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

  // What executing `file` once expands to, computed from its entities and the nesting
  // multipliers of its arrays and includes without executing anything, and checked against the
  // budgets as it accumulates: the error names the line where the file's expansion crosses a
  // budget (an array's `xf` or `i` line, where its block is multiplied). A file expands the same
  // wherever it is included, so the result is kept per file. Errors that only execution can
  // find (unbalanced `xf`, undefined names) are left to it.
  SceneExpansion ExpansionOf(const MgfFile& file) {
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

  void ExecuteIncluded(const MgfFile& file) {
    CountEntity();  // an include of an empty file, arrayed, must still count as work
    include_stack_.push_back(file.canonical);
    Execute(file);
    include_stack_.pop_back();
  }

  // Cannot fire after ExpansionOf accepted the file (it counts the same way); kept so that the
  // budget holds even if the two ever disagree.
  void CountEntity() {
    if (++executed_ > options_.budget.max_entities) {
      Fail("more than " + std::to_string(options_.budget.max_entities) +
           " entities executed (array repeats and includes included; SceneBudget::max_entities)");
    }
  }

  void Execute(const MgfFile& file) {
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

  void Dispatch(const Args& a, size_t* pc) {
    switch (KindOf(a.keyword())) {
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
      case Kind::kColor: {
        bool defined;
        SelectContext(colors_, a, "colour", &defined);
        return;
      }
      case Kind::kCxy: {
        ExpectCount(a, 2, 2, "2 arguments (x y)");
        const double x = Number(a, 1), y = Number(a, 2);
        // §3 cxy wants x, y > 0 and x + y < 1; like mgflib we reject only negative values and
        // x + y > 1 (the hospital scene has "cxy 0 .38" and "cxy .4 0").
        if (x < 0.0 || y < 0.0 || x + y > 1.0) {
          Fail("cxy: chromaticity (" + std::string(a[1]) + ", " + std::string(a[2]) +
               ") is outside the CIE diagram (need x >= 0, y >= 0, x + y <= 1)");
        }
        if (y < kMinChromaY) {
          // (Almost) no luminance: the colour of a luminance-normalised value would be infinite.
          Warn("cxy: y = " + std::string(a[2]) + " is a colour without luminance; neutral grey used instead");
          *colors_.current = Chroma{};
          return;
        }
        *colors_.current = Chroma{x, y};
        return;
      }
      case Kind::kCspec: {
        if (a.size() < 5) Fail("cspec: expected l_min l_max and at least 2 values");
        const double lmin = Number(a, 1), lmax = Number(a, 2);
        if (!(lmin < lmax)) Fail("cspec: l_min must be less than l_max");
        std::vector<double> v;
        v.reserve(a.size() - 3);
        for (size_t i = 3; i < a.size(); ++i) v.push_back(Number(a, i));
        double x, y;
        if (!mgf::SpectrumToXy(lmin, lmax, v.data(), v.size(), &x, &y)) {
          Fail("cspec: the spectrum has no positive luminance in 380-780 nm");
        }
        *colors_.current = Chroma{x, y};
        return;
      }
      case Kind::kCct: {
        ExpectCount(a, 1, 1, "1 argument (temperature in K)");
        const double t = Number(a, 1);
        if (!(t > 0.0)) Fail("cct: temperature must be positive");
        Chroma c;
        if (!mgf::BlackbodyToChroma(t, &c))
          Fail("cct: temperature " + Quote(a[1]) + " gives no visible light");
        *colors_.current = c;
        return;
      }
      case Kind::kCmix: {
        if (a.size() < 3 || (a.size() - 1) % 2 != 0) {
          Fail("cmix: expected pairs of weight and colour name");
        }
        // Weights are relative luminances (§3 cmix); summing per-unit-luminance XYZ is exactly
        // the spectral mix for spectral colours and needs no spectrum for (x,y) colours.
        Vec3d xyz;
        for (size_t i = 1; i + 1 < a.size(); i += 2) {
          const double w = Number(a, i);
          const auto it = colors_.named.find(a[i + 1]);
          if (it == colors_.named.end()) Fail("undefined colour " + Quote(a[i + 1]));
          xyz += it->second.XyzPerLuminance() * w;
        }
        Chroma c;
        if (!XyzToChroma(xyz, &c)) Fail("cmix: the mixture has no positive luminance");
        *colors_.current = c;
        return;
      }
      case Kind::kMaterial: {
        bool defined;
        SelectContext(materials_, a, "material", &defined);
        if (defined) materials_.current->name = std::string(a[1]);
        if (defined || a.size() == 1) materials_.current->cached = kNone;
        return;
      }
      case Kind::kSides: {
        ExpectCount(a, 1, 1, "1 argument (1 or 2)");
        const long s = Integer(a, 1);
        if (s != 1 && s != 2) Fail("sides: must be 1 or 2");
        Mat().sides = static_cast<int>(s);
        return;
      }
      case Kind::kRd:
        ExpectCount(a, 1, 1, "1 argument (rho_d)");
        Mat().rd = Fraction(a, 1, "reflectance");
        Mat().rd_c = CurrentColor();
        return;
      case Kind::kTd:
        ExpectCount(a, 1, 1, "1 argument (tau_d)");
        Mat().td = Fraction(a, 1, "transmittance");
        Mat().td_c = CurrentColor();
        return;
      case Kind::kEd:
        ExpectCount(a, 1, 1, "1 argument (epsilon_d in lm/m^2)");
        Mat().ed = NonNegative(a, 1, "emittance");
        Mat().ed_c = CurrentColor();
        return;
      case Kind::kRs:
        ExpectCount(a, 2, 2, "2 arguments (rho_s alpha_r)");
        Mat().rs = Fraction(a, 1, "reflectance");
        Mat().rs_alpha = NonNegative(a, 2, "roughness");
        Mat().rs_c = CurrentColor();
        return;
      case Kind::kTs:
        ExpectCount(a, 2, 2, "2 arguments (tau_s alpha_t)");
        Mat().ts = Fraction(a, 1, "transmittance");
        Mat().ts_alpha = NonNegative(a, 2, "roughness");
        Mat().ts_c = CurrentColor();
        return;
      case Kind::kIr: {
        ExpectCount(a, 2, 2, "2 arguments (n_real n_imag)");
        const double n = Number(a, 1), k = Number(a, 2);
        if (!(n > 0.0)) Fail("ir: the real index of refraction must be positive");
        if (n > kMaxMaterialValue) Fail("ir: the index of refraction is out of range");
        if (k != 0.0) {
          Warn("ir: imaginary part " + std::string(a[2]) + " ignored (metals are rendered as dielectrics)");
        }
        Mat().ir_n = n;
        Mat().ir_k = k;
        return;
      }
      case Kind::kVertex: {
        bool defined;
        SelectContext(vertices_, a, "vertex", &defined);
        return;
      }
      case Kind::kPoint:
        ExpectCount(a, 3, 3, "3 arguments (x y z)");
        vertices_.current->p = {Number(a, 1), Number(a, 2), Number(a, 3)};
        return;
      case Kind::kNormal:
        ExpectCount(a, 3, 3, "3 arguments (dx dy dz)");
        // §3 n: normalised; a zero vector means "no normal".
        vertices_.current->n = SafeNormalize({Number(a, 1), Number(a, 2), Number(a, 3)});
        return;
      case Kind::kFace:
        Face(a);
        return;
      case Kind::kFaceHoles:
        FaceWithHoles(a);
        return;
      case Kind::kSphere:
        Sphere(a);
        return;
      case Kind::kCylinder:
        ExpectCount(a, 3, 3, "3 arguments (v1 radius v2)");
        {
          const double r = Number(a, 2);
          if (r == 0.0) Fail("cyl: radius must not be zero");
          Cone(a, a[1], r, a[3], r);
        }
        return;
      case Kind::kCone: {
        ExpectCount(a, 4, 4, "4 arguments (v1 rad1 v2 rad2)");
        const double r1 = Number(a, 2), r2 = Number(a, 4);
        if (r1 == 0.0 && r2 == 0.0) Fail("cone: both radii are zero");
        if ((r1 > 0.0 && r2 < 0.0) || (r1 < 0.0 && r2 > 0.0)) {
          Fail("cone: the radii must not have opposite signs");
        }
        Cone(a, a[1], r1, a[3], r2);
        return;
      }
      case Kind::kPrism:
        Prism(a);
        return;
      case Kind::kRing:
        Ring(a);
        return;
      case Kind::kTorus:
        Torus(a);
        return;
      case Kind::kUnknown:
        WarnOnce(a.keyword(), "unknown entity " + Quote(a.keyword()) + " ignored");
        return;
    }
  }

  void WarnOnce(std::string_view kind, const std::string& message) {
    std::string key = state_->file->canonical;
    key += '\0';
    key += kind;
    if (warned_once_.insert(std::move(key)).second) Warn(message);
  }

  // ---- emission ------------------------------------------------------------------------------
  uint32_t MaterialIndex() {
    MaterialCtx& m = *materials_.current;
    if (m.cached != kNone) return m.cached;
    Material out;
    out.name = m.name;
    out.diffuse_reflectance = ChromaRgb(m.rd_c) * static_cast<float>(m.rd);
    out.specular_reflectance = ChromaRgb(m.rs_c) * static_cast<float>(m.rs);
    out.specular_roughness = static_cast<float>(m.rs_alpha);
    out.diffuse_transmittance = ChromaRgb(m.td_c) * static_cast<float>(m.td);
    out.specular_transmittance = ChromaRgb(m.ts_c) * static_cast<float>(m.ts);
    out.transmission_roughness = static_cast<float>(m.ts_alpha);
    out.ior = static_cast<float>(m.ir_n);
    out.one_sided = m.sides == 1;
    // Luminous emittance (lm/m²) of a Lambertian emitter -> radiance in W/(m²·sr): divide by π
    // and by the luminous efficacy of white light; the colour has luminance Y = 1.
    out.emission = ChromaRgb(m.ed_c) * static_cast<float>(m.ed / (kPiD * mgf::kLuminousEfficacy));
    // Energy conservation (§3 m: "the sum ... must not be greater than one").
    // Saturated colours can push a channel above 1 even when the photometric values obey it.
    const Rgb sum = out.diffuse_reflectance + out.specular_reflectance + out.diffuse_transmittance +
                    out.specular_transmittance;
    const float max_sum = sum.Max();
    if (max_sum > 1.0f) {
      const float s = 1.0f / max_sum;
      out.diffuse_reflectance *= s;
      out.specular_reflectance *= s;
      out.diffuse_transmittance *= s;
      out.specular_transmittance *= s;
    }
    std::string key = out.name;
    key += '\0';
    auto put = [&key](const auto& v) { key.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
    for (const Rgb* c : {&out.diffuse_reflectance, &out.specular_reflectance, &out.diffuse_transmittance,
                         &out.specular_transmittance, &out.emission}) {
      put(c->r);
      put(c->g);
      put(c->b);
    }
    put(out.specular_roughness);
    put(out.transmission_roughness);
    put(out.ior);
    put(out.one_sided);
    auto [it, inserted] =
        material_index_.try_emplace(std::move(key), static_cast<uint32_t>(scene_.materials.size()));
    if (inserted) {
      if (max_sum > 1.0001f) {  // rounding of "rd 1" with a near-white colour is not worth a word
        Warn("material " + Quote(m.name.empty() ? std::string_view("(unnamed)") : m.name) +
             ": rd+rs+td+ts reaches " + std::to_string(max_sum) + " in a colour channel; scaled down to 1");
      }
      scene_.materials.push_back(std::move(out));
    }
    m.cached = it->second;
    return m.cached;
  }

  // Starts a source primitive: its material, and a light id assigned at its first triangle.
  void BeginPrimitive(size_t expected_triangles) {
    if (scene_.triangles.size() + expected_triangles > options_.budget.max_triangles) {
      Fail("more than " + std::to_string(options_.budget.max_triangles) +
           " triangles (SceneBudget::max_triangles)");
    }
    prim_material_ = MaterialIndex();
    prim_emissive_ = scene_.materials[prim_material_].IsEmissive();
    prim_light_ = kNoLight;
  }

  uint32_t AddVertex(const Vec3d& p, const Vec3d& n) override {
    for (int k = 0; k < 3; ++k) {
      if (!(std::abs(p[k]) <= kMaxCoordinate)) {
        Fail("coordinates out of range after transformation (|x| > 1e18)");
      }
    }
    if (world_positions_.size() >= std::min<uint64_t>(options_.budget.max_vertices, 0xfffffff0u)) {
      Fail("more than " + std::to_string(options_.budget.max_vertices) +
           " vertices (SceneBudget::max_vertices)");
    }
    world_positions_.push_back(p);  // in double until the scene's frame is known (Finish)
    scene_.normals.push_back(Vec3(n));
    any_normal_ = any_normal_ || !(n == Vec3d{});
    return static_cast<uint32_t>(world_positions_.size() - 1);
  }

  void AddTriangle(uint32_t a, uint32_t b, uint32_t c) override {
    if (scene_.triangles.size() >= options_.budget.max_triangles) {
      Fail("more than " + std::to_string(options_.budget.max_triangles) +
           " triangles (SceneBudget::max_triangles)");
    }
    if (prim_emissive_ && prim_light_ == kNoLight) prim_light_ = scene_.num_lights++;
    scene_.triangles.push_back({a, b, c});
    scene_.triangle_material.push_back(prim_material_);
    scene_.triangle_light.push_back(prim_emissive_ ? prim_light_ : kNoLight);
  }

  // Emits a polygon given in world space, in its final orientation. Returns false if degenerate.
  bool EmitPolygon(std::span<const PolyVertex> poly, bool use_normals, std::string_view what) {
    poly_points_.resize(poly.size());
    for (size_t i = 0; i < poly.size(); ++i) poly_points_[i] = poly[i].p;
    bool approximate = false;
    if (!TriangulatePolygon(poly_points_, &poly_tris_, &approximate)) return false;
    if (approximate) {
      Warn(std::string(what) + ": self-intersecting polygon, triangulated approximately");
    }
    remap_.assign(poly.size(), kNone);
    auto vertex = [&](uint32_t i) {
      if (remap_[i] == kNone) remap_[i] = AddVertex(poly[i].p, use_normals ? poly[i].n : Vec3d{});
      return remap_[i];
    };
    for (const auto& t : poly_tris_) {
      const uint32_t a = vertex(t[0]), b = vertex(t[1]), c = vertex(t[2]);
      AddTriangle(a, b, c);
    }
    return true;
  }

  // World-space vertices of a list of vertex names; `all_normals` tells whether every vertex
  // has a normal. Mirroring transforms reverse the order (see mgf_loader.h).
  void WorldPolygon(const Args& a, size_t first, size_t end, std::vector<PolyVertex>* out,
                    bool* all_normals) const {
    if (end - first > kMaxPolygonVertices) {
      Fail(std::string(a.keyword()) + ": more than " + std::to_string(kMaxPolygonVertices) +
           " vertices in one polygon");
    }
    const Affine& xf = World();
    out->clear();
    *all_normals = true;
    for (size_t i = first; i < end; ++i) {
      const VertexCtx& v = NamedVertex(a[i]);
      const bool has_n = !(v.n == Vec3d{});
      *all_normals = *all_normals && has_n;
      out->push_back({xf.Point(v.p), has_n ? SafeNormalize(xf.Vector(v.n)) : Vec3d{}});
    }
    if (xf.Mirrors()) std::reverse(out->begin(), out->end());
  }

  void Face(const Args& a) {
    if (a.size() < 4) Fail("f: expected at least 3 vertex names, got " + std::to_string(a.size() - 1));
    bool all_normals;
    WorldPolygon(a, 1, a.size(), &poly_, &all_normals);
    BeginPrimitive(a.size());
    if (!EmitPolygon(poly_, all_normals, "f")) Warn("f: degenerate face (no area) skipped");
  }

  // §3 fh: "p1 p2 ... - h1.1 h1.2 ... - h2.1 ...". Holes are bridged into the outer contour,
  // turning the face into the seamed polygon of §3 f, which the ear clipper handles.
  void FaceWithHoles(const Args& a) {
    std::vector<std::pair<size_t, size_t>> contours;  // [first, end) word ranges
    size_t start = 1;
    for (size_t i = 1; i <= a.size(); ++i) {
      if (i == a.size() || a[i] == "-") {
        if (i - start < 3) Fail("fh: every contour needs at least 3 vertices");
        contours.emplace_back(start, i);
        start = i + 1;
      }
    }
    std::vector<std::vector<PolyVertex>> rings(contours.size());
    bool all_normals = true;
    for (size_t k = 0; k < contours.size(); ++k) {
      bool n;
      WorldPolygon(a, contours[k].first, contours[k].second, &rings[k], &n);
      all_normals = all_normals && n;
    }
    BeginPrimitive(a.size() * 3);
    std::vector<std::vector<Vec3d>> contour_points(rings.size());
    for (size_t k = 0; k < rings.size(); ++k) {
      for (const PolyVertex& v : rings[k]) contour_points[k].push_back(v.p);
    }
    std::vector<ContourVertex> bridged;
    size_t ignored_holes = 0;
    if (!BridgeHoles(contour_points, &bridged, &ignored_holes)) {
      Warn("fh: degenerate outer contour (no area) skipped");
      return;
    }
    for (size_t k = 0; k < ignored_holes; ++k) {
      Warn("fh: a hole lies outside the outer contour; hole ignored");
    }
    std::vector<PolyVertex> merged;
    merged.reserve(bridged.size());
    for (const ContourVertex& v : bridged) merged.push_back(rings[v.contour][v.index]);
    if (!EmitPolygon(merged, all_normals, "fh")) Warn("fh: degenerate face (no area) skipped");
  }

  // World-space points and radii beyond kMaxCoordinate are errors; radii that vanish under a
  // tiny scale make the primitive degenerate (a warning).
  Vec3d CheckedPoint(const Vec3d& p) const {
    for (int k = 0; k < 3; ++k) {
      if (!(std::abs(p[k]) <= kMaxCoordinate)) {
        Fail("coordinates out of range after transformation (|x| > 1e18)");
      }
    }
    return p;
  }
  bool UsableRadius(double r) const {
    if (!(r <= kMaxCoordinate)) Fail("radius out of range after transformation (> 1e18)");
    return r > 1e-300;
  }

  void Sphere(const Args& a) {
    ExpectCount(a, 2, 2, "2 arguments (vc radius)");
    const VertexCtx& vc = NamedVertex(a[1]);
    const double r = Number(a, 2);
    if (r == 0.0) Fail("sph: radius must not be zero");
    const Affine& xf = World();
    const Vec3d c = CheckedPoint(xf.Point(vc.p));
    const double scale = xf.Scale();
    const double rw = std::abs(r) * scale;
    const double sign = r > 0.0 ? 1.0 : -1.0;  // negative radius: inward normals (§3 sph)
    const int n = options_.curve_segments;
    const int bands = geometry::SphereBands(n);
    BeginPrimitive(static_cast<size_t>(2) * n * bands);
    if (!UsableRadius(rw)) {
      Warn("sph: radius vanishes after transformation; skipped");
      return;
    }
    geometry::TessellateSphere(c, rw, sign, circle_, *this);
  }

  // cyl and cone (§3 cyl, cone): open-ended truncated cone from v1 (radius r1) to v2 (r2).
  void Cone(const Args& a, std::string_view n1, double r1, std::string_view n2, double r2) {
    const VertexCtx& v1 = NamedVertex(n1);
    const VertexCtx& v2 = NamedVertex(n2);
    if (v1.p == v2.p) {
      Fail(std::string(a.keyword()) + ": the end points coincide" +
           (a.keyword() == "cone" ? " (use ring)" : ""));
    }
    const Affine& xf = World();
    const Vec3d p1 = CheckedPoint(xf.Point(v1.p)), p2 = CheckedPoint(xf.Point(v2.p));
    const double scale = xf.Scale();
    const double sign = (r1 < 0.0 || r2 < 0.0) ? -1.0 : 1.0;  // negative radii face inwards
    const double ra = std::abs(r1) * scale, rb = std::abs(r2) * scale;
    const int n = options_.curve_segments;
    BeginPrimitive(static_cast<size_t>(2) * n);
    const Vec3d axis = p2 - p1;
    const double h = Length(axis);
    if (!UsableRadius(std::max(ra, rb)) || !(h > 0.0)) {
      Warn(std::string(a.keyword()) + ": degenerate after transformation; skipped");
      return;
    }
    geometry::TessellateCone(p1, ra, p2, rb, sign, circle_, *this);
  }

  // The centre vertex of ring and torus must have a normal (§3 ring, torus).
  const VertexCtx& OrientedCentre(const Args& a) const {
    const VertexCtx& vc = NamedVertex(a[1]);
    if (vc.n == Vec3d{}) {
      Fail(std::string(a.keyword()) + ": centre vertex " + Quote(a[1]) + " has no normal");
    }
    return vc;
  }

  void Ring(const Args& a) {
    ExpectCount(a, 3, 3, "3 arguments (vc rmin rmax)");
    const VertexCtx& vc = OrientedCentre(a);
    const double rmin = Number(a, 2), rmax = Number(a, 3);
    if (rmin < 0.0) Fail("ring: inner radius must not be negative");
    if (!(rmax > rmin)) Fail("ring: outer radius must be greater than the inner radius");
    const Affine& xf = World();
    const Vec3d c = CheckedPoint(xf.Point(vc.p));
    const Vec3d nz = SafeNormalize(xf.Vector(vc.n));
    const double scale = xf.Scale();
    const double ri = rmin * scale, ro = rmax * scale;
    const int n = options_.curve_segments;
    BeginPrimitive(static_cast<size_t>(2) * n);
    if (nz == Vec3d{} || !UsableRadius(ro)) {
      Warn("ring: degenerate after transformation; skipped");
      return;
    }
    geometry::TessellateRing(c, nz, ri, ro, circle_, *this);
  }

  // §3 torus: tube of radius (rmax − rmin)/2 swept around a circle of radius (rmax + rmin)/2
  // (mgflib's reading of "inner and outer radii").
  void Torus(const Args& a) {
    ExpectCount(a, 3, 3, "3 arguments (vc rmin rmax)");
    const VertexCtx& vc = OrientedCentre(a);
    const double rmin = Number(a, 2), rmax = Number(a, 3);
    if (rmax == 0.0) Fail("torus: outer radius must not be zero");
    if (rmax > 0.0 && rmin < 0.0) Fail("torus: inner radius must not be negative");
    if (rmax < 0.0 && rmin > 0.0) Fail("torus: inner radius must not be positive for an inward torus");
    if (!(std::abs(rmax) > std::abs(rmin))) {
      Fail("torus: |outer radius| must be greater than |inner radius|");
    }
    const double sign = rmax > 0.0 ? 1.0 : -1.0;
    const Affine& xf = World();
    const Vec3d c = CheckedPoint(xf.Point(vc.p));
    const Vec3d nz = SafeNormalize(xf.Vector(vc.n));
    const double scale = xf.Scale();
    const double tube = (std::abs(rmax) - std::abs(rmin)) * 0.5 * scale;
    const double sweep = (std::abs(rmax) + std::abs(rmin)) * 0.5 * scale;
    const int n = options_.curve_segments;
    BeginPrimitive(static_cast<size_t>(2) * n * n);
    if (nz == Vec3d{} || !UsableRadius(tube) || !UsableRadius(sweep)) {
      Warn("torus: degenerate after transformation; skipped");
      return;
    }
    geometry::TessellateTorus(c, nz, tube, sweep, sign, circle_, *this);
  }

  // §3 prism: the given face is one end (kept as given, so it faces outwards); the other end is
  // its mirror image at distance `length` opposite to the face normal; N side quads join them.
  // A negative length extrudes along the normal and leaves every normal pointing inwards.
  void Prism(const Args& a) {
    if (a.size() < 5) Fail("prism: expected at least 3 vertex names and a length");
    const double length = Number(a, a.size() - 1);
    if (length == 0.0) Fail("prism: length must not be zero");
    bool all_normals;
    WorldPolygon(a, 1, a.size() - 1, &poly_, &all_normals);
    const size_t n = poly_.size();
    BeginPrimitive(4 * n);
    Vec3d area2;
    for (size_t i = 0; i < n; ++i) area2 += Cross(poly_[i].p - poly_[0].p, poly_[(i + 1) % n].p - poly_[0].p);
    const Vec3d nz = SafeNormalize(area2);
    const double scale = World().Scale();
    if (nz == Vec3d{}) {
      Warn("prism: degenerate end face (no area) skipped");
      return;
    }
    const Vec3d d = nz * (-length * scale);
    std::vector<PolyVertex> end_face(poly_.size());
    for (size_t i = 0; i < n; ++i) end_face[i] = {poly_[n - 1 - i].p + d, {}};
    const std::vector<PolyVertex>& base = poly_;
    EmitPolygon(base, false, "prism");
    EmitPolygon(end_face, false, "prism");
    for (size_t i = 0; i < n; ++i) {
      const PolyVertex& p = base[i];
      const PolyVertex& q = base[(i + 1) % n];
      const std::array<PolyVertex, 4> side = {PolyVertex{p.p, p.n}, PolyVertex{p.p + d, p.n},
                                              PolyVertex{q.p + d, q.n}, PolyVertex{q.p, q.n}};
      EmitPolygon(side, all_normals, "prism");
    }
  }

  void Finish() {
    StoreInSceneFrame(world_positions_, &scene_);
    std::vector<Vec3d>().swap(world_positions_);
    if (!any_normal_) std::vector<Vec3>().swap(scene_.normals);
    if (suppressed_warnings_ > 0) {
      scene_.warnings.push_back(scene_.source + ": " + std::to_string(suppressed_warnings_) +
                                " more warnings not shown");
      spdlog::warn("{}", scene_.warnings.back());
    }
  }

  const MgfOptions& options_;
  SceneDescription& scene_;
  const UnitCircle circle_;  // cos, sin of the N segment angles

  std::map<std::string, std::unique_ptr<MgfFile>> files_;  // by canonical path
  std::vector<std::string> include_stack_;
  FileState* state_ = nullptr;
  int line_ = 0;
  uint64_t executed_ = 0;
  std::unordered_map<std::string, SceneExpansion> expansion_of_;  // by canonical path
  std::vector<Vec3d> world_positions_;  // world coordinates, stored in the scene's frame by Finish

  ContextTable<VertexCtx> vertices_;
  ContextTable<Chroma> colors_;
  ContextTable<MaterialCtx> materials_;
  std::vector<XfFrame> xf_stack_;
  int object_depth_ = 0;

  std::unordered_map<std::string, uint32_t> material_index_;
  uint32_t prim_material_ = 0;
  bool prim_emissive_ = false;
  uint32_t prim_light_ = kNoLight;
  bool any_normal_ = false;

  std::set<std::string> warned_once_;
  size_t suppressed_warnings_ = 0;

  // Scratch buffers reused across faces.
  std::vector<PolyVertex> poly_;
  std::vector<Vec3d> poly_points_;
  std::vector<std::array<uint32_t, 3>> poly_tris_;
  std::vector<uint32_t> remap_;
};

void CheckOptions(const MgfOptions& o, const std::string& name) {
  if (o.curve_segments < kMinCurveSegments || o.curve_segments > kMaxCurveSegments) {
    throw InputError(SourceLocation{name, 0},
                     "MgfOptions::curve_segments = " + std::to_string(o.curve_segments) + " is not in [" +
                         std::to_string(kMinCurveSegments) + ", " + std::to_string(kMaxCurveSegments) + "]");
  }
  if (o.max_depth < 1) throw InputError(SourceLocation{name, 0}, "MgfOptions::max_depth < 1");
}

SceneDescription Load(std::unique_ptr<MgfFile> file, const MgfOptions& options) {
  CheckOptions(options, file->name);
  Tokenize(*file);
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

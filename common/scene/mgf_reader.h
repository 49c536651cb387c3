#pragma once
// The MGF interpreter behind LoadMgf (mgf_loader.h), shared by the three files that implement
// it: mgf_loader.cpp (files, includes, arrays, budgets and the entity dispatch), mgf_context.cpp
// (the colour, material and vertex contexts of §2.1) and mgf_geometry.cpp (the entities that emit
// triangles). Not for use outside them.

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "common/core/error.h"
#include "common/core/math.h"
#include "common/scene/curved_primitives.h"
#include "common/scene/mgf_color.h"
#include "common/scene/mgf_options.h"
#include "common/scene/mgf_tokenizer.h"
#include "common/scene/mgf_transform.h"
#include "common/scene/scene.h"
#include "common/scene/scene_budget.h"

namespace pf::mgf {

inline constexpr uint32_t kNone = 0xffffffffu;
// Material values beyond this are not physical and would overflow the float Material.
inline constexpr double kMaxMaterialValue = 1e30;

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

// The words of one entity: the keyword, then its arguments.
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

// The entity kinds of §3, grouped as Dispatch routes them: structure (o xf i ies), contexts
// (c .. n: mgf_context.cpp), geometry (f .. torus: mgf_geometry.cpp).
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

  void Run(std::unique_ptr<MgfFile> top);

  void ReportCounts() const;

 private:
  struct FileState {
    const MgfFile* file;
    size_t xf_base;
    int object_base;
  };

  // ---- messages, arguments (mgf_loader.cpp) -----------------------------------------------------
  SourceLocation Here() const { return SourceLocation{state_ ? state_->file->name : std::string(), line_}; }
  [[noreturn]] void Fail(const std::string& reason) const { throw InputError(Here(), reason); }
  void Warn(const std::string& message);

  void ExpectCount(const Args& a, size_t lo, size_t hi, const char* usage) const;
  double Number(const Args& a, size_t i) const;
  long Integer(const Args& a, size_t i) const;
  double Fraction(const Args& a, size_t i, const char* what) const;
  double NonNegative(const Args& a, size_t i, const char* what) const;

  // ---- contexts (mgf_context.cpp) ---------------------------------------------------------------
  // The four forms of c/m/v (§2.1): "x", "x id", "x id =", "x id = template". Returns the
  // name of a newly defined context (empty otherwise) through *defined.
  template <typename T>
  void SelectContext(ContextTable<T>& table, const Args& a, const char* what, bool* defined);

  const VertexCtx& NamedVertex(std::string_view name) const;
  MaterialCtx& Mat();
  void MaterialComponent(Kind kind, const Args& a);
  const Chroma& CurrentColor() const { return *colors_.current; }
  // The current material as a SceneDescription material, converted once per change (mgf_loader.h:
  // colour and material rules).
  uint32_t MaterialIndex();

  // ---- transforms, files, expansion (scene_budget.h), execution (mgf_loader.cpp) ----------------
  const Affine& World() const;

  XformSpec ParseXform(const Args& a, size_t first) const;

  void PushFrame(XformSpec spec, size_t resume);
  void UpdateFrameWorld(XfFrame& f) const;

  const MgfFile& Include(std::string_view name);

  // Triangles and vertices one geometric entity emits at most (the tessellation rule of
  // mgf_loader.h; curved_primitives.h gives the exact counts, polygons are bounded by their
  // vertex lists: `fh` bridges each hole with two extra vertices).
  SceneExpansion PrimitiveExpansion(Kind kind, const Args& a) const;

  // What executing `file` once expands to, computed from its entities and the nesting
  // multipliers of its arrays and includes without executing anything, and checked against the
  // budgets as it accumulates: the error names the line where the file's expansion crosses a
  // budget (an array's `xf` or `i` line, where its block is multiplied). A file expands the same
  // wherever it is included, so the result is kept per file. Errors that only execution can
  // find (unbalanced `xf`, undefined names) are left to it.
  SceneExpansion ExpansionOf(const MgfFile& file);

  void ExecuteIncluded(const MgfFile& file);

  // Cannot fire after ExpansionOf accepted the file (it counts the same way); kept so that the
  // budget holds even if the two ever disagree.
  void CountEntity();

  void Execute(const MgfFile& file);

  // Executes one entity: structure (o, xf, i, ies) here, contexts through ContextEntity
  // (mgf_context.cpp), geometry through EmitGeometry (mgf_geometry.cpp).
  void Dispatch(const Args& a, size_t* pc);
  // c cxy cspec cct cmix m sides rd td ed rs ts ir v p n: the context entities (§2.1, §3).
  void ContextEntity(Kind kind, const Args& a);

  void WarnOnce(std::string_view kind, const std::string& message);
  // After the last entity: positions into the scene's frame (scene_frame.h), the warning summary.
  void Finish();

  // ---- emission (mgf_geometry.cpp) --------------------------------------------------------------
  // f fh sph cyl cone prism ring torus: the entities that emit triangles (§3), one member each.
  void EmitGeometry(Kind kind, const Args& a);

  // Starts a source primitive: its material, and a light id assigned at its first triangle.
  void BeginPrimitive(size_t expected_triangles);

  uint32_t AddVertex(const Vec3d& p, const Vec3d& n) override;

  void AddTriangle(uint32_t a, uint32_t b, uint32_t c) override;

  // Emits a polygon given in world space, in its final orientation. Returns false if degenerate.
  bool EmitPolygon(std::span<const PolyVertex> poly, bool use_normals, std::string_view what);

  // World-space vertices of a list of vertex names; `all_normals` tells whether every vertex
  // has a normal. Mirroring transforms reverse the order (see mgf_loader.h).
  void WorldPolygon(const Args& a, size_t first, size_t end, std::vector<PolyVertex>* out,
                    bool* all_normals) const;

  void Face(const Args& a);

  // §3 fh: "p1 p2 ... - h1.1 h1.2 ... - h2.1 ...". Holes are bridged into the outer contour,
  // turning the face into the seamed polygon of §3 f, which the ear clipper handles.
  void FaceWithHoles(const Args& a);

  // World-space points and radii beyond kMaxCoordinate are errors; radii that vanish under a
  // tiny scale make the primitive degenerate (a warning).
  Vec3d CheckedPoint(const Vec3d& p) const;
  bool UsableRadius(double r) const;

  void Sphere(const Args& a);

  void Cylinder(const Args& a);
  void Cone(const Args& a);
  // cyl and cone (§3 cyl, cone): open-ended truncated cone from v1 (radius r1) to v2 (r2).
  void TruncatedCone(const Args& a, std::string_view n1, double r1, std::string_view n2, double r2);

  // The centre vertex of ring and torus must have a normal (§3 ring, torus).
  const VertexCtx& OrientedCentre(const Args& a) const;

  void Ring(const Args& a);

  // §3 torus: tube of radius (rmax − rmin)/2 swept around a circle of radius (rmax + rmin)/2
  // (mgflib's reading of "inner and outer radii").
  void Torus(const Args& a);

  // §3 prism: the given face is one end (kept as given, so it faces outwards); the other end is
  // its mirror image at distance `length` opposite to the face normal; N side quads join them.
  // A negative length extrudes along the normal and leaves every normal pointing inwards.
  void Prism(const Args& a);

  const MgfOptions& options_;
  SceneDescription& scene_;
  const geometry::UnitCircle circle_;  // cos, sin of the N segment angles

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

}  // namespace pf::mgf

#include "proto/convert.h"

#include <algorithm>
#include <cmath>

#include "common/core/error.h"
#include "common/plan/plan_choice.h"
#include "common/render/render_settings_table.h"
#include "proto/limits.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

Vec3 VecFromProto(const v1::Vec3& v, const std::string& field) {
  const Vec3 out(float(v.x()), float(v.y()), float(v.z()));
  if (!IsFinite(out)) throw InputError(field + ": must be three finite numbers");
  return out;
}
// A camera point: world coordinates, kept in double (the wire's type; common/scene/scene_frame.h),
// checked as the worker will use it: finite as a float.
Vec3d PointFromProto(const v1::Vec3& v, const std::string& field) {
  const Vec3d out(v.x(), v.y(), v.z());
  if (!IsFinite(Vec3(out))) throw InputError(field + ": must be three finite numbers");
  return out;
}
void VecToProto(const Vec3d& v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

void RequireAtLeastOne(uint64_t v, const std::string& field) {
  if (v < 1) throw InputError(field + ": must be >= 1");
}

}  // namespace

const char* JobStateName(v1::JobState s) {
  switch (s) {
    case v1::JOB_STATE_QUEUED:
      return "queued";
    case v1::JOB_STATE_RUNNING:
      return "running";
    case v1::JOB_STATE_SUCCEEDED:
      return "succeeded";
    case v1::JOB_STATE_FAILED:
      return "failed";
    case v1::JOB_STATE_CANCELLED:
      return "cancelled";
    default:
      return "unknown";
  }
}

CameraSpec CameraFromProto(const v1::Camera& c, const std::string& field) {
  CameraSpec cam;
  cam.eye = PointFromProto(c.eye(), field + ".eye");
  cam.look_at = PointFromProto(c.look_at(), field + ".look_at");
  cam.up = VecFromProto(c.up(), field + ".up");
  // Checked as the worker will use it: as a float (1e-300 becomes 0, 179.9999999 becomes 180).
  cam.vfov_degrees = float(c.vfov_degrees());
  if (!(cam.vfov_degrees >= kMinVfovDegrees && cam.vfov_degrees <= kMaxVfovDegrees))
    throw InputError(field + ".vfov_degrees: must be in [" + std::to_string(kMinVfovDegrees) + ", " +
                     std::to_string(kMaxVfovDegrees) + "] (as a 32-bit float)");
  if (c.width() == 0 || c.height() == 0) throw InputError(field + ".width/height: must be > 0");
  if (c.width() > kMaxImageSide || c.height() > kMaxImageSide ||
      uint64_t(c.width()) * c.height() > kMaxImagePixels)
    throw LimitError(field + ".width/height: " + std::to_string(c.width()) + "x" +
                     std::to_string(c.height()) + " exceeds the limit (" + std::to_string(kMaxImageSide) +
                     " per side, " + std::to_string(kMaxImagePixels) + " pixels)");
  cam.width = int(c.width());
  cam.height = int(c.height());
  const Vec3 forward(cam.look_at - cam.eye);
  if (!(LengthSquared(forward) > 0.0f)) throw InputError(field + ".look_at: must differ from eye");
  if (!(LengthSquared(Cross(forward, cam.up)) > 0.0f))
    throw InputError(field + ".up: must not be parallel to the view direction");
  return cam;
}

void CameraToProto(const CameraSpec& c, v1::Camera* out) {
  VecToProto(c.eye, out->mutable_eye());
  VecToProto(c.look_at, out->mutable_look_at());
  VecToProto(c.up, out->mutable_up());
  out->set_vfov_degrees(c.vfov_degrees);
  out->set_width(uint32_t(c.width));
  out->set_height(uint32_t(c.height));
}

// SettingsFromProto, SettingsToProto: settings_convert.cpp (from the settings table).

PlanSpec PlanFromProto(const v1::Plan& p, const std::string& field) {
  PlanSpec out;
  auto check_spp = [](uint32_t spp, const std::string& f) {
    RequireAtLeastOne(spp, f);
    if (spp > kMaxSamplesPerPixel)
      throw LimitError(f + ": exceeds the limit " + std::to_string(kMaxSamplesPerPixel));
  };
  // Multiple maps and progressive: maps (passes) × samples per pixel over tiles.
  auto read_maps = [&](PlanKind kind, const auto& m, uint32_t maps, const char* maps_field) {
    out.kind = kind;
    out.maps = maps;
    out.samples_per_pixel = m.samples_per_pixel();
    out.tile_size = m.tile_size();
    const std::string f = field + std::string(maps_field);
    RequireAtLeastOne(out.maps, f);
    check_spp(out.samples_per_pixel, f.substr(0, f.rfind('.')) + ".samples_per_pixel");
  };
  switch (p.kind_case()) {
    case v1::Plan::kMultipleMaps:
      read_maps(PlanKind::kMultipleMaps, p.multiple_maps(), p.multiple_maps().maps(), ".multiple_maps.maps");
      out.tail_tile_size = p.multiple_maps().tail_tile_size();
      break;
    case v1::Plan::kMapsInTurn:
      out.kind = PlanKind::kMapsInTurn;
      out.samples_per_pixel = p.maps_in_turn().samples_per_pixel();
      out.tile_size = p.maps_in_turn().tile_size();
      check_spp(out.samples_per_pixel, field + ".maps_in_turn.samples_per_pixel");
      break;
    case v1::Plan::kSkipping:
      out.kind = PlanKind::kSkipping;
      out.stride = p.skipping().stride();
      out.rounds = p.skipping().rounds();
      out.samples_per_pixel = p.skipping().samples_per_pixel();
      RequireAtLeastOne(out.stride, field + ".skipping.stride");
      RequireAtLeastOne(out.rounds, field + ".skipping.rounds");
      check_spp(out.samples_per_pixel, field + ".skipping.samples_per_pixel");
      break;
    case v1::Plan::kHierarchical: {
      const v1::Hierarchical& h = p.hierarchical();
      out.kind = PlanKind::kHierarchical;
      out.levels = h.levels();
      out.dims = h.dims();
      out.base_samples = h.base_samples();
      out.min_samples = h.min_samples();
      out.decay = h.decay();
      out.localize_threshold = h.localize_threshold();
      out.localize_contrast = h.localize_contrast();
      out.samples_per_pixel = h.samples_per_pixel();
      out.tile_size = h.rows_per_task();
      check_spp(out.samples_per_pixel, field + ".hierarchical.samples_per_pixel");
      switch (h.part()) {
        case v1::HIERARCHY_PART_ALL:
          out.hierarchy_part = HierarchyPart::kAll;
          break;
        case v1::HIERARCHY_PART_INDIRECT:
          out.hierarchy_part = HierarchyPart::kIndirect;
          break;
        default:
          throw InputError(field + ".hierarchical.part: unknown value " + std::to_string(int(h.part())));
      }
      out.direct_samples = h.direct_samples_per_pixel();
      if (out.direct_samples > kMaxSamplesPerPixel)
        throw LimitError(field + ".hierarchical.direct_samples_per_pixel: exceeds the limit " +
                         std::to_string(kMaxSamplesPerPixel));
      // The rest (ranges, map count) is checked by ValidatePlan with the image size.
      break;
    }
    case v1::Plan::kProgressive:  // multiple maps whose maps are the passes
      read_maps(PlanKind::kProgressive, p.progressive(), p.progressive().passes(), ".progressive.passes");
      break;
    case v1::Plan::kAutoPlan:
      throw InputError(field +
                       ".auto_plan: not resolved (the coordinator replaces it by the plan it chooses)");
    default:
      throw InputError(
          field +
          ": one of multiple_maps, maps_in_turn, skipping, hierarchical, progressive, auto_plan is required");
  }
  return out;
}

void PlanToProto(const PlanSpec& p, v1::Plan* out) {
  switch (p.kind) {
    case PlanKind::kMultipleMaps: {
      auto* m = out->mutable_multiple_maps();
      m->set_maps(p.maps);
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_tile_size(p.tile_size);
      m->set_tail_tile_size(p.tail_tile_size);
      break;
    }
    case PlanKind::kMapsInTurn: {
      auto* m = out->mutable_maps_in_turn();
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_tile_size(p.tile_size);
      break;
    }
    case PlanKind::kSkipping: {
      auto* m = out->mutable_skipping();
      m->set_stride(p.stride);
      m->set_rounds(p.rounds);
      m->set_samples_per_pixel(p.samples_per_pixel);
      break;
    }
    case PlanKind::kHierarchical: {
      auto* m = out->mutable_hierarchical();
      m->set_levels(p.levels);
      m->set_dims(p.dims);
      m->set_base_samples(p.base_samples);
      m->set_min_samples(p.min_samples);
      m->set_decay(p.decay);
      m->set_localize_threshold(p.localize_threshold);
      m->set_localize_contrast(p.localize_contrast);
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_rows_per_task(p.tile_size);
      // Unset for part all: such plans serialise exactly as before the setting existed.
      if (p.hierarchy_part == HierarchyPart::kIndirect) m->set_part(v1::HIERARCHY_PART_INDIRECT);
      m->set_direct_samples_per_pixel(p.direct_samples);
      break;
    }
    case PlanKind::kProgressive: {
      auto* m = out->mutable_progressive();
      m->set_passes(p.maps);
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_tile_size(p.tile_size);
      break;
    }
  }
}

std::vector<AutoChoice> AutoChoicesFromProto(const google::protobuf::RepeatedPtrField<v1::AutoSetting>& in,
                                             const std::string& field) {
  if (size_t(in.size()) > limits::kMaxAutoSettings)
    throw InputError(field + ": more than " + std::to_string(limits::kMaxAutoSettings) + " entries");
  std::vector<AutoChoice> out;
  for (int i = 0; i < in.size(); ++i) {
    const std::string at = field + "[" + std::to_string(i) + "].";
    limits::CheckText(in[i].setting(), (at + "setting").c_str(), limits::kMaxAutoSettingTextBytes);
    limits::CheckText(in[i].value(), (at + "value").c_str(), limits::kMaxAutoSettingTextBytes);
    limits::CheckText(in[i].reason(), (at + "reason").c_str(), limits::kMaxAutoSettingTextBytes);
    // A row of the settings table, by its name or its old flag's ("caustic-map"), once: the header
    // key auto.<setting> is one per setting, and a client cannot make up others.
    const std::string& name = in[i].setting();
    const auto& table = RenderSettingsTable();
    if (std::none_of(table.begin(), table.end(),
                     [&](const RenderSetting& row) { return row.name == name || row.legacy_flag == name; }))
      throw InputError(at + "setting: " + limits::Quote(name) +
                       " is not a render setting (pf settings lists them)");
    if (std::any_of(out.begin(), out.end(), [&](const AutoChoice& c) { return c.setting == name; }))
      throw InputError(at + "setting: " + limits::Quote(name) + " is listed twice");
    out.push_back({in[i].setting(), in[i].value(), in[i].reason()});
  }
  return out;
}

void AutoChoiceToProto(const AutoChoice& c, v1::AutoSetting* out) {
  out->set_setting(c.setting);
  out->set_value(c.value);
  out->set_reason(c.reason);
}

PixelSubset PixelSubsetFromProto(const v1::PixelSubset& p, const std::string& field) {
  PixelSubset out;
  switch (p.kind_case()) {
    case v1::PixelSubset::kTile:
      out.kind = PixelSubset::Kind::kTile;
      out.x0 = p.tile().x0();
      out.y0 = p.tile().y0();
      out.x1 = p.tile().x1();
      out.y1 = p.tile().y1();
      break;
    case v1::PixelSubset::kPermutationStride:
      out.kind = PixelSubset::Kind::kPermutationStride;
      out.permutation_seed = p.permutation_stride().permutation_seed();
      out.offset = p.permutation_stride().offset();
      out.stride = p.permutation_stride().stride();
      break;
    case v1::PixelSubset::kHierarchyLevel:
      out.kind = PixelSubset::Kind::kHierarchyLevel;
      out.level = p.hierarchy_level().level();
      out.levels = p.hierarchy_level().levels();
      out.dims = p.hierarchy_level().dims();
      out.y0 = p.hierarchy_level().y0();
      out.y1 = p.hierarchy_level().y1();
      break;
    case v1::PixelSubset::kList:
      out.kind = PixelSubset::Kind::kList;
      out.list.assign(p.list().indices().begin(), p.list().indices().end());
      break;
    default:
      throw InputError(field + ": tile, permutation_stride, hierarchy_level or list is required");
  }
  return out;
}

void PixelSubsetToProto(const PixelSubset& p, v1::PixelSubset* out) {
  if (p.kind == PixelSubset::Kind::kTile) {
    auto* t = out->mutable_tile();
    t->set_x0(p.x0);
    t->set_y0(p.y0);
    t->set_x1(p.x1);
    t->set_y1(p.y1);
  } else if (p.kind == PixelSubset::Kind::kHierarchyLevel) {
    auto* h = out->mutable_hierarchy_level();
    h->set_level(p.level);
    h->set_levels(p.levels);
    h->set_dims(p.dims);
    h->set_y0(p.y0);
    h->set_y1(p.y1);
  } else if (p.kind == PixelSubset::Kind::kList) {
    out->mutable_list()->mutable_indices()->Add(p.list.begin(), p.list.end());
  } else {
    auto* s = out->mutable_permutation_stride();
    s->set_permutation_seed(p.permutation_seed);
    s->set_offset(p.offset);
    s->set_stride(p.stride);
  }
}

TaskSpec TaskSpecFromProto(const v1::Task& t) {
  TaskSpec s;
  s.task_id = t.task_id();
  s.map_index = t.map_index();
  s.map_seed = t.map_seed();
  s.pixel_seed = t.pixel_seed();
  s.pixels = PixelSubsetFromProto(t.pixels(), "task.pixels");
  s.sample_begin = t.sample_begin();
  s.sample_end = t.sample_end();
  s.progressive = t.progressive();
  if (s.sample_end <= s.sample_begin) throw InputError("task.sample_end: must be > sample_begin");
  switch (t.part()) {
    case v1::RADIANCE_PART_ALL:
      s.part = RadiancePart::kAll;
      break;
    case v1::RADIANCE_PART_MAPPED:
      s.part = RadiancePart::kMapped;
      break;
    case v1::RADIANCE_PART_UNMAPPED:
      s.part = RadiancePart::kUnmapped;
      break;
    default:
      throw InputError("task.part: unknown value " + std::to_string(int(t.part())));
  }
  return s;
}

void TaskSpecToProto(const TaskSpec& spec, v1::Task* out) {
  out->set_task_id(spec.task_id);
  out->set_map_index(spec.map_index);
  out->set_map_seed(spec.map_seed);
  out->set_pixel_seed(spec.pixel_seed);
  PixelSubsetToProto(spec.pixels, out->mutable_pixels());
  out->set_sample_begin(spec.sample_begin);
  out->set_sample_end(spec.sample_end);
  if (spec.progressive) out->set_progressive(true);
  out->set_part(spec.part == RadiancePart::kMapped     ? v1::RADIANCE_PART_MAPPED
                : spec.part == RadiancePart::kUnmapped ? v1::RADIANCE_PART_UNMAPPED
                                                       : v1::RADIANCE_PART_ALL);
}

bool ResolveAutoPlan(v1::JobSpec* spec, int width, int height, int caustic_paths, uint32_t workers,
                     bool maps_can_be_shipped, const std::string& field) {
  if (!spec->plan().has_auto_plan()) return false;
  const v1::PlanAuto a = spec->plan().auto_plan();
  const std::string f = field + ".plan.auto_plan";
  const JobRenderSettings settings = SettingsFromProto(spec->settings(), field + ".settings");
  PlanChoiceInput in;
  in.width = width;
  in.height = height;
  in.photon_map = settings.integrator == IntegratorKind::kPhotonMap;
  in.photon_budget = in.photon_map ? settings.photons : 0;
  if (a.samples_per_pixel() > kMaxSamplesPerPixel)
    throw LimitError(f + ".samples_per_pixel: exceeds the limit " + std::to_string(kMaxSamplesPerPixel));
  in.samples_per_pixel = a.samples_per_pixel();
  in.workers = a.workers() > 0 ? a.workers() : workers;
  in.caustic_map = in.photon_map && (settings.caustic == CausticMapMode::kOn ||
                                     (settings.caustic == CausticMapMode::kAuto && caustic_paths != 0));
  in.time_budget_seconds = spec->stop().time_budget_seconds();
  in.target_noise_rms = spec->stop().target_noise_rms();
  in.maps_can_be_shipped = maps_can_be_shipped;
  PlanChoice choice;
  try {
    choice = ChoosePlan(in);
  } catch (const InputError& e) {
    // ChoosePlan names fields relative to the job ("plan.auto.workers"); the wire's message is
    // auto_plan, and the budget is a setting.
    std::string msg = e.what();
    if (msg.rfind("plan.auto.", 0) == 0)
      msg = f + "." + msg.substr(10);
    else
      msg = field + "." + msg;
    throw InputError(msg);
  }
  v1::AutoPlanChoice record;
  record.set_reason(choice.reason);
  record.set_workers(in.workers);
  record.set_photon_budget(in.photon_budget);
  record.set_photons_per_map(choice.photons_per_map);
  record.set_caustic_map(in.caustic_map);
  record.set_maps_can_be_shipped(maps_can_be_shipped);
  spec->mutable_plan()->Clear();
  PlanToProto(choice.plan, spec->mutable_plan());
  *spec->mutable_plan()->mutable_chosen_by_auto() = record;
  if (in.photon_map) spec->mutable_settings()->mutable_photon_map()->set_photons(choice.photons_per_map);
  return true;
}

void BundleToProto(const SceneBundle& bundle, v1::SceneBundle* out) {
  out->set_entry(bundle.entry);
  for (const auto& [path, content] : bundle.files) {
    v1::SceneFile* f = out->add_files();
    f->set_path(path);
    f->set_content(content);
  }
}

}  // namespace pf

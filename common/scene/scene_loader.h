#pragma once
// The one entry point for reading a scene from disk: dispatches on the file extension
// (case-insensitive):
//   .json  a manifest (docs/scene-manifest.md): loads its geometry (.mgf or .obj), applies its
//          material overrides, its scale (to positions and to camera eye/look-at points) and
//          attaches its cameras. `source` is the manifest's path.
//   .mgf   MGF 2.0 (mgf_loader.h), no cameras.
//   .obj   Wavefront OBJ/MTL (obj_loader.h), no cameras.
//   .gltf, .glb  glTF 2.0 (gltf_loader.h), with its camera and KHR_lights_punctual lights; a
//          manifest may name one as its geometry (the manifest's cameras, if any, replace the
//          file's; its lights are added).
// Anything else is an InputError that lists these. So is a scene without any light (no emitting
// material, no manifest "lights"): it would render black. Bare files carry no camera; use
// DefaultCamera() for them (and for manifests without "cameras").

#include <filesystem>
#include <map>
#include <string>

#include "common/core/error.h"
#include "common/scene/manifest.h"
#include "common/scene/scene.h"

namespace pf {

// scale_override > 0 replaces the manifest's "scale" (or scales a bare file); 0 = none;
// negative or non-finite values are an InputError.
// Every file the scene refers to (manifest "geometry", MGF `i`, OBJ `mtllib`) must lie inside
// `root` (scene_reference.h); an empty root means the folder of `path` — the folder that
// CollectBundle ships, so local renders read exactly what a farm render would.
SceneDescription LoadScene(const std::filesystem::path& path, double scale_override = 0,
                           const std::filesystem::path& root = {});

// Applies a manifest's "materials" overrides to every material of each name (semantics in
// docs/scene-manifest.md). `manifest_file` is used in messages. Throws InputError if a name
// matches no material, or if an override would turn an emitter on or off (light ids are
// assigned by the geometry loader, per source primitive).
void ApplyMaterialOverrides(const std::map<std::string, MaterialOverride>& overrides,
                            const std::string& manifest_file, SceneDescription* scene);

// Multiplies world positions (the frame's origin in double, the stored positions in double,
// rounded once) and camera eye/look-at points by `scale` (> 0). Normals, radiance and
// reflectances are unchanged (a light's power grows with its area, i.e. with scale²).
// A scale whose float is 0 or subnormal, or that makes a vertex or camera coordinate overflow a
// float, or a camera's eye and look-at coincide, is an InputError at `where` naming `field`
// ("key 'scale'", "scale override") — never a scene with Inf or NaN coordinates.
void ApplyScale(double scale, const SourceLocation& where, const std::string& field, SceneDescription* scene);

// A camera for scenes without one. Convention: y is up (true of every scene in scenes/: OBJ's
// usual convention, and of the MGF rooms we ship). The camera looks along −z at the centre of
// the bounding box, from in front of its +z face, far enough back that the box's x-y cross
// section fits the field of view (45° vertical, 512 × 512) with a 5 % margin. For the Cornell
// boxes (open towards +z) this looks into the open side; for closed rooms it shows the outside
// of a wall — write a manifest with a camera inside. An empty scene gets the CameraSpec
// default.
CameraSpec DefaultCamera(const SceneDescription& scene);

}  // namespace pf

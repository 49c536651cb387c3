#include "common/render/scene_runtime.h"

#include <utility>

namespace pf {

SceneRuntime::SceneRuntime(SceneDescription d)
    : description(std::move(d)), accel(description), lights(accel) {}

}  // namespace pf

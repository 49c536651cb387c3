#pragma once
// An animation's tasks (docs/farm.md "Animation"): frames of one static scene seen by a moving
// camera, rendered as tasks of one job. The job's image is its frames stacked top to bottom — width
// × (height · frames), frame f in rows [f · height, (f + 1) · height) — so merging, checkpoints, noise
// estimates and images work on it as on any image; a task's pixels are a tile of one frame, in the
// stacked image's rows, and its `frame` says which camera renders it.
//
// Every frame takes the still image's plan with the *same* seeds: map m of every frame is the map
// with seed MapSeed(seed, m) — one map key, traced once and shared by all frames (the key holds no
// camera) — and a frame's pixel samples draw from the streams of its own pixel (x, y) as a
// single-frame job's do. So frame f of the animation is bit for bit the single-frame job with
// frame f's camera and the same seed and plan (the e2e test checks it).
//
// Order: map by map, and each map's tasks frame by frame — a worker holds one map at a time, and a
// stop rule that ends the job early leaves every frame with the same maps merged. A longer plan (more
// maps or passes) keeps every task of the shorter one at the same id, as a still image's does.
//
// Only plans whose pixel subsets are tiles stack this way: multiple maps, maps in turn and
// progressive. Skipping permutes the pixels of one image and the hierarchical plan builds its
// levels on one image's rows.

#include <cstdint>
#include <string>
#include <vector>

#include "common/plan/task_plan.h"

namespace pf {

// "" if `plan` can render frames apart; otherwise why not (a sentence without a field name).
std::string FramesPlanProblem(const PlanSpec& plan);

uint64_t CountFrameTasks(const PlanSpec& plan, int width, int height, uint32_t frames);

// The tasks of `frames` frames of width × height (frames ≥ 1; 1 gives ExpandPlan's tasks).
std::vector<TaskSpec> ExpandFrames(const PlanSpec& plan, int width, int height, uint64_t seed,
                                   uint32_t frames);

// The task as its frame renders it: its tile in the frame's own rows (what a worker receives with
// the frame's camera).
TaskSpec FrameLocalTask(const TaskSpec& task, int height);

}  // namespace pf

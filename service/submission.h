// Submission: what a client asks the service to render -- one or more NFF
// scenes (the frames of one job, rendered in order) and the render settings
// they share -- and its JSON form, the body of `POST /jobs` (docs/api.md).
// Parsing is strict (unknown keys and out-of-range values are errors naming the
// key path) and checking parses every scene, so a bad submission is refused at
// the door with "scenes[1] (b.nff): b.nff:12: ..." and never reaches a worker.
#pragma once

#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/render_job.h"
#include "tracer/render_settings.h"

namespace rayfarm {

inline constexpr size_t kMaxFramesPerJob = 100000;
inline constexpr int kMaxPriority = 1000;

struct SceneFile {
  std::string name;  // for messages and the job record, e.g. "walk-0003.nff"
  std::string text;  // NFF
};

struct Submission {
  std::vector<SceneFile> scenes;  // frame i + 1 is scenes[i]
  RenderOverrides overrides;      // `threads` is the workers' business and not sent
  int priority = 0;               // higher runs sooner; in [-1000, 1000]
};

nlohmann::json submission_json(const Submission& s);
// Throws InputError naming the key path, e.g. "settings.spp: expected an integer in [1, 65536]".
Submission parse_submission(const nlohmann::json& body);

// The scenes' names in a submission's JSON text (a stored submission.json),
// read without holding its scene text: each "nff" is dropped as it is read,
// nothing is parsed as NFF. With `first_only` the reading stops at the first
// name, which submission_json writes within the text's first bytes (its keys
// are sorted: "priority", "scenes", then "name" before "nff"). Throws
// InputError "NAME: invalid JSON: ..." or "NAME: scenes[2]: expected a name".
std::vector<std::string> scene_names_in(std::istream& in, const std::string& name, bool first_only = false);

// Parses every scene and derives each frame's settings (the one settings rule,
// tracer/render_job.h); each frame's float image must fit in max_image_bytes
// (the broker holds it whole). Throws InputError "settings.spp: ..." for a
// setting out of the rule's range whatever the scene, else "scenes[i] (name): ...".
std::vector<RenderSettings> check_submission(const Submission& s, uint64_t max_image_bytes = UINT64_MAX);

// A new job's scene names hold no control characters (C0 and NUL, DEL, C1 as
// UTF-8): they are printed in logs, in `rayfarm status` and the job's error.
// Throws InputError "scenes[i].name: ...". For submissions only: a job stored
// before this check with such a name is still loaded (its names escaped where printed).
void check_scene_names(const Submission& s);

}  // namespace rayfarm

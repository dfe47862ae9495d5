// What the accuracy study sweeps: one list of knobs, each a set of values
// applied to the base settings (the SPD's 16 spp, depth 5). A new accuracy knob
// of the tracer is one more entry in study_knobs(); the runner, the tables,
// the CSV and the plots take every knob from here.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "study/quality_study.h"
#include "tracer/render_settings.h"

namespace rayfarm {

struct KnobValue {
  std::string text;                            // as tables show it: "16", "64/0.05", "on"
  std::function<void(RenderSettings&)> apply;  // changes the base settings to this value
};

struct Knob {
  KnobInfo info;
  std::vector<KnobValue> values;  // in sweep order
};

// The knobs of a study, in sweep order; knobs with no values are left out.
std::vector<Knob> study_knobs(const StudyOptions& options);

// Applies a preset "spp=64,depth=8,adaptive=0.05,cutoff=0.01,robust=1" (any
// subset, any order) to `settings`; throws InputError naming the preset and
// the bad key or value.
void apply_preset(const std::string& preset, RenderSettings& settings);

// Every field of the settings that changes pixels or cost, as text: two
// renders with equal keys give equal images, so the study renders them once.
std::string settings_key(const RenderSettings& settings);

}  // namespace rayfarm

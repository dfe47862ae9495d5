// The study's knobs. Each sweep varies one knob from the base settings, so
// its rows differ from the SPD setting in that knob alone.
#include "study/study_knobs.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>

#include "tracer/error.h"

namespace rayfarm {

namespace {

std::string text_of(double v, const char* fmt = "%g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// A knob whose values come from one list and set one field.
template <class T, class Set>
Knob list_knob(KnobInfo info, const std::vector<T>& list, Set set) {
  Knob knob{std::move(info), {}};
  for (const T& v : list) {
    knob.values.push_back({text_of(static_cast<double>(v)), [set, v](RenderSettings& s) { set(s, v); }});
  }
  return knob;
}

Knob adaptive_knob(const StudyOptions& o) {
  Knob knob{{"adaptive", "spp / contrast",
             "Four corner cells of the k x k grid first, the rest only where their contrast "
             "(max - min) / (max + min) exceeds the threshold in some channel; depth " +
                 std::to_string(o.base_depth) + ".",
             ""},
            {}};
  for (int spp : o.adaptive_spp) {
    for (double t : o.adaptive_thresholds) {
      knob.values.push_back({std::to_string(spp) + "/" + text_of(t), [spp, t](RenderSettings& s) {
                               s.spp = spp;
                               s.adaptive_contrast = t;
                             }});
    }
  }
  return knob;
}

Knob on_off_knob(KnobInfo info, bool (RenderSettings::*field)) {
  Knob knob{std::move(info), {}};
  for (bool on : {false, true}) {
    knob.values.push_back({on ? "on" : "off", [field, on](RenderSettings& s) { s.*field = on; }});
  }
  return knob;
}

}  // namespace

std::vector<Knob> study_knobs(const StudyOptions& o) {
  const std::string base_spp = std::to_string(o.base_spp), base_depth = std::to_string(o.base_depth);
  const int deepest = o.depth_list.empty() ? 0 : *std::max_element(o.depth_list.begin(), o.depth_list.end());
  std::vector<Knob> knobs;
  knobs.push_back(list_knob(KnobInfo{"spp", "spp", "Uniform k x k grid, correlated multi-jittered; depth " + base_depth + ".", ""},
                            o.spp_list, [](RenderSettings& s, int v) { s.spp = v; }));
  knobs.push_back(list_knob(KnobInfo{"depth", "max depth",
                                     base_spp + " spp, eye ray = depth 1; every depth shares its sample positions.",
                                     std::to_string(deepest)},
                            o.depth_list, [](RenderSettings& s, int v) { s.max_depth = v; }));
  knobs.push_back(adaptive_knob(o));
  knobs.push_back(list_knob(KnobInfo{"cutoff", "cutoff",
                                     "A reflection or refraction ray is not spawned when its path weight (the product "
                                     "of the Ks / T factors above it) times the most one hit can shade is below the "
                                     "cutoff; " + base_spp + " spp, depth " + std::to_string(o.cutoff_depth) +
                                     " (pruning instead of a low depth limit), same samples.",
                                     "0"},
                            o.cutoffs, [depth = o.cutoff_depth](RenderSettings& s, double v) {
                              s.max_depth = depth;
                              s.cutoff = v;
                            }));
  if (!o.presets.empty()) {
    Knob knob{{"preset", "preset", "Several knobs at once, from the base settings.", ""}, {}};
    for (const std::string& p : o.presets) {
      knob.values.push_back({p, [p](RenderSettings& s) { apply_preset(p, s); }});
    }
    knobs.push_back(knob);
  }
  if (o.robust) {
    knobs.push_back(on_off_knob({"robust", "robust BVH",
                                 "Embree's RTC_SCENE_FLAG_ROBUST (watertight traversal); " + base_spp +
                                     " spp, depth " + base_depth + ", same samples.",
                                 "on"},
                                &RenderSettings::robust_bvh));
  }
  knobs.erase(std::remove_if(knobs.begin(), knobs.end(), [](const Knob& k) { return k.values.empty(); }),
              knobs.end());
  return knobs;
}

void apply_preset(const std::string& preset, RenderSettings& s) {
  std::istringstream in(preset);
  std::string item;
  std::set<std::string> keys;
  while (std::getline(in, item, ',')) {
    const size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    const auto bad = [&](const std::string& why) {
      return InputError("study: preset \"" + preset + "\": " + why);
    };
    // "spp=4,spp=16" rendered 16 spp under a name that says 4 as well.
    if (!keys.insert(key).second) throw bad("\"" + key + "\" given twice");
    double v = 0;
    size_t used = 0;
    try {
      v = std::stod(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (value.empty() || used != value.size()) throw bad("\"" + item + "\" is not key=number");
    // spp=16.5 rendered 16 spp under the name "spp=16.5"; and a cast of 1e10
    // to int is undefined, so it is clamped, for validate_settings to refuse.
    const auto whole = [&] {
      if (!(v == std::floor(v))) throw bad("\"" + item + "\": " + key + " is a whole number");
      return static_cast<int>(std::clamp(v, double{INT_MIN}, double{INT_MAX}));
    };
    if (key == "spp") {
      s.spp = whole();
    } else if (key == "depth") {
      s.max_depth = whole();
    } else if (key == "adaptive") {
      s.adaptive_contrast = v;
    } else if (key == "cutoff") {
      s.cutoff = v;
    } else if (key == "robust") {
      if (v != 0 && v != 1) throw bad("\"" + item + "\": robust is 0 (off) or 1 (on)");
      s.robust_bvh = v != 0;
    } else {
      throw bad("unknown key \"" + key + "\" (spp, depth, adaptive, cutoff, robust)");
    }
  }
}

std::string settings_key(const RenderSettings& s) {
  return std::to_string(s.width) + "x" + std::to_string(s.height) + " spp " + std::to_string(s.spp) + " depth " +
         std::to_string(s.max_depth) + " seed " + std::to_string(s.seed) + " contrast " +
         text_of(s.adaptive_contrast, "%.17g") + " cutoff " + text_of(s.cutoff, "%.17g") + " robust " +
         (s.robust_bvh ? "1" : "0") + " isa " + s.max_isa + " threads " +
         std::to_string(s.threads);
}

}  // namespace rayfarm

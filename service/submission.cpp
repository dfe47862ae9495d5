// Submissions and their JSON; see submission.h.
#include "service/submission.h"

#include <limits>
#include <stdexcept>

#include "protocol/json_fields.h"
#include "protocol/messages.h"
#include "tracer/image_memory.h"
#include "tracer/nff_reader.h"
#include "tracer/text_file.h"

namespace rayfarm {

using nlohmann::json;

json submission_json(const Submission& s) {
  json scenes = json::array();
  for (const SceneFile& f : s.scenes) scenes.push_back({{"name", f.name}, {"nff", f.text}});
  const RenderOverrides& o = s.overrides;
  json settings = {{"spp", o.spp}, {"depth", o.max_depth}, {"seed", o.seed},
                   {"adaptive_contrast", o.adaptive_contrast}, {"cutoff", o.cutoff}, {"robust_bvh", o.robust_bvh}};
  if (o.width) settings["width"] = *o.width;
  if (o.height) settings["height"] = *o.height;
  return {{"scenes", scenes}, {"settings", settings}, {"priority", s.priority}};
}

Submission parse_submission(const json& body) {
  JsonFields root(body);
  Submission s;
  const json& scenes = root.array("scenes", 1, kMaxFramesPerJob);
  for (size_t i = 0; i < scenes.size(); ++i) {
    JsonFields f(scenes[i], root.key_path("scenes[" + std::to_string(i) + "]"));
    SceneFile file;
    file.name = f.string("name", 1, 4096);
    file.text = f.string("nff", 0, protocol::kMaxSceneBytes);
    f.finish();
    s.scenes.push_back(std::move(file));
  }
  if (root.has("settings")) {
    JsonFields st = root.object("settings");
    RenderOverrides& o = s.overrides;
    // Only the types are checked here; the ranges are the settings rule's
    // (validate_settings), applied by check_submission.
    constexpr int kAny = std::numeric_limits<int>::max();
    if (st.has("width")) o.width = static_cast<int>(st.integer("width", -kAny, kAny));
    if (st.has("height")) o.height = static_cast<int>(st.integer("height", -kAny, kAny));
    st.read("spp", o.spp, -kAny, kAny);
    st.read("depth", o.max_depth, -kAny, kAny);
    if (st.has("seed")) o.seed = st.unsigned64("seed");
    st.read("adaptive_contrast", o.adaptive_contrast, -1e308, 1e308);
    st.read("cutoff", o.cutoff, -1e308, 1e308);
    st.read("robust_bvh", o.robust_bvh);
    st.finish();
  }
  root.read("priority", s.priority, -kMaxPriority, kMaxPriority);
  root.finish();
  return s;
}

namespace {

// A SAX reader of the root's "scenes": [{"name": ...}, ...], the rest of the
// text skipped. The lexer still reads each "nff" whole, but it is dropped at
// once rather than kept in a DOM of the whole submission.
class SceneNameReader : public nlohmann::json_sax<json> {
 public:
  explicit SceneNameReader(bool first_only) : first_only_(first_only) {}
  std::vector<std::string> names;
  size_t scenes = 0;  // scene objects begun

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool string(string_t& value) override {
    if (!in_scene() || key_ != "name") return true;
    if (names.size() == scenes) throw std::runtime_error(scene_path() + ".name: given twice");
    names.push_back(std::move(value));
    return !first_only_;  // false stops the reading there
  }
  bool key(string_t& key) override {
    if (depth_ == 1) root_key_ = key;
    if (in_scene()) key_ = key;
    return true;
  }
  bool start_object(std::size_t) override {
    if (in_scenes_ && depth_ == 2) ++scenes, key_.clear();
    ++depth_;
    return true;
  }
  bool end_object() override {
    --depth_;
    if (in_scenes_ && depth_ == 2 && names.size() < scenes) throw std::runtime_error(scene_path() + ".name: missing");
    return true;
  }
  bool start_array(std::size_t) override {
    if (depth_ == 1 && root_key_ == "scenes") in_scenes_ = found_scenes_ = true;
    ++depth_;
    return true;
  }
  bool end_array() override {
    if (--depth_ == 1) in_scenes_ = false;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    throw std::runtime_error("invalid JSON: " + short_json_error(e.what()));
  }
  // Once the whole text is read: it held no scenes, or no scene at all.
  void finish() const {
    if (!found_scenes_) throw std::runtime_error("scenes: missing, or not an array");
    if (scenes == 0) throw std::runtime_error("scenes: empty");
  }

 private:
  bool in_scene() const { return in_scenes_ && depth_ == 3; }
  std::string scene_path() const { return "scenes[" + std::to_string(scenes - 1) + "]"; }
  const bool first_only_;
  int depth_ = 0;  // of the containers open
  bool in_scenes_ = false, found_scenes_ = false;
  std::string root_key_, key_;
};

}  // namespace

std::vector<std::string> scene_names_in(std::istream& in, const std::string& name, bool first_only) {
  SceneNameReader reader(first_only);
  try {
    const bool whole = json::sax_parse(in, &reader);
    if (whole) reader.finish();
  } catch (const std::exception& e) {  // the reader's own, and the library's (e.g. a stream that fails)
    throw InputError(name + ": " + e.what());
  }
  return std::move(reader.names);
}

namespace {

// Each setting the client wrote, alone against the one settings rule
// (validate_settings), so that its error names the field as written
// ("settings.width: width must be ...") rather than the first scene. Only a
// side derived from a scene's aspect ratio is left for that scene to name.
void check_written_settings(const RenderOverrides& o) {
  const auto check = [](const char* key, auto&& write) {
    RenderSettings s;  // the rule's defaults pass it: only `write`'s field can fail
    write(s);
    try {
      validate_settings(s);
    } catch (const InputError& e) {
      throw InputError(std::string("settings.") + key + ": " + e.what());
    }
  };
  if (o.width) check("width", [&](RenderSettings& s) { s.width = *o.width; });
  if (o.height) check("height", [&](RenderSettings& s) { s.height = *o.height; });
  check("spp", [&](RenderSettings& s) { s.spp = o.spp; });
  check("depth", [&](RenderSettings& s) { s.max_depth = o.max_depth; });
  check("adaptive_contrast", [&](RenderSettings& s) { s.adaptive_contrast = o.adaptive_contrast; });
  check("cutoff", [&](RenderSettings& s) { s.cutoff = o.cutoff; });
}

}  // namespace

std::vector<RenderSettings> check_submission(const Submission& s, uint64_t max_image_bytes) {
  check_written_settings(s.overrides);
  std::vector<RenderSettings> frames;
  for (size_t i = 0; i < s.scenes.size(); ++i) {
    const SceneFile& f = s.scenes[i];
    try {
      frames.push_back(derive_settings(parse_nff(f.text, f.name), s.overrides));
      check_image_memory(frames.back().width, frames.back().height, max_image_bytes, "the broker's image limit");
    } catch (const InputError& e) {
      throw InputError("scenes[" + std::to_string(i) + "] (" + f.name + "): " + e.what());
    }
  }
  return frames;
}

namespace {

// C0 (NUL included), DEL, or C1 as UTF-8 (U+0080..U+009F: a CSI among them),
// the control characters escape_control_characters escapes (it escapes the
// invisible format characters too, which a name may still hold).
bool has_control_character(const std::string& text) {
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    const auto next = i + 1 < text.size() ? static_cast<unsigned char>(text[i + 1]) : 0;
    if (c < 0x20 || c == 0x7f || (c == 0xc2 && next >= 0x80 && next <= 0x9f)) return true;
  }
  return false;
}

}  // namespace

void check_scene_names(const Submission& s) {
  for (size_t i = 0; i < s.scenes.size(); ++i)
    if (has_control_character(s.scenes[i].name))
      throw InputError("scenes[" + std::to_string(i) + "].name: expected no control characters (a scene's name is "
                       "printed in logs and terminals), found '" + quoted_excerpt(s.scenes[i].name) + "'");
}

}  // namespace rayfarm

// libFuzzer target: a job submission, the body of `POST /api/jobs`
// (service/submission.h), from text. Text that is not JSON is the HTTP layer's
// 400 and ends here; JSON must become a Submission whose every scene parses and
// whose settings pass the settings rule, or throw InputError naming the key path
// or "scenes[i] (name): ..." -- never another exception. A Submission that is
// accepted must survive submission_json() -> parse_submission() unchanged, as
// the service stores it in the state folder that way and reads it back after a
// restart. A finished job's stored file is read for its scene names alone
// (scene_names_in): any text gives names or InputError, and a stored
// submission gives exactly its scenes' names.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_oracle.h"
#include "service/submission.h"

using namespace rayfarm;

namespace {

std::vector<std::string> names_in(const std::string& text, bool first_only) {
  std::istringstream in(text);
  return scene_names_in(in, "submission.json", first_only);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  for (bool first_only : {false, true})
    fuzz::expect_clean_error("submission.json: ",
                             [&] { names_in(std::string(reinterpret_cast<const char*>(data), size), first_only); });
  const nlohmann::json body =
      nlohmann::json::parse(reinterpret_cast<const char*>(data), reinterpret_cast<const char*>(data) + size,
                            nullptr, /*allow_exceptions=*/false);
  if (body.is_discarded()) return 0;
  fuzz::expect_clean_error("", [&] {
    const Submission s = parse_submission(body);
    check_submission(s);
    const nlohmann::json stored = submission_json(s);
    if (submission_json(parse_submission(stored)) != stored) fuzz::fail("a stored submission reads back differently");
    const std::vector<std::string> names = names_in(stored.dump(), false);
    bool same = names.size() == s.scenes.size() && names_in(stored.dump(), true) == std::vector{s.scenes[0].name};
    for (size_t i = 0; same && i < names.size(); ++i) same = names[i] == s.scenes[i].name;
    if (!same) fuzz::fail("a stored submission's scene names read back differently");
  });
  return 0;
}

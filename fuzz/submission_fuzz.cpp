// libFuzzer target: a job submission, the body of `POST /api/jobs`
// (service/submission.h), from text. Text that is not JSON is the HTTP layer's
// 400 and ends here; JSON must become a Submission whose every scene parses and
// whose settings pass the settings rule, or throw InputError naming the key path
// or "scenes[i] (name): ..." -- never another exception. A Submission that is
// accepted must survive submission_json() -> parse_submission() unchanged, as
// the service stores it in the state folder that way and reads it back after a
// restart.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_oracle.h"
#include "service/submission.h"

using namespace rayfarm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const nlohmann::json body =
      nlohmann::json::parse(reinterpret_cast<const char*>(data), reinterpret_cast<const char*>(data) + size,
                            nullptr, /*allow_exceptions=*/false);
  if (body.is_discarded()) return 0;
  fuzz::expect_clean_error("", [&] {
    const Submission s = parse_submission(body);
    check_submission(s);
    const nlohmann::json stored = submission_json(s);
    if (submission_json(parse_submission(stored)) != stored) fuzz::fail("a stored submission reads back differently");
  });
  return 0;
}

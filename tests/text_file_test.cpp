// Whole-file text and JSON IO (tracer/text_file.h): every JSON error names the
// file, and the place inside it where the text says where.
#include <doctest/doctest.h>

#include <string>

#include "tracer/error.h"
#include "tracer/text_file.h"

using namespace rayfarm;

TEST_CASE("text_file: JSON text parses, and syntax errors name the source") {
  CHECK(parse_json_text(R"({"a": [1, 2.5, "x"]})", "a.json")["a"][1] == 2.5);
  CHECK_THROWS_WITH_AS(parse_json_text(R"({"a": )", "a.json"),
                       doctest::Contains("a.json: invalid JSON: [json.exception.parse_error.101] parse error at line 1"),
                       InputError);
}

TEST_CASE("text_file: a number too large for a double names the source, line and column") {
  // Found by fuzzing: nlohmann raises overflow as out_of_range, which escaped
  // as an uncaught exception naming neither file nor place.
  CHECK_THROWS_WITH_AS(parse_json_text("{\"a\": 1,\n  \"b\": [1, 1e999]}", "cfg.json"),
                       "cfg.json: invalid JSON: number out of range at line 2, column 12: 1e999 does not fit a double",
                       InputError);
  CHECK_THROWS_WITH_AS(parse_json_text("-1e999", "n.json"),
                       "n.json: invalid JSON: number out of range at line 1, column 1: -1e999 does not fit a double",
                       InputError);
  // Large but finite, and tiny numbers that round to 0, are numbers.
  CHECK(parse_json_text("[1e308, 1e-999]", "n.json")[0] == 1e308);
}

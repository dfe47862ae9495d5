// Whole-file text and JSON IO (tracer/text_file.h): every JSON error names the
// file, and the place inside it: a line and column for syntax, a key path for
// a number out of range.
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

TEST_CASE("text_file: a number too large for a double names the source and its place") {
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

TEST_CASE("text_file: an error quotes at most 80 bytes of what it read, a cut scene or a huge key or number") {
  // The JSON library quotes the whole token it was reading: a submission.json
  // cut inside its scene made an error, and a log line, as long as the scene.
  const std::string scene(20000, 'a');
  const auto error_of = [](const std::string& text) {
    try {
      parse_json_text(text, "submission.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("parsed");
  };
  const std::string cut = error_of(R"({"scenes": [{"name": "a.nff", "nff": ")" + scene);
  CHECK(cut == "submission.json: invalid JSON: [json.exception.parse_error.101] parse error at line 1, column 20039: "
               "syntax error while parsing value - invalid string: missing closing quote; last read: '\"" +
                   scene.substr(0, 79) + "...'");
  // The library's own tail after the token stays.
  const std::string key = error_of("{\"" + scene);
  CHECK(key.size() < 400);
  CHECK(key.find("last read: '\"" + scene.substr(0, 79) + "...'; expected string literal") != std::string::npos);
  const std::string number = error_of("[1" + std::string(5000, '0') + "]");
  CHECK(number == "submission.json: invalid JSON: number out of range at line 1, column 2: 1" +
                      std::string(79, '0') + "... does not fit a double");
  const std::string twice = error_of("{\"" + scene + "\": 1, \"" + scene + "\": 2}");
  CHECK(twice == "submission.json: invalid JSON: duplicate key \"" + scene.substr(0, 80) + "...\" in one object");
  // Short tokens are quoted whole, as before.
  CHECK(error_of(R"({"a": tru})") == "submission.json: invalid JSON: [json.exception.parse_error.101] parse error at "
                                     "line 1, column 10: syntax error while parsing value - invalid literal; last "
                                     "read: '\"a\": tru}'");
}

TEST_CASE("text_file: a middle excerpt keeps the head and the tail, each cut between UTF-8 characters") {
  std::string e_acute;
  for (int i = 0; i < 60; ++i) e_acute += "\xc3\xa9";  // 120 bytes
  CHECK(middle_excerpt(e_acute, 120, 10) == e_acute);  // fits: whole
  // 10 + 7 + 23 bytes: a head of 10 and a tail of 23 would each split an é.
  const std::string cut = middle_excerpt("x" + e_acute + "yy", 40, 10);
  CHECK(cut == "x" + e_acute.substr(0, 8) + " [...] " + e_acute.substr(0, 20) + "yy");
  CHECK(cut.size() <= 40);
  CHECK(middle_excerpt(std::string(50, 'a') + "END", 20, 5, "~") == "aaaaa~" + std::string(11, 'a') + "END");
  // Bytes that are no UTF-8 are cut where they fall, not stepped back over to nothing.
  CHECK(quoted_excerpt(std::string(100, '\x80'), 40) == std::string(40, '\x80') + "...");
}

TEST_CASE("text_file: a quoted excerpt is cut between UTF-8 characters, never inside one") {
  std::string e_acute;
  for (int i = 0; i < 60; ++i) e_acute += "\xc3\xa9";  // 120 bytes
  CHECK(quoted_excerpt("x" + e_acute) == "x" + e_acute.substr(0, 78) + "...");  // 79 bytes: 80 would split one
  CHECK(quoted_excerpt(e_acute) == e_acute.substr(0, 80) + "...");
  CHECK(quoted_excerpt(std::string(80, 'a')) == std::string(80, 'a'));
  // Quoted as written, for what prints the message to escape; but a NUL, which would end the message there.
  CHECK(quoted_excerpt("a\x1b[2J\xe8") == "a\x1b[2J\xe8");
  CHECK(quoted_excerpt(std::string("a\0b\0", 4)) == "a\xef\xbf\xbd" "b\xef\xbf\xbd");
  // A value quoted as JSON is cut between characters too.
  CHECK(json_excerpt(std::string(36, 'a') + e_acute) == "\"" + std::string(36, 'a') + "\xc3\xa9...");
  CHECK(json_excerpt(nlohmann::json{{"k", std::string(50, 'b')}}) == "{\"k\":\"" + std::string(34, 'b') + "...");
  CHECK(json_excerpt(std::string(38, 'a')) == "\"" + std::string(38, 'a') + "\"");
  CHECK(json_excerpt("caf\xe9") == "\"caf\xef\xbf\xbd\"");
  CHECK(json_excerpt(nlohmann::json::array({1, 2.0, nullptr, true})) == "[1,2.0,null,true]");
  // A token that itself holds the library's tail marker is still cut.
  const std::string sly = "syntax error - invalid string; last read: '\"" + std::string(500, 'b') + "'; expected " +
                          std::string(500, 'c') + "'";
  CHECK(short_json_error(sly).size() < 200);
}

TEST_CASE("text_file: a JSON value is quoted with its strings as they are, for its printer to escape once") {
  // JSON's escapes were escaped again where the message is printed: a config
  // string holding an ESC read "a\\u001bb" on the terminal.
  CHECK(json_excerpt("a\x1b" "b") == "\"a\x1b" "b\"");
  CHECK(json_excerpt("a\\b\"c\n") == "\"a\\b\"c\n\"");
  CHECK(json_excerpt(nlohmann::json{{"k\x01", nlohmann::json::array({"v\x1b"})}}) == "{\"k\x01\":[\"v\x1b\"]}");
  CHECK(json_excerpt(std::string(37, 'a') + "\"bc") == "\"" + std::string(37, 'a') + "\"b...");
  // But a NUL, which would end the message there (what() is a C string).
  CHECK(json_excerpt(std::string("a\0b", 3)) == "\"a\xef\xbf\xbd" "b\"");
}

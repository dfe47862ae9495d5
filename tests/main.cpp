// The single doctest binary; every tests/*_test.cpp file adds its cases here.
//
// ctest runs each case alone by name (doctest_discover_tests). A run whose
// filters select no case fails: doctest would pass it, and a name the
// discovery mangles (a ';' splits it in two CMake list items) would then pass
// without running.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <sys/stat.h>

#include <cstdio>

namespace {

unsigned cases_selected = 0;

// Hears the run's totals; reports nothing itself.
struct SelectedCases : doctest::IReporter {
  explicit SelectedCases(const doctest::ContextOptions&) {}
  void report_query(const doctest::QueryData&) override {}
  void test_run_start() override {}
  void test_run_end(const doctest::TestRunStats& stats) override { cases_selected = stats.numTestCasesPassingFilters; }
  void test_case_start(const doctest::TestCaseData&) override {}
  void test_case_reenter(const doctest::TestCaseData&) override {}
  void test_case_end(const doctest::CurrentTestCaseStats&) override {}
  void test_case_exception(const doctest::TestCaseException&) override {}
  void subcase_start(const doctest::SubcaseSignature&) override {}
  void subcase_end() override {}
  void log_assert(const doctest::AssertData&) override {}
  void log_message(const doctest::MessageData&) override {}
  void test_case_skipped(const doctest::TestCaseData&) override {}
};

REGISTER_LISTENER("selected-cases", 1, SelectedCases);

}  // namespace

int main(int argc, char** argv) {
  // The folders and files the cases make are the owner's to write whatever
  // the runner's umask: an allow folder others may write is refused.
  ::umask(022);
  doctest::Context context(argc, argv);
  const int result = context.run();
  if (context.shouldExit()) return result;  // a query (--help, --list-test-cases)
  if (result == 0 && cases_selected == 0) {
    std::fprintf(stderr, "no test case matches the filters\n");
    return 1;
  }
  return result;
}

// Journal: records come back in order; a tail torn anywhere (short header,
// short payload, flipped byte, zeros) is detected, cut off and reported, and appends
// continue after the last intact record; other formats and versions are refused.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>

#include "service/journal.h"
#include "tests/test_files.h"
#include "tracer/error.h"

using namespace rayfarm;
namespace fs = std::filesystem;

namespace {

std::string temp_journal(const char* name) {
  const fs::path p = test::process_dir("journal-test") / name;
  fs::remove(p);
  return p.string();
}

// Opens `path` (creating it) and appends `records`.
void append_all(const std::string& path, std::initializer_list<const char*> records) {
  JournalRecovery r;
  Journal j(path, r);
  for (const char* rec : records) j.append(rec);
}

std::vector<std::string> reopen(const std::string& path, JournalRecovery* info = nullptr) {
  JournalRecovery r;
  Journal j(path, r);
  if (info) *info = r;
  return r.records;
}

}  // namespace

TEST_CASE("journal: records read back in order across reopenings") {
  const std::string path = temp_journal("order.journal");
  {
    JournalRecovery r;
    Journal j(path, r);
    CHECK(r.records.empty());
    j.append("one");
    j.append(std::string(100000, 'x'));
    j.append("three");
  }
  {
    JournalRecovery r;
    Journal j(path, r);
    REQUIRE(r.records.size() == 3);
    CHECK(r.dropped_bytes == 0);
    j.append("four");
  }
  const auto records = reopen(path);
  REQUIRE(records.size() == 4);
  CHECK(records[0] == "one");
  CHECK(records[1] == std::string(100000, 'x'));
  CHECK(records[2] == "three");
  CHECK(records[3] == "four");
}

TEST_CASE("journal: an empty record is refused, as its eight zero bytes read as a power loss's zero fill") {
  const std::string path = temp_journal("empty-record.journal");
  JournalRecovery r;
  Journal j(path, r);
  CHECK_THROWS_WITH_AS(j.append(""), doctest::Contains("an empty journal record"), std::logic_error);
  CHECK(j.size() == kJournalHeaderBytes);
}

TEST_CASE("journal: zeros past the last record (a power loss) are dropped, the records before kept") {
  const std::string path = temp_journal("zero-tail.journal");
  for (const size_t zeros : {size_t{1}, size_t{7}, size_t{8}, size_t{9}, size_t{16}, size_t{4096}, size_t{1} << 20}) {
    CAPTURE(zeros);
    fs::remove(path);
    append_all(path, {"first record", "second record"});
    const auto good = fs::file_size(path);
    {
      std::ofstream f(path, std::ios::binary | std::ios::app);
      const std::string fill(zeros, '\0');
      f.write(fill.data(), static_cast<std::streamsize>(fill.size()));
    }
    JournalRecovery info;
    const auto records = reopen(path, &info);
    REQUIRE(records.size() == 2);
    CHECK(records[1] == "second record");
    CHECK(info.dropped_bytes == zeros);
    CHECK(info.dropped_reason.rfind("record 3 at byte " + std::to_string(good) + ": ", 0) == 0);
    if (zeros >= 8) CHECK(info.dropped_reason.find("zeros to the end, not records") != std::string::npos);
    CHECK(fs::file_size(path) == good);  // cut off, so appends follow the last record
    append_all(path, {"after recovery"});
    const auto again = reopen(path);
    REQUIRE(again.size() == 3);
    CHECK(again[2] == "after recovery");
  }
  // Zeros followed by more (a later block written, an earlier one not): records
  // cannot be found past them, so all of it goes.
  fs::remove(path);
  append_all(path, {"first record"});
  const auto good = fs::file_size(path);
  {
    std::ofstream f(path, std::ios::binary | std::ios::app);
    f.write(std::string(4096, '\0').data(), 4096);
    f << "record-like bytes";
  }
  JournalRecovery info;
  CHECK(reopen(path, &info).size() == 1);
  CHECK(info.dropped_bytes == 4096 + 17);
  CHECK(info.dropped_reason == "record 2 at byte " + std::to_string(good) + ": an empty record, which is never written");
}

TEST_CASE("journal: a header of zeros (a power loss before it was written) is a journal with no records, begun again") {
  const std::string path = temp_journal("zero-header.journal");
  for (const size_t zeros : {size_t{1}, size_t{15}, size_t{16}, size_t{24}, size_t{4096}}) {
    CAPTURE(zeros);
    {
      std::ofstream f(path, std::ios::binary | std::ios::trunc);
      f.write(std::string(zeros, '\0').data(), static_cast<std::streamsize>(zeros));
    }
    JournalRecovery info;
    CHECK(reopen(path, &info).empty());
    CHECK(info.dropped_bytes == zeros);
    CHECK(info.dropped_reason == "header all zeros: never written before a power loss");
    CHECK(fs::file_size(path) == kJournalHeaderBytes);
    append_all(path, {"after recovery"});
    const auto again = reopen(path);
    REQUIRE(again.size() == 1);
    CHECK(again[0] == "after recovery");
  }
}

TEST_CASE("journal: a record torn at every byte is dropped and the rest kept") {
  const std::string path = temp_journal("torn.journal");
  append_all(path, {"first record", "second record, the one a crash tears"});
  const auto full = fs::file_size(path);
  const auto second = full - (8 + std::string("second record, the one a crash tears").size());
  for (auto cut = second + 1; cut < full; ++cut) {
    const std::string copy = temp_journal("torn-copy.journal");
    fs::copy_file(path, copy, fs::copy_options::overwrite_existing);
    fs::resize_file(copy, cut);
    JournalRecovery info;
    const auto records = reopen(copy, &info);
    REQUIRE(records.size() == 1);
    CHECK(records[0] == "first record");
    CHECK(info.dropped_bytes == cut - second);
    CHECK(info.dropped_reason.find("record 2") != std::string::npos);
    CHECK(fs::file_size(copy) == second);  // the torn tail is cut off
    append_all(copy, {"after recovery"});
    const auto again = reopen(copy);
    REQUIRE(again.size() == 2);
    CHECK(again[1] == "after recovery");
  }
}

TEST_CASE("journal: a header torn at every byte is a journal with no records, begun again") {
  const std::string path = temp_journal("torn-header.journal");
  append_all(path, {});
  const std::string header = [&] {
    std::ifstream f(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  }();
  REQUIRE(header.size() == kJournalHeaderBytes);
  for (size_t cut = 1; cut < kJournalHeaderBytes; ++cut) {
    {
      std::ofstream f(path, std::ios::binary | std::ios::trunc);
      f.write(header.data(), static_cast<std::streamsize>(cut));
    }
    JournalRecovery info;
    CHECK(reopen(path, &info).empty());
    CHECK(info.dropped_bytes == cut);
    CHECK(info.dropped_reason == "header torn (" + std::to_string(cut) + " of 16 bytes)");
    CHECK(fs::file_size(path) == kJournalHeaderBytes);
    append_all(path, {"after recovery"});
    const auto again = reopen(path);
    REQUIRE(again.size() == 1);
    CHECK(again[0] == "after recovery");
  }
  // A short file that is not the header's start is still another file.
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f << "RFJOUX";
  }
  JournalRecovery r;
  CHECK_THROWS_WITH_AS(Journal(path, r), doctest::Contains("not a rayfarm journal"), InputError);
}

TEST_CASE("journal: a flipped payload byte fails the checksum") {
  const std::string path = temp_journal("flip.journal");
  append_all(path, {"intact", "will be corrupted", "after the corruption"});
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(kJournalHeaderBytes + 8 + 6 + 8 + 3);
    f.put('#');
  }
  JournalRecovery info;
  const auto records = reopen(path, &info);
  REQUIRE(records.size() == 1);
  CHECK(info.dropped_reason.find("checksum mismatch") != std::string::npos);
}

TEST_CASE("journal: other files and versions are refused with the path") {
  const std::string path = temp_journal("other.journal");
  {
    std::ofstream f(path, std::ios::binary);
    f << "this is not a journal at all";
  }
  JournalRecovery r;
  CHECK_THROWS_WITH_AS(Journal(path, r), doctest::Contains("not a rayfarm journal"), InputError);
  {
    std::ofstream f(path, std::ios::binary);
    f.write(kJournalMagic, sizeof kJournalMagic);
    const char version2[8] = {2, 0, 0, 0, 0, 0, 0, 0};
    f.write(version2, sizeof version2);
  }
  CHECK_THROWS_WITH_AS(Journal(path, r), doctest::Contains("version 2"), InputError);
  std::string bytes(kJournalMagic, sizeof kJournalMagic);
  bytes += std::string("\x01\0\0\0\0\0\0\0", 8);
  bytes += std::string("\xff\xff\xff\x7f", 4) + "abcd";  // absurd length
  const JournalRecovery scanned = scan_journal(bytes, "mem");
  CHECK(scanned.records.empty());
  CHECK(scanned.dropped_reason.find("implausible length") != std::string::npos);
}

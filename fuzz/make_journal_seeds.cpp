// Writes the journal fuzz target's seed corpus (journal_fuzz.cpp): a journal
// file of the service's own making with one record of each kind, a copy torn
// in its last record, and each record's payload alone. Run again after a
// change to the journal or record format: make_journal_seeds fuzz/corpus/journal
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include "service/job_store.h"
#include "service/journal.h"

using namespace rayfarm;

namespace {

// `kind` is journal_fuzz.cpp's first byte: 0 a whole journal, 1 one record.
void write_seed(const std::string& path, char kind, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << kind << bytes;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_journal_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  RowBand band;
  band.frame = 1;
  band.y0 = 3;
  band.y1 = 4;
  band.width = 2;
  band.stats.eye = 32;
  band.stats.shadow = 20;
  band.rgb = {0, 0.25f, 0.5f, 1, 2, 1e-7f};
  const RowsSent sent{1, 3, 5};

  const std::string journal_path = dir + "/.journal";
  {
    JournalRecovery ignored;
    Journal journal(journal_path, ignored);
    journal.append(encode_journal_record(sent));
    journal.append(encode_journal_record(band));
  }
  std::ifstream in(journal_path, std::ios::binary);
  const std::string journal{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::remove(journal_path.c_str());

  write_seed(dir + "/journal", 0, journal);
  write_seed(dir + "/journal-torn", 0, journal.substr(0, journal.size() - 5));
  write_seed(dir + "/rows", 1, encode_journal_record(band));
  write_seed(dir + "/sent", 1, encode_journal_record(sent));
  return 0;
}

// libFuzzer target: the service's write-ahead journal as found in a state
// folder after a crash (service/journal.h, service/job_store.h). The first byte
// picks what the rest is:
//   even: a whole rows.journal file. scan_journal() must throw InputError
//         "fuzz.journal: ..." (bad header, other version) or keep an intact
//         prefix and account for every byte (kept + dropped = size); each kept
//         record is then decoded as below.
//   odd:  one record's payload, as a checksum-valid record hands it over (a
//         checksum is hard to forge by mutation, so the decoder gets fed
//         directly too).
// decode_journal_record() must return a record that encodes back to the same
// bytes, or throw InputError -- never read past the payload or allocate from a
// length it did not check.
#include <cstddef>
#include <cstdint>
#include <string>
#include <variant>

#include "fuzz/fuzz_oracle.h"
#include "service/job_store.h"
#include "service/journal.h"

using namespace rayfarm;

namespace {

void check_record(const std::string& payload) {
  fuzz::expect_clean_error("", [&] {
    const auto record = decode_journal_record(payload);
    const std::string again = std::visit([](const auto& r) { return encode_journal_record(r); }, record);
    if (again != payload) fuzz::fail("a journal record encodes back to other bytes");
  });
}

void check_journal(std::string_view bytes) {
  fuzz::expect_clean_error("fuzz.journal: ", [&] {
    const JournalRecovery r = scan_journal(bytes, "fuzz.journal");
    if (r.kept_bytes < kJournalHeaderBytes || r.kept_bytes + r.dropped_bytes != bytes.size())
      fuzz::fail("the journal scan lost track of bytes");
    if ((r.dropped_bytes == 0) != r.dropped_reason.empty()) fuzz::fail("a torn tail without its reason, or the reverse");
    for (const std::string& payload : r.records) check_record(payload);
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] % 2 == 0)
    check_journal(rest);
  else
    check_record(rest);
  return 0;
}

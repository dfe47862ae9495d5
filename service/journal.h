// Journal: an append-only file of checksummed records, the service's
// write-ahead log. Each record is [u32 length][u32 CRC-32 (zlib) of the
// payload][payload], little-endian, after a 16-byte header naming the format
// and its version. A crash can leave a torn last record (short, or failing its
// checksum); opening the journal detects it, drops it and everything after it,
// and says how many bytes were dropped. A header torn the same way (fewer
// than 16 bytes, all of them the header's first) is a journal with no records.
// A power loss can also leave zeros past the last write (ext4 data=writeback,
// XFS): zeros where a record starts are a torn tail, and zeros where the header
// goes a journal never written, begun again. Records are never empty, as
// eight zero bytes would make one.
// A record is written with one write(2):
// once append() returns it survives a crash of this process; sync() also makes
// it survive a power loss.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rayfarm {

inline constexpr char kJournalMagic[8] = {'R', 'F', 'J', 'O', 'U', 'R', 'N', 'L'};
inline constexpr uint32_t kJournalVersion = 1;
inline constexpr uint32_t kJournalHeaderBytes = 16;
inline constexpr uint32_t kJournalMaxRecord = 256u << 20;

// The journal's file could not be opened, read, cut or written for a reason
// of the system, not of its content (EACCES, EROFS, EMFILE, ENOSPC, EIO):
// "path: cannot open the journal (Permission denied)". Its rows are still
// good once the reason passes, so the job must not be set aside for it.
struct JournalError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// What opening found.
struct JournalRecovery {
  std::vector<std::string> records;  // intact records, in order
  uint64_t kept_bytes = 0;           // header + intact records
  uint64_t dropped_bytes = 0;        // torn tail cut off
  std::string dropped_reason;        // e.g. "record 12 at byte 4096: checksum mismatch"
};

class Journal {
 public:
  // Opens `path`, creating it (with its header) if absent or empty. Reads every
  // intact record into `recovery` and truncates a torn tail. Throws InputError
  // "path: ..." for a file that is not a journal or has another version, and
  // for a symbolic link or anything but a regular file (never followed);
  // JournalError for a file that cannot be opened, read or cut (its errno).
  Journal(const std::string& path, JournalRecovery& recovery);
  ~Journal();
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;

  // Appends one record, not empty. Throws JournalError naming the file
  // on failure (a full disk must stop the job, not lose rows silently).
  void append(std::string_view payload);
  // fdatasync: what was appended survives a power loss too.
  void sync();

  const std::string& path() const { return path_; }
  uint64_t size() const { return size_; }

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t size_ = 0;
};

// Scans journal bytes (header included) without touching any file.
JournalRecovery scan_journal(std::string_view bytes, const std::string& name);

}  // namespace rayfarm

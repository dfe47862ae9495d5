// The append-only journal; see journal.h.
#include "service/journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "service/little_endian.h"
#include "tracer/error.h"

namespace rayfarm {
namespace {

uint32_t crc_of(std::string_view payload) {
  return static_cast<uint32_t>(
      crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(payload.data()), static_cast<uInt>(payload.size())));
}

std::string header() {
  std::string h(kJournalMagic, sizeof kJournalMagic);
  put_u32(h, kJournalVersion);
  put_u32(h, 0);  // reserved
  return h;
}

std::string system_error(const std::string& path, const char* what) {
  return path + ": " + what + " (" + std::strerror(errno) + ")";
}

// write(2) until done; a short write would otherwise tear a record we think is whole.
void write_all(int fd, const char* data, size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0 && errno == EINTR) continue;
    if (w < 0) throw JournalError(system_error(path, "cannot append to the journal"));
    data += w;
    n -= static_cast<size_t>(w);
  }
}

std::string read_all(int fd, const std::string& path) {
  std::string bytes;
  char buf[1 << 16];
  while (true) {
    const ssize_t r = ::read(fd, buf, sizeof buf);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw JournalError(system_error(path, "cannot read the journal"));
    if (r == 0) return bytes;
    bytes.append(buf, static_cast<size_t>(r));
  }
}

bool all_zero(std::string_view bytes) { return bytes.find_first_not_of('\0') == std::string_view::npos; }

}  // namespace

JournalRecovery scan_journal(std::string_view bytes, const std::string& name) {
  if (bytes.size() < kJournalHeaderBytes || std::memcmp(bytes.data(), kJournalMagic, sizeof kJournalMagic) != 0)
    throw InputError(name + ": not a rayfarm journal (bad header)");
  const uint32_t version = get_u32(bytes, 8);
  if (version != kJournalVersion)
    throw InputError(name + ": journal format version " + std::to_string(version) + "; this rayfarm reads version " +
                     std::to_string(kJournalVersion));
  JournalRecovery r;
  size_t at = kJournalHeaderBytes;
  auto torn = [&](const std::string& why) {
    r.dropped_reason = "record " + std::to_string(r.records.size() + 1) + " at byte " + std::to_string(at) + ": " + why;
  };
  while (at < bytes.size()) {
    if (bytes.size() - at < 8) {
      torn("truncated record header");
      break;
    }
    const uint32_t length = get_u32(bytes, at), crc = get_u32(bytes, at + 4);
    // Eight zero bytes pass as an empty record (the CRC-32 of nothing is 0),
    // which append() never writes: they are what a power loss leaves past the
    // last write on some filesystems (ext4 data=writeback, XFS), the file
    // grown before its data reached the disk.
    if (length == 0) {
      torn(all_zero(bytes.substr(at)) ? "zeros to the end, not records (never written before a power loss)"
                                      : "an empty record, which is never written");
      break;
    }
    if (length > kJournalMaxRecord) {
      torn("implausible length " + std::to_string(length));
      break;
    }
    if (bytes.size() - at - 8 < length) {
      torn("truncated payload (" + std::to_string(bytes.size() - at - 8) + " of " + std::to_string(length) +
           " bytes)");
      break;
    }
    const std::string_view payload = bytes.substr(at + 8, length);
    if (crc_of(payload) != crc) {
      torn("checksum mismatch");
      break;
    }
    r.records.emplace_back(payload);
    at += 8 + length;
  }
  r.kept_bytes = at;
  r.dropped_bytes = bytes.size() - at;
  return r;
}

Journal::Journal(const std::string& path, JournalRecovery& recovery) : path_(path) {
  // Not through a symbolic link: one pointing out of the state folder would
  // have rows written (and a file created) wherever it points. Not blocking
  // on a FIFO either, refused below with anything else but a regular file.
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK, 0644);
  if (fd_ < 0 && errno == ELOOP)
    throw InputError(path + ": a symbolic link, not followed; the journal is a file of its own");
  if (fd_ < 0 && errno == EISDIR) throw InputError(path + ": a folder, not a regular file; the journal is a file of its own");
  if (fd_ < 0) throw JournalError(system_error(path, "cannot open the journal"));
  try {
    struct stat st {};
    if (::fstat(fd_, &st) != 0) throw JournalError(system_error(path, "cannot open the journal"));
    if (!S_ISREG(st.st_mode)) throw InputError(path + ": not a regular file; the journal is a file of its own");
    ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_NONBLOCK);  // a regular file's writes block anyway
    std::string bytes = read_all(fd_, path);
    // Shorter than the header and the start of it: a crash (a power loss) tore
    // the first write of a new journal, so no record followed. Begun again,
    // as an empty one is, rather than refused as another file.
    const size_t torn_header = bytes.size() < kJournalHeaderBytes && header().compare(0, bytes.size(), bytes) == 0
                                   ? bytes.size()
                                   : 0;
    // Zeros where the header goes: the file grew, but a power loss came before
    // its first write reached the disk (the zero fill of scan_journal's
    // records). What follows cannot be told apart into records: begun again too.
    const size_t zero_header =
        !bytes.empty() && all_zero(std::string_view(bytes).substr(0, kJournalHeaderBytes)) ? bytes.size() : 0;
    const size_t dropped = torn_header + zero_header;
    if (dropped > 0 && (::ftruncate(fd_, 0) != 0 || ::lseek(fd_, 0, SEEK_SET) < 0))
      throw JournalError(system_error(path, "cannot cut the torn header off the journal"));
    if (bytes.empty() || dropped > 0) {  // new, or created by a crash before its header was written
      bytes = header();
      write_all(fd_, bytes.data(), bytes.size(), path);
    }
    recovery = scan_journal(bytes, path);
    if (dropped > 0) {
      recovery.dropped_bytes = dropped;
      recovery.dropped_reason = torn_header > 0 ? "header torn (" + std::to_string(torn_header) + " of " +
                                                      std::to_string(kJournalHeaderBytes) + " bytes)"
                                                : "header all zeros: never written before a power loss";
    }
    if (recovery.dropped_bytes > 0 && ::ftruncate(fd_, static_cast<off_t>(recovery.kept_bytes)) != 0)
      throw JournalError(system_error(path, "cannot cut the torn tail off the journal"));
    if (::lseek(fd_, static_cast<off_t>(recovery.kept_bytes), SEEK_SET) < 0)
      throw JournalError(system_error(path, "cannot seek in the journal"));
    size_ = recovery.kept_bytes;
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

void Journal::append(std::string_view payload) {
  if (payload.size() > kJournalMaxRecord) throw JournalError(path_ + ": journal record too large");
  // Its bytes would be eight zeros, which opening takes for a power loss's zero fill.
  if (payload.empty()) throw std::logic_error(path_ + ": an empty journal record");
  std::string record;
  record.reserve(8 + payload.size());
  put_u32(record, static_cast<uint32_t>(payload.size()));
  put_u32(record, crc_of(payload));
  record.append(payload);
  write_all(fd_, record.data(), record.size(), path_);
  size_ += record.size();
}

void Journal::sync() {
  if (::fdatasync(fd_) != 0) throw JournalError(system_error(path_, "cannot sync the journal"));
}

}  // namespace rayfarm

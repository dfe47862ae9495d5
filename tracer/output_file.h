// Output files (images, stats, job records): checked before any work and
// written atomically. A render can take hours; it must not fail at the end
// because the folder is missing or read-only, and a crash mid-write must never
// leave a truncated file under the final name. So the check creates (and
// removes) a file in the target folder, and writes go to a temporary file in
// that same folder, are flushed to disk and then renamed over the target
// (rename(2) is atomic within one file system).
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "tracer/error.h"
#include "tracer/interrupt_cleanup.h"

namespace rayfarm {

// Throws InputError "path: cannot write (reason)" unless a file can be created
// in path's folder (the current directory if it has none), or when path is an
// existing device, FIFO or socket, which the final rename would replace.
void check_output_path(const std::string& path);

// A command's files by the option that names them ({"-o", "w.png"},
// {"--stats", "w.png"}, {"the scene", "w.nff"}): throws InputError "--stats w.png
// is the same file as -o" when two name one file, since the later write would
// replace the earlier (or the scene) without a word. Empty paths are skipped.
void check_distinct_files(const std::vector<std::pair<std::string, std::string>>& files);

// The same for a folder that files will be written into later: creates it if
// missing, then throws InputError "dir: cannot create folder (reason)" or
// "dir: cannot write (reason)" unless a file can be created in it.
void check_output_folder(const std::string& dir);

// A file that appears under its name whole or not at all, for writers that
// span more than one call (an image written while it renders): write to
// temp_path(), then commit(). Destroyed uncommitted (an error, an exception
// in between), it removes the temporary and leaves `path` untouched; so does
// a SIGINT or SIGTERM, where the command asked for it (interrupt_cleanup.h).
//
// Nothing runs in a process killed by SIGKILL (or the OOM killer, a crash),
// so its temporary stays. Temporaries are named ".NAME.PID-N.tmp.EXT" after
// their file and writer, and each AtomicOutputFile removes those of its own
// file whose writer's PID no process has any more: the next write of a file
// clears what an earlier killed write of it left. A temporary of a running
// process is never touched (nor one whose PID a new process has taken: it
// waits for a later write), nor any file not named so. PIDs are this machine's:
// two machines writing one file in a shared (NFS) folder could take each
// other's live temporary for a stale one.
class AtomicOutputFile {
 public:
  explicit AtomicOutputFile(std::string path);
  ~AtomicOutputFile();
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  const std::string& path() const { return path_; }
  // In path's folder, keeping path's extension (writers choose the format by it).
  const std::string& temp_path() const { return temp_; }
  // Syncs the temporary to disk and renames it over `path`. Throws InputError
  // naming `path`.
  void commit();
  // A writer's error about the temporary, restated to name `path`, the file
  // the user asked for.
  InputError naming_path(const InputError& error) const;

 private:
  std::string path_;
  std::string target_;  // path_, or the file it links to: renamed over instead of the link
  std::string temp_;
  RemovedOnInterrupt removed_on_interrupt_{temp_};
  bool committed_ = false;
};

// Calls write(temp) on an AtomicOutputFile's temporary, then commits it. On any
// failure the temporary file is removed and `path` is untouched.
void write_atomically(const std::string& path, const std::function<void(const std::string& temp)>& write);

}  // namespace rayfarm

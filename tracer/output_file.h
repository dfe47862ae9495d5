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

namespace rayfarm {

// Throws InputError "path: cannot write (reason)" unless a file can be created
// in path's folder (the current directory if it has none).
void check_output_path(const std::string& path);

// Calls write(temp) with a temporary path in path's folder that keeps path's
// extension (writers choose the format by it), then syncs and renames it to
// `path`. On any failure the temporary file is removed and `path` is untouched.
void write_atomically(const std::string& path, const std::function<void(const std::string& temp)>& write);

}  // namespace rayfarm

// The order in which a frame's rows are handed out: coarse to fine, in
// bit-reversed order of the row index (the van der Corput sequence). After the
// first 1/32 of the rows, every 32nd row is done; after 1/16, every 16th; and
// within a level the rows spread evenly too. The rows done at any moment thus
// cover the whole frame, so a progressive preview (status/preview.h) sharpens
// everywhere at once instead of filling in from the top. Tasks of k rows are
// bands of k rows in the same order of band index. Pixels do not depend on the
// order (each seeds its own sampler), so neither does the image.
#pragma once

#include <optional>
#include <utility>
#include <vector>

namespace rayfarm {

// A permutation of 0..count-1, sorted by the bit-reversed index (bits: enough
// for count - 1): 0, then count/2, count/4, 3count/4, ... for a power of two.
std::vector<int> coarse_to_fine(int count);

// Hands out a frame's rows as contiguous bands [y0, y1) in coarse-to-fine order,
// for tasks of any size, each row once. Pure logic: the broker's TaskBoard and
// the replay's simulator both cut their tasks with it.
class RowCursor {
 public:
  explicit RowCursor(int height);

  // Up to `rows` rows: the first k-row band (k = `rows`) in coarse-to-fine
  // order whose first row is still free, cut short where rows already handed
  // out begin (tasks of another size), or else the topmost free rows.
  // nullopt once every row is handed out.
  std::optional<std::pair<int, int>> take(int rows);

  int remaining() const { return remaining_; }

 private:
  struct BandOrder {
    std::vector<int> starts;  // first rows of the bands, coarse to fine
    size_t next = 0;
  };
  BandOrder& order_for(int rows);

  int height_;
  int remaining_;
  int first_free_ = 0;  // no free row above it
  std::vector<char> taken_;
  std::vector<std::pair<int, BandOrder>> orders_;  // by band size; a job sees one or a few sizes
};

}  // namespace rayfarm
